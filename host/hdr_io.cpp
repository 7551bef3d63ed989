// Radiance RGBE (.hdr) input. The header and the scanlines' structure are
// checked here, so that every refusal is a one-line message and absurd sizes
// are refused before anything is allocated; stb_image then decodes the
// scanlines (flat or run-length) behind a canonical header.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "image_io.h"

#define STBI_ONLY_HDR
#define STBI_NO_STDIO
#define STBI_MAX_DIMENSIONS ht::kMaxImageDimension
#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#include <stb_image.h>
#pragma GCC diagnostic pop

namespace ht {

namespace {

// A header longer than this is refused: real ones are a few hundred bytes.
constexpr size_t kMaxHeaderBytes = 1 << 16;

struct HdrHeader {
  int width = 0, height = 0;
  size_t dataOffset = 0;   // first byte of the scanlines
  double exposure = 1.0;   // product of the EXPOSURE= lines: stored value = radiance x exposure
};

std::string_view trimmed(std::string_view s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  return s;
}

// The next line of the header starting at `pos`, without its newline; false
// at the end of the data or past the header's size limit.
bool nextLine(const uint8_t* data, size_t size, size_t& pos, std::string_view& line) {
  const size_t end = std::min(size, kMaxHeaderBytes);
  if (pos >= end) return false;
  const void* nl = std::memchr(data + pos, '\n', end - pos);
  if (!nl) return false;
  const size_t at = size_t(static_cast<const uint8_t*>(nl) - data);
  line = std::string_view(reinterpret_cast<const char*>(data + pos), at - pos);
  pos = at + 1;
  return true;
}

bool parseDimension(std::string_view s, long long& value) {
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc() && end == s.data() + s.size();
}

// Checks the scanlines' structure before stb_image decodes them, which pads
// a short file with zeros (and, on a run-length scanline, then loops for
// ever) and restarts at the first pixel on a flat scanline after run-length
// ones. Scanlines are flat (four bytes a pixel) where the width rules out
// run-length coding or the first scanline does not start with its mark
// (2, 2, width); otherwise each is the mark and, per channel, runs
// (128 + n, value) and dumps (n, n bytes) that fill the width exactly.
void checkScanlines(const uint8_t* data, uint64_t size, int width, int height, const std::string& name) {
  auto endsEarly = [&](int y) {
    return Error(fmt::format("{}: truncated Radiance .hdr file (the scanlines end early, in row {})", name, y));
  };
  const bool canRunLength = width >= 8 && width < 32768;
  auto marked = [&](uint64_t at) {
    return data[at] == 2 && data[at + 1] == 2 && (data[at + 2] & 0x80) == 0;
  };
  if (!canRunLength || size < 4 || !marked(0)) {
    const uint64_t need = 4 * uint64_t(width) * uint64_t(height);
    if (size < need)
      throw Error(fmt::format("{}: truncated Radiance .hdr file ({} bytes of scanlines cannot hold {}x{} pixels, {} "
                              "needed)", name, size, width, height, need));
    return;
  }
  uint64_t at = 0;
  for (int y = 0; y < height; ++y) {
    if (size - at < 4) throw endsEarly(y);
    if (!marked(at))
      throw Error(fmt::format("{}: unsupported Radiance .hdr file (row {} is flat after run-length rows)", name, y));
    if ((int(data[at + 2]) << 8 | int(data[at + 3])) != width)
      throw Error(fmt::format("{}: corrupt Radiance .hdr file (a scanline's length is not the image's width, in row {})",
                              name, y));
    at += 4;
    for (int c = 0; c < 4; ++c)
      for (int x = 0; x < width;) {
        if (at >= size) throw endsEarly(y);
        const int count = data[at++];
        const int n = count > 128 ? count - 128 : count;
        const uint64_t bytes = count > 128 ? 1 : uint64_t(n);
        if (n == 0 || n > width - x)
          throw Error(fmt::format("{}: corrupt Radiance .hdr file (bad run-length data in row {})", name, y));
        if (size - at < bytes) throw endsEarly(y);
        at += bytes;
        x += n;
      }
  }
}

HdrHeader parseHeader(const uint8_t* data, size_t size, uint64_t fileSize, const std::string& name) {
  if (size == 0) throw Error(name + ": empty file (not a Radiance .hdr image)");
  size_t pos = 0;
  std::string_view line;
  if (size < 2 || data[0] != '#' || data[1] != '?')
    throw Error(name + ": not a Radiance .hdr file (no #? signature)");
  if (!nextLine(data, size, pos, line))
    throw Error(name + ": truncated or corrupt Radiance header (no end of line within 64 KiB)");
  HdrHeader h;
  for (;;) {
    if (!nextLine(data, size, pos, line))
      throw Error(name + ": truncated or corrupt Radiance header (no blank line ends it within 64 KiB)");
    line = trimmed(line);
    if (line.empty()) break;
    if (line.starts_with("FORMAT=")) {
      const std::string_view format = trimmed(line.substr(7));
      if (format != "32-bit_rle_rgbe")
        throw Error(fmt::format("{}: unsupported Radiance pixel format \"{}\" (only 32-bit_rle_rgbe is read)", name,
                                oneLine(std::string(format))));
    } else if (line.starts_with("EXPOSURE=")) {
      const std::string_view text = trimmed(line.substr(9));
      double e = 0.0;
      const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), e);
      if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(e) || !(e > 0.0))
        throw Error(fmt::format("{}: bad Radiance header line \"{}\" (EXPOSURE must be a positive number)", name,
                                oneLine(std::string(line))));
      h.exposure *= e;
    }
    // Comments, software names, GAMMA=, PRIMARIES= and the like change no value.
  }
  // Real files say 0.1 to 100; far outside, dividing would overflow a pixel
  // or flush it to 0 instead of giving its radiance.
  if (!(h.exposure >= 1e-6 && h.exposure <= 1e6))
    throw Error(fmt::format("{}: Radiance EXPOSURE {:g} (the product of its EXPOSURE= lines) is outside [1e-6, 1e6]",
                            name, h.exposure));
  if (!nextLine(data, size, pos, line))
    throw Error(name + ": truncated Radiance header (no resolution line)");
  const std::string_view res = trimmed(line);
  std::vector<std::string_view> words;
  for (size_t i = 0; i < res.size();) {
    while (i < res.size() && res[i] == ' ') ++i;
    const size_t j = std::min(res.find(' ', i), res.size());
    if (j > i) words.push_back(res.substr(i, j - i));
    i = j;
  }
  long long height = 0, width = 0;
  auto axis = [](std::string_view w) { return w == "-Y" || w == "+Y" || w == "-X" || w == "+X"; };
  if (words.size() != 4 || !axis(words[0]) || !axis(words[2]) || !parseDimension(words[1], height) ||
      !parseDimension(words[3], width))
    throw Error(fmt::format("{}: bad Radiance resolution line \"{}\" (expected -Y height +X width)", name,
                            oneLine(std::string(res))));
  if (words[0] != "-Y" || words[2] != "+X")
    throw Error(fmt::format("{}: unsupported Radiance orientation \"{}\" (only -Y height +X width, top row first, "
                            "is read; flip or rotate the map first)",
                            name, oneLine(std::string(res))));
  checkImageDimensions(name, width, height);
  h.width = int(width);
  h.height = int(height);
  h.dataOffset = pos;
  // Each scanline takes at least four bytes: a file far too short is refused
  // from its size alone, also where only the header is at hand.
  if (fileSize - pos < 4 * uint64_t(h.height))
    throw Error(fmt::format("{}: truncated Radiance .hdr file ({} bytes of scanlines cannot hold {}x{} pixels)", name,
                            fileSize - pos, h.width, h.height));
  return h;
}

