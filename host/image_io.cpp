#include "image_io.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfVersion.h>
#include <png.h>

namespace ht {

namespace {

// Library messages sometimes span several lines; ours must stay on one.
std::string oneLine(std::string s) {
  std::replace(s.begin(), s.end(), '\n', ' ');
  std::replace(s.begin(), s.end(), '\r', ' ');
  return s;
}

void checkImageDimensions(const std::string& path, long long width, long long height) {
  if (width <= 0 || height <= 0)
    throw Error(path + ": empty image (" + std::to_string(width) + "x" + std::to_string(height) + ")");
  if (width > kMaxImageDimension || height > kMaxImageDimension || width * height > (1ll << 28))
    throw Error(path + ": image too large (" + std::to_string(width) + "x" + std::to_string(height) +
                ", limit " + std::to_string(kMaxImageDimension) + " per side and 2^28 pixels)");
}

uint8_t encodeSrgb8(float linear) {
  // !(x > 0) also catches NaN, which would otherwise survive the clamp.
  float v = !(linear > 0.0f) ? 0.0f : std::min(linear, 1.0f);
  float s = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
  return uint8_t(std::lround(std::clamp(s, 0.0f, 1.0f) * 255.0f));
}

}  // namespace

ImageRGB readExr(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open " + path + ": " + std::strerror(errno));
  // A directory opens fine as a stream on Linux and would only fail later.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw Error("cannot open " + path + ": is a directory");

  // Checking the magic number ourselves gives a clear message for files that
  // are not EXR at all, instead of whatever OpenEXR makes of their bytes.
  char start[8] = {};
  in.read(start, sizeof start);
  if (in.gcount() < 4 || !Imf::isImfMagic(start))
    throw Error(path + ": not an OpenEXR file (bad magic number)");

  ImageRGB image;
  try {
    // Parse only the header first so that absurd sizes are refused before
    // OpenEXR allocates line-offset tables or we allocate pixels.
    int version = 0;
    std::memcpy(&version, start + 4, 4);  // little endian on every supported host
    if (in.gcount() < 8) throw Error(path + ": truncated OpenEXR file (no version field)");
    Imf::StdIFStream stream(in, path.c_str());
    Imf::Header header;
    header.readFrom(stream, version);
    const Imath::Box2i dw = header.dataWindow();
    checkImageDimensions(path, (long long)dw.max.x - dw.min.x + 1, (long long)dw.max.y - dw.min.y + 1);

    const Imf::ChannelList& channels = header.channels();
    const bool hasRgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    const bool hasY = channels.findChannel("Y") != nullptr;
    if (!hasRgb && !hasY) throw Error(path + ": no colour channels (need R, G, B or Y)");

    image.width = dw.max.x - dw.min.x + 1;
    image.height = dw.max.y - dw.min.y + 1;

    if (!hasRgb && (channels.findChannel("RY") || channels.findChannel("BY"))) {
      // Luminance/chroma files need OpenEXR's YCA reconstruction, which only
      // the RGBA interface offers (half precision is all such files carry).
      Imf::RgbaInputFile file(path.c_str());
      std::vector<Imf::Rgba> rgba(size_t(image.width) * image.height);
      // The frame buffer base addresses pixel (0,0), which may lie outside
      // a data window that does not start at the origin.
      file.setFrameBuffer(rgba.data() - dw.min.x - ptrdiff_t(dw.min.y) * image.width, 1, image.width);
      file.readPixels(dw.min.y, dw.max.y);
      image.pixels.resize(rgba.size());
      for (size_t i = 0; i < rgba.size(); ++i) image.pixels[i] = {float(rgba[i].r), float(rgba[i].g), float(rgba[i].b)};
      return image;
    }

    in.clear();
    stream.seekg(0);
    Imf::InputFile file(stream);
    image.pixels.resize(size_t(image.width) * image.height);
    // OpenEXR converts half/uint channels to float and fills the data window
    // straight into the vec3 array (three interleaved floats per pixel).
    const size_t xs = sizeof(glm::vec3), ys = xs * image.width;
    float* base = &image.pixels[0].x;
    Imf::FrameBuffer fb;
    if (hasRgb) {
      fb.insert("R", Imf::Slice::Make(Imf::FLOAT, base + 0, dw, xs, ys));
      fb.insert("G", Imf::Slice::Make(Imf::FLOAT, base + 1, dw, xs, ys));
      fb.insert("B", Imf::Slice::Make(Imf::FLOAT, base + 2, dw, xs, ys));
    } else {
      fb.insert("Y", Imf::Slice::Make(Imf::FLOAT, base, dw, xs, ys));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    if (!hasRgb)
      for (glm::vec3& p : image.pixels) p = glm::vec3(p.x);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(path + ": corrupt, truncated or unsupported OpenEXR file (" + oneLine(e.what()) + ")");
  }
  return image;
}

void writeExr(const std::string& path, const ImageRGB& image) {
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * image.height)
    throw Error("cannot write " + path + ": image has inconsistent size");
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* name : {"R", "G", "B"}) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    Imf::OutputFile file(path.c_str(), header);
    // OpenEXR only reads through the frame buffer, the cast is safe.
    char* base = const_cast<char*>(reinterpret_cast<const char*>(image.pixels.data()));
    const size_t xs = sizeof(glm::vec3), ys = xs * image.width;
    Imf::FrameBuffer fb;
    fb.insert("R", Imf::Slice(Imf::FLOAT, base + 0 * sizeof(float), xs, ys));
    fb.insert("G", Imf::Slice(Imf::FLOAT, base + 1 * sizeof(float), xs, ys));
    fb.insert("B", Imf::Slice(Imf::FLOAT, base + 2 * sizeof(float), xs, ys));
    file.setFrameBuffer(fb);
    file.writePixels(image.height);
  } catch (const std::exception& e) {
    throw Error("cannot write " + path + ": " + oneLine(e.what()));
  }
}

void writePng(const std::string& path, const ImageRGB& image, float exposure) {
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * image.height)
    throw Error("cannot write " + path + ": image has inconsistent size");
  const float scale = std::exp2(exposure);
  std::vector<uint8_t> bytes(image.pixels.size() * 3);
  for (size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) bytes[3 * i + c] = encodeSrgb8(image.pixels[i][c] * scale);

  // libpng's simplified API reports errors through the struct instead of
  // longjmp, which would skip C++ destructors.
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = png_uint_32(image.width);
  png.height = png_uint_32(image.height);
  png.format = PNG_FORMAT_RGB;
  if (!png_image_write_to_file(&png, path.c_str(), 0, bytes.data(), 3 * image.width, nullptr))
    throw Error("cannot write " + path + ": " + oneLine(png.message));
  png_image_free(&png);
}

ImageError compareImages(const ImageRGB& ref, const ImageRGB& test) {
  ImageError e;
  e.pixels = ref.pixels.size();
  double se = 0.0, rel = 0.0, absRel = 0.0;
  for (size_t i = 0; i < ref.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      double r = ref.pixels[i][c], d = double(test.pixels[i][c]) - r;
      se += d * d;
      rel += d * d / (r * r + 1e-2);
      absRel += std::abs(d) / (std::abs(r) + 1e-2);
    }
  double n = 3.0 * double(std::max<uint64_t>(e.pixels, 1));
  e.rmse = std::sqrt(se / n);
  e.relMse = rel / n;
  e.meanAbsRelError = absRel / n;
  return e;
}

}  // namespace ht
