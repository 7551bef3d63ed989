// A Radiance RGBE (.hdr) writer for the tests: flat or run-length scanlines,
// any header lines and resolution line, so that both valid files and the
// broken ones a reader must refuse can be made exactly.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

namespace ht::test {

// Ward's shared-exponent encoding, rounded to nearest (stb_image decodes
// m x 2^(e - 136) without an offset): each channel is off by at most
// max(r, g, b) / 256.
inline void encodeRgbe(const glm::vec3& c, uint8_t out[4]) {
  const float v = std::max(c.x, std::max(c.y, c.z));
  if (!(v > 1e-32f)) {
    out[0] = out[1] = out[2] = out[3] = 0;
    return;
  }
  int e = 0;
  std::frexp(v, &e);  // v = m 2^e, m in [0.5, 1)
  const float scale = std::ldexp(1.0f, 8 - e);
  const float ch[3] = {c.x, c.y, c.z};
  for (int i = 0; i < 3; ++i) out[i] = uint8_t(std::min(255.0f, std::floor(std::max(0.0f, ch[i]) * scale + 0.5f)));
  out[3] = uint8_t(e + 128);
}

inline glm::vec3 decodeRgbe(const uint8_t in[4]) {
  if (in[3] == 0) return glm::vec3(0.0f);
  const float f = std::ldexp(1.0f, int(in[3]) - 136);
  return glm::vec3(float(in[0]) * f, float(in[1]) * f, float(in[2]) * f);
}

// One channel of a scanline as Radiance's run-length code: runs of four or
// more equal bytes as (128 + n, value), the rest as (n, n bytes).
inline void appendRunLength(const std::vector<uint8_t>& bytes, std::vector<uint8_t>& out) {
  const size_t n = bytes.size();
  size_t i = 0;
  while (i < n) {
    size_t run = 1;
    while (i + run < n && run < 127 && bytes[i + run] == bytes[i]) ++run;
    if (run >= 4) {
      out.push_back(uint8_t(128 + run));
      out.push_back(bytes[i]);
      i += run;
      continue;
    }
    // A dump up to the next run of four (or 128 bytes).
    size_t j = i;
    while (j < n && j - i < 128) {
      size_t r = 1;
      while (j + r < n && r < 4 && bytes[j + r] == bytes[j]) ++r;
      if (r >= 4) break;
      ++j;
    }
    out.push_back(uint8_t(j - i));
    out.insert(out.end(), bytes.begin() + long(i), bytes.begin() + long(j));
    i = j;
  }
}

struct RgbeFile {
  int width = 0, height = 0;
  std::vector<glm::vec3> pixels;  // row-major, top row first
  bool runLength = true;          // needs 8 <= width < 32768
  std::string signature = "#?RADIANCE";
  std::vector<std::string> headerLines = {"FORMAT=32-bit_rle_rgbe"};
  std::string resolution;  // empty: "-Y height +X width"
};

inline std::string encodeRgbeFile(const RgbeFile& f) {
  std::string s = f.signature + "\n";
  for (const std::string& line : f.headerLines) s += line + "\n";
  s += "\n";
  s += (f.resolution.empty() ? "-Y " + std::to_string(f.height) + " +X " + std::to_string(f.width) : f.resolution) +
       "\n";
  std::vector<uint8_t> data;
  std::vector<uint8_t> channel(size_t(std::max(f.width, 0)));
  for (int y = 0; y < f.height; ++y) {
    std::vector<uint8_t> row(size_t(f.width) * 4);
    for (int x = 0; x < f.width; ++x) encodeRgbe(f.pixels[size_t(y) * size_t(f.width) + size_t(x)], &row[size_t(x) * 4]);
    if (!f.runLength) {
      data.insert(data.end(), row.begin(), row.end());
      continue;
    }
    data.insert(data.end(), {2, 2, uint8_t(f.width >> 8), uint8_t(f.width & 0xff)});
    for (int c = 0; c < 4; ++c) {
      for (int x = 0; x < f.width; ++x) channel[size_t(x)] = row[size_t(x) * 4 + size_t(c)];
      appendRunLength(channel, data);
    }
  }
  s.append(reinterpret_cast<const char*>(data.data()), data.size());
  return s;
}

}  // namespace ht::test