// stb_image's input: a canonical header, then the file's scanlines (which
// checkScanlines has found complete).
struct Source {
  std::string header;
  const uint8_t* data = nullptr;
  size_t size = 0;
  size_t pos = 0;  // over header + data

  size_t total() const { return header.size() + size; }
  static int read(void* user, char* out, int n) {
    Source& s = *static_cast<Source*>(user);
    int done = 0;
    while (done < n && s.pos < s.total()) {
      if (s.pos < s.header.size()) {
        const size_t k = std::min(size_t(n - done), s.header.size() - s.pos);
        std::memcpy(out + done, s.header.data() + s.pos, k);
        done += int(k);
        s.pos += k;
      } else {
        const size_t at = s.pos - s.header.size();
        const size_t k = std::min(size_t(n - done), s.size - at);
        std::memcpy(out + done, s.data + at, k);
        done += int(k);
        s.pos += k;
      }
    }
    return done;
  }
  static void skip(void* user, int n) {
    Source& s = *static_cast<Source*>(user);
    s.pos = n < 0 ? s.pos - std::min(s.pos, size_t(-int64_t(n))) : s.pos + size_t(n);
  }
  static int eof(void* user) {
    const Source& s = *static_cast<const Source*>(user);
    return s.pos >= s.total();
  }
};

ImageRGB decode(const uint8_t* data, size_t size, const std::string& name) {
  const HdrHeader h = parseHeader(data, size, size, name);
  checkScanlines(data + h.dataOffset, size - h.dataOffset, h.width, h.height, name);
  Source src;
  src.header = fmt::format("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {} +X {}\n", h.height, h.width);
  src.data = data + h.dataOffset;
  src.size = size - h.dataOffset;
  const stbi_io_callbacks callbacks{&Source::read, &Source::skip, &Source::eof};
  int w = 0, hgt = 0, comp = 0;
  std::unique_ptr<float, void (*)(void*)> pixels(stbi_loadf_from_callbacks(&callbacks, &src, &w, &hgt, &comp, 3),
                                                 &stbi_image_free);
  if (!pixels) {
    const char* why = stbi_failure_reason();
    if (why && std::strcmp(why, "outofmem") == 0) throw Error(name + ": out of memory reading the Radiance .hdr file");
    throw Error(fmt::format("{}: corrupt Radiance .hdr file ({})", name, why ? why : "undecodable scanlines"));
  }
  if (w != h.width || hgt != h.height) throw Error(name + ": corrupt Radiance .hdr file (size changed while decoding)");
  ImageRGB image;
  image.width = w;
  image.height = hgt;
  image.pixels.resize(size_t(w) * size_t(hgt));
  std::memcpy(image.pixels.data(), pixels.get(), image.pixels.size() * sizeof(glm::vec3));
  if (h.exposure != 1.0)
    for (glm::vec3& p : image.pixels) p /= float(h.exposure);
  return image;
}

bool hasHdrName(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".hdr" || ext == ".pic" || ext == ".rgbe";
}

// The file's bytes (at most `limit` of them), with the errors of opening it.
std::vector<uint8_t> readBytes(const std::string& path, uint64_t limit = UINT64_MAX) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw Error("cannot open " + path + ": is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open " + path + ": " + std::strerror(errno));
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw Error("cannot open " + path + ": " + ec.message());
  std::vector<uint8_t> bytes;
  try {
    bytes.resize(size_t(std::min<uint64_t>(size, limit)));
  } catch (const std::bad_alloc&) {
    throw Error(path + ": out of memory reading the file");
  }
  if (!in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size())))
    throw Error("cannot read " + path + ": " + std::strerror(errno));
  return bytes;
}

bool looksLikeHdr(const std::string& path) {
  if (hasHdrName(path)) return true;
  std::ifstream in(path, std::ios::binary);
  char start[2] = {};
  return in.read(start, 2) && start[0] == '#' && start[1] == '?';
}

}  // namespace

ImageRGB readHdrFromMemory(const void* data, size_t size, const std::string& name) {
  try {
    return decode(static_cast<const uint8_t*>(data), size, name);
  } catch (const Error& e) {
    throw Error(oneLine(e.what()));
  }
}

ImageRGB readHdr(const std::string& path) {
  try {
    const std::vector<uint8_t> bytes = readBytes(path);
    return decode(bytes.data(), bytes.size(), path);
  } catch (const Error& e) {
    throw Error(oneLine(e.what()));
  }
}

ImageRGB readImage(const std::string& path) { return looksLikeHdr(path) ? readHdr(path) : readExr(path); }

bool readImageSize(const std::string& path, int& width, int& height, uint64_t* decodeBytes) {
  if (decodeBytes) *decodeBytes = 0;
  if (!looksLikeHdr(path)) return readExrSize(path, width, height);
  try {
    const std::vector<uint8_t> bytes = readBytes(path, kMaxHeaderBytes);
    std::error_code ec;
    const uint64_t size = std::filesystem::file_size(path, ec);
    if (ec) return false;
    const HdrHeader h = parseHeader(bytes.data(), bytes.size(), size, path);
    width = h.width;
    height = h.height;
    if (decodeBytes) *decodeBytes = size + uint64_t(h.width) * uint64_t(h.height) * sizeof(glm::vec3);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace ht
