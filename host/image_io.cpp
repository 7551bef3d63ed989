#include "image_io.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <new>

#include <fmt/format.h>
#include <OpenEXR/Iex.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfVersion.h>
#include <png.h>
#include <tbb/info.h>

#include "system_memory.h"
#include "output_file.h"
#include "sampling.h"

namespace ht {

void checkImageDimensions(const std::string& path, long long width, long long height) {
  if (width <= 0 || height <= 0)
    throw Error(path + ": empty image (" + std::to_string(width) + "x" + std::to_string(height) + ")");
  if (width > kMaxImageDimension || height > kMaxImageDimension || width * height > (1ll << 28))
    throw Error(path + ": image too large (" + std::to_string(width) + "x" + std::to_string(height) +
                ", limit " + std::to_string(kMaxImageDimension) + " per side and 2^28 pixels)");
}

namespace {

uint8_t encodeSrgb8(float linear) {
  // !(x > 0) also catches NaN, which would otherwise survive the clamp.
  float v = !(linear > 0.0f) ? 0.0f : std::min(linear, 1.0f);
  float s = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
  return uint8_t(std::lround(std::clamp(s, 0.0f, 1.0f) * 255.0f));
}

}  // namespace


namespace {

// An in-memory file for OpenEXR. Reads past the end throw like a short file.
class MemoryIStream final : public Imf::IStream {
 public:
  MemoryIStream(const char* data, size_t size, const std::string& name)
      : Imf::IStream(name.c_str()), data_(data), size_(size) {}
  bool read(char c[], int n) override {
    if (n < 0 || pos_ > size_ || uint64_t(n) > size_ - pos_)
      throw Iex::InputExc("Early end of file: read past the end of " + std::to_string(size_) + " bytes.");
    if (n > 0) std::memcpy(c, data_ + pos_, size_t(n));
    pos_ += uint64_t(n);
    return pos_ < size_;
  }
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = pos; }
  void clear() override {}

 private:
  const char* data_;
  uint64_t size_;
  uint64_t pos_ = 0;
};

// Any buffer OpenEXR allocates while reading (a chunk of scan lines, a tile,
// a row of tiles) must stay below this; headers asking for more are refused
// before the library allocates anything. 16k RGBA float lines in DWAB
// chunks of 256 need 64 MiB.
constexpr uint64_t kMaxBufferBytes = uint64_t(256) << 20;

// Scan lines per chunk of each compression (OpenEXR's numLinesInBuffer).
int64_t linesPerChunk(Imf::Compression c) {
  switch (c) {
    case Imf::NO_COMPRESSION:
    case Imf::RLE_COMPRESSION:
    case Imf::ZIPS_COMPRESSION:
      return 1;
    case Imf::ZIP_COMPRESSION:
    case Imf::PXR24_COMPRESSION:
      return 16;
    case Imf::PIZ_COMPRESSION:
    case Imf::B44_COMPRESSION:
    case Imf::B44A_COMPRESSION:
    case Imf::DWAA_COMPRESSION:
      return 32;
    default:
      return 256;  // DWAB, and the most any compression uses
  }
}

int64_t ceilDiv(int64_t a, int64_t b) { return (a + b - 1) / b; }

// OpenEXR's level arithmetic (ImfTiledMisc): floor or ceil of log2, and
// the size of a level, never below 1.
int64_t roundLog2(int64_t x, Imf::LevelRoundingMode rounding) {
  int64_t y = 0, r = 0;
  while (x > 1) {
    if (x & 1) r = 1;
    ++y;
    x >>= 1;
  }
  return rounding == Imf::ROUND_UP ? y + r : y;
}

int64_t levelCount(int64_t size, Imf::LevelRoundingMode rounding) { return roundLog2(size, rounding) + 1; }

int64_t levelSize(int64_t size, int64_t level, Imf::LevelRoundingMode rounding) {
  int64_t s = rounding == Imf::ROUND_UP ? ceilDiv(size, int64_t(1) << level) : size >> level;
  return std::max<int64_t>(s, 1);
}

// Number of tiles over all levels of a tiled image.
int64_t tileCount(const Imf::TileDescription& td, int64_t w, int64_t h) {
  auto tiles = [&](int64_t lw, int64_t lh) { return ceilDiv(lw, td.xSize) * ceilDiv(lh, td.ySize); };
  if (td.mode == Imf::ONE_LEVEL) return tiles(w, h);
  int64_t total = 0;
  if (td.mode == Imf::MIPMAP_LEVELS) {
    int64_t n = levelCount(std::max(w, h), td.roundingMode);
    for (int64_t l = 0; l < n; ++l) total += tiles(levelSize(w, l, td.roundingMode), levelSize(h, l, td.roundingMode));
  } else {
    int64_t nx = levelCount(w, td.roundingMode), ny = levelCount(h, td.roundingMode);
    for (int64_t ly = 0; ly < ny; ++ly)
      for (int64_t lx = 0; lx < nx; ++lx)
        total += tiles(levelSize(w, lx, td.roundingMode), levelSize(h, ly, td.roundingMode));
  }
  return total;
}

// Refuses a header whose buffers or offset tables could not come from a
// sound file of `fileSize` bytes, before OpenEXR sizes allocations on it.
void checkHeader(const std::string& name, const Imf::Header& header, int version, uint64_t fileSize,
                 uint64_t headersEnd) {
  const bool multiPart = Imf::isMultiPart(version);
  if ((multiPart && !header.hasType()) || (header.hasType() && Imf::isDeepData(header.type())) ||
      (!multiPart && Imf::isNonImage(version)))
    throw Error(name + ": unsupported OpenEXR file (deep data or unknown part type)");
  const Imath::Box2i dw = header.dataWindow();
  const int64_t w = int64_t(dw.max.x) - dw.min.x + 1, h = int64_t(dw.max.y) - dw.min.y + 1;
  checkImageDimensions(name, w, h);
  // Coordinates far from the origin would overflow OpenEXR's arithmetic.
  constexpr int64_t kMaxCoordinate = int64_t(1) << 30;
  if (std::max({std::abs(int64_t(dw.min.x)), std::abs(int64_t(dw.min.y)), std::abs(int64_t(dw.max.x)),
                std::abs(int64_t(dw.max.y))}) > kMaxCoordinate)
    throw Error(name + ": unsupported OpenEXR data window (coordinates beyond 2^30)");
  const bool tiled = multiPart ? header.type() == Imf::TILEDIMAGE : Imf::isTiled(version);
  header.sanityCheck(tiled, multiPart);

  uint64_t bytesPerPixel = 0;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
    bytesPerPixel += it.channel().type == Imf::HALF ? 2 : 4;
  if (bytesPerPixel > 4096) throw Error(name + ": unsupported OpenEXR file (too many channels)");
  // Every chunk needs an 8-byte entry in the offset table after the headers.
  const uint64_t offsetRoom = (fileSize > headersEnd ? fileSize - headersEnd : 0) / 8;
  if (header.hasChunkCount() && (header.chunkCount() < 0 || uint64_t(header.chunkCount()) > offsetRoom))
    throw Error(fmt::format("{}: truncated or corrupt OpenEXR file ({} bytes cannot hold {} chunks)", name, fileSize,
                            header.chunkCount()));
  if (tiled) {
    const Imf::TileDescription& td = header.tileDescription();
    if (td.xSize < 1 || td.ySize < 1 || td.xSize > uint64_t(kMaxImageDimension) ||
        td.ySize > uint64_t(kMaxImageDimension) || uint64_t(td.xSize) * td.ySize * bytesPerPixel > kMaxBufferBytes ||
        uint64_t(w) * td.ySize * bytesPerPixel > kMaxBufferBytes)
      throw Error(fmt::format("{}: unsupported OpenEXR tile size {}x{}", name, td.xSize, td.ySize));
    if (td.mode != Imf::ONE_LEVEL && td.mode != Imf::MIPMAP_LEVELS && td.mode != Imf::RIPMAP_LEVELS)
      throw Error(name + ": corrupt OpenEXR file (unknown tile level mode)");
    const int64_t tiles = tileCount(td, w, h);
    if (uint64_t(tiles) > offsetRoom)
      throw Error(fmt::format("{}: truncated OpenEXR file ({} bytes cannot hold the offsets of {} tiles)", name,
                              fileSize, tiles));
  } else {
    const int64_t lines = linesPerChunk(header.compression());
    if (uint64_t(w) * uint64_t(lines) * bytesPerPixel > kMaxBufferBytes)
      throw Error(name + ": unsupported OpenEXR file (chunks of scan lines too large)");
    if (uint64_t(h) > offsetRoom * uint64_t(lines))
      throw Error(fmt::format("{}: truncated OpenEXR file ({} bytes cannot hold {} scan lines)", name, fileSize, h));
  }
}

// Bytes that OpenEXR 3.1 reads for the value of each fixed-size attribute
// type, whatever size the file declares; 0 for other types.
int64_t fixedAttributeSize(const std::string& type) {
  static const std::pair<const char*, int64_t> kSizes[] = {
      {"box2i", 16},  {"box2f", 16},   {"chromaticities", 32}, {"compression", 1}, {"double", 8},
      {"envmap", 1},  {"float", 4},    {"int", 4},             {"keycode", 28},    {"lineOrder", 1},
      {"m33f", 36},   {"m33d", 72},    {"m44f", 64},           {"m44d", 128},      {"rational", 8},
      {"tiledesc", 9}, {"timecode", 8}, {"v2i", 8},            {"v2f", 8},         {"v2d", 16},
      {"v3i", 12},    {"v3f", 12},     {"v3d", 24},            {"deepImageState", 1}};
  for (const auto& [name, size] : kSizes)
    if (type == name) return size;
  return 0;
}

// Walks the attribute lists of every header (name, type, size, value) the
// way OpenEXR 3.1 reads them, with the file's size at hand. OpenEXR trusts
// the declared sizes: it allocates what an attribute claims before reading,
// and reads fixed-size types and channel lists by their own length, so a
// wrong size shifts everything after it. Any attribute that claims more
// bytes than the file holds, or whose value does not fill exactly its
// declared size, is refused here. Returns where the headers end.
uint64_t scanHeaders(Imf::IStream& s, uint64_t size, int version, const std::string& name) {
  constexpr size_t kMaxName = 255;  // Imf::Name::MAX_LENGTH
  auto corrupt = [&](const std::string& what) {
    return Error(name + ": corrupt or truncated OpenEXR header (" + oneLine(what) + ")");
  };
  uint64_t pos = 8;
  s.seekg(pos);
  auto byte = [&]() {
    if (pos >= size) throw corrupt("the file ends inside the header");
    char c = 0;
    s.read(&c, 1);
    ++pos;
    return c;
  };
  auto int32 = [&]() {
    char b[4];
    for (char& c : b) c = byte();
    int32_t v = 0;
    std::memcpy(&v, b, 4);  // little endian on every supported host
    return v;
  };
  auto text = [&](char first) {
    std::string t(1, first);
    for (char c = byte(); c != 0; c = byte()) {
      t += c;
      if (t.size() > kMaxName) throw corrupt("name longer than 255 characters");
    }
    return t;
  };
  auto skip = [&](uint64_t n) {
    if (n > size - pos) throw corrupt("the file ends inside the header");
    pos += n;
    s.seekg(pos);
  };
  for (int part = 0;; ++part) {
    if (part > 1024) throw corrupt("more than 1024 parts");
    int attributes = 0;
    for (char c = byte(); c != 0; c = byte()) {
      const std::string attribute = text(c);
      const char t = byte();
      if (t == 0) throw corrupt("attribute \"" + attribute + "\" has no type");
      const std::string type = text(t);
      const int32_t n = int32();
      if (n < 0 || uint64_t(n) > size - pos)
        throw corrupt(fmt::format("attribute \"{}\" of {} bytes does not fit in the file", attribute, n));
      const uint64_t end = pos + uint64_t(n);
      auto mismatch = [&] {
        return corrupt(fmt::format("attribute \"{}\" of type {} does not fill its {} bytes", attribute, type, n));
      };
      if (const int64_t fixed = fixedAttributeSize(type); fixed != 0) {
        if (n != fixed) throw mismatch();
        skip(uint64_t(n));
      } else if (type == "chlist") {
        for (char ch = byte(); ch != 0; ch = byte()) {
          text(ch);
          const int32_t pixelType = int32();
          if (pixelType < 0 || pixelType > 2) throw corrupt(fmt::format("unknown pixel type {}", pixelType));
          skip(12);  // pLinear, 3 reserved bytes, x and y sampling
          if (pos > end) throw mismatch();
        }
        if (pos != end) throw mismatch();
      } else if (type == "preview") {
        if (n < 8) throw mismatch();
        const uint64_t w = uint32_t(int32()), h = uint32_t(int32());
        if (w * h * 4 != uint64_t(n) - 8) throw mismatch();
        skip(uint64_t(n) - 8);
      } else if (type == "stringvector") {
        while (pos < end) {
          if (end - pos < 4) throw mismatch();
          const int32_t length = int32();
          if (length < 0 || uint64_t(length) > end - pos) throw mismatch();
          skip(uint64_t(length));
        }
      } else if ((type == "floatvector" && n % 4 != 0) || (type == "idmanifest" && n < 4)) {
        throw mismatch();
      } else {
        skip(uint64_t(n));  // strings and opaque types are read by their size
      }
      if (++attributes > 4096) throw corrupt("more than 4096 attributes");
    }
    if (!Imf::isMultiPart(version) || attributes == 0) break;
  }
  return pos;
}

// OpenEXR decompresses and converts the chunks of a file on its global
// thread pool, which is empty until the program sizes it: until then every
// file is read in the calling thread, whatever thread count it is opened
// with. The pool is sized once, to the threads TBB uses.
int exrThreads() {
  static const int threads = [] {
    const int n = std::max(1, tbb::info::default_concurrency());
    Imf::setGlobalThreadCount(n);
    return n;
  }();
  return threads;
}

// Reads the whole image from `stream` (positioned at 0) of `size` bytes;
// with headerOnly, only its checked size.
ImageRGB readExrStream(Imf::IStream& stream, uint64_t size, const std::string& name, bool headerOnly = false) {
  // Checking the magic number ourselves gives a clear message for files that
  // are not EXR at all, instead of whatever OpenEXR makes of their bytes.
  char start[8] = {};
  if (size < 4) throw Error(name + ": not an OpenEXR file (bad magic number)");
  stream.read(start, 4);
  if (!Imf::isImfMagic(start)) throw Error(name + ": not an OpenEXR file (bad magic number)");
  if (size < 8) throw Error(name + ": truncated OpenEXR file (no version field)");
  stream.read(start + 4, 4);
  int version = 0;
  std::memcpy(&version, start + 4, 4);  // little endian on every supported host
  if (!Imf::supportsFlags(Imf::getFlags(version)) || Imf::getVersion(version) != 2)
    throw Error(fmt::format("{}: unsupported OpenEXR version or flags (0x{:x})", name, uint32_t(version)));

  ImageRGB image;
  try {
    // Parse and check the headers first so that absurd sizes are refused
    // before OpenEXR allocates offset tables or buffers, or we allocate pixels.
    const uint64_t headersEnd = scanHeaders(stream, size, version, name);
    stream.seekg(8);
    Imf::Header header;
    header.readFrom(stream, version);
    checkHeader(name, header, version, size, headersEnd);
    // Other parts of a multi-part file are not read, but OpenEXR sizes their
    // offset tables too.
    if (Imf::isMultiPart(version))
      for (;;) {
        Imf::Header part;
        part.readFrom(stream, version);
        if (part.readsNothing()) break;
        checkHeader(name, part, version, size, headersEnd);
      }
    const Imath::Box2i dw = header.dataWindow();

    const Imf::ChannelList& channels = header.channels();
    const bool hasRgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    const bool hasY = channels.findChannel("Y") != nullptr;
    if (!hasRgb && !hasY) throw Error(name + ": no colour channels (need R, G, B or Y)");
    const bool yca = !hasRgb && (channels.findChannel("RY") || channels.findChannel("BY"));
    if (!yca)
      for (const char c : std::string(hasRgb ? "RGB" : "Y")) {
        const Imf::Channel* ch = channels.findChannel(std::string(1, c));
        if (ch->xSampling != 1 || ch->ySampling != 1)
          throw Error(fmt::format("{}: unsupported OpenEXR file (channel {} is subsampled)", name, c));
      }

    image.width = dw.max.x - dw.min.x + 1;
    image.height = dw.max.y - dw.min.y + 1;
    if (headerOnly) return image;
    const size_t width = size_t(image.width);
    const size_t total = width * size_t(image.height);
    // Pixels are filled in as rows are decoded, so a file that claims a huge
    // image but holds little fails before it touches much memory. Reserving
    // only takes address space, and growing the vector would copy every
    // pixel: up front we reserve up to 768 MiB, more if the file's size
    // makes it plausible (ZIP packs a smooth sky several hundred to one).
    image.pixels.reserve(std::min<uint64_t>(total, std::max<uint64_t>(size * 64 + width * 64, uint64_t(1) << 26)));
    adviseHugePages(image.pixels.data(), image.pixels.capacity() * sizeof(glm::vec3));
    // Each strip is read in one call, its chunks (16 or 32 rows for most
    // compressions) decompressed in parallel: enough rows to keep every
    // thread busy.
    const int threads = exrThreads();
    const int64_t kStrip = std::max<int64_t>(64, int64_t(32) * threads);
    stream.clear();
    stream.seekg(0);

    if (yca) {
      // Luminance/chroma files need OpenEXR's YCA reconstruction, which only
      // the RGBA interface offers (half precision is all such files carry).
      Imf::RgbaInputFile file(stream, threads);
      std::vector<Imf::Rgba> rgba;
      for (int64_t y0 = dw.min.y; y0 <= dw.max.y; y0 += kStrip) {
        const int64_t y1 = std::min<int64_t>(y0 + kStrip - 1, dw.max.y);
        rgba.resize(width * size_t(y1 - y0 + 1));
        // The frame buffer base addresses pixel (0,0), which may lie outside
        // the strip; the offset is computed in integers.
        const intptr_t base = reinterpret_cast<intptr_t>(rgba.data()) -
                              (intptr_t(dw.min.x) + intptr_t(y0) * intptr_t(width)) * intptr_t(sizeof(Imf::Rgba));
        file.setFrameBuffer(reinterpret_cast<Imf::Rgba*>(base), 1, width);
        file.readPixels(int(y0), int(y1));
        for (const Imf::Rgba& p : rgba) image.pixels.push_back({float(p.r), float(p.g), float(p.b)});
      }
      return image;
    }

    // Chunks of scan lines are decompressed and converted on OpenEXR's
    // worker threads.
    Imf::InputFile file(stream, threads);
    // OpenEXR converts half/uint channels to float and fills each strip of
    // rows straight into the vec3 array (three interleaved floats per pixel).
    const size_t xs = sizeof(glm::vec3), ys = xs * width;
    for (int64_t y0 = dw.min.y; y0 <= dw.max.y; y0 += kStrip) {
      const int64_t y1 = std::min<int64_t>(y0 + kStrip - 1, dw.max.y);
      const size_t row = size_t(y0 - dw.min.y);
      const size_t newSize = width * (row + size_t(y1 - y0 + 1));
      image.pixels.resize(newSize);
      float* strip = &image.pixels[width * row].x;
      const Imath::V2i origin(dw.min.x, int(y0));
      const int64_t rows = y1 - y0 + 1;
      Imf::FrameBuffer fb;
      if (hasRgb) {
        fb.insert("R", Imf::Slice::Make(Imf::FLOAT, strip + 0, origin, int64_t(width), rows, xs, ys));
        fb.insert("G", Imf::Slice::Make(Imf::FLOAT, strip + 1, origin, int64_t(width), rows, xs, ys));
        fb.insert("B", Imf::Slice::Make(Imf::FLOAT, strip + 2, origin, int64_t(width), rows, xs, ys));
      } else {
        fb.insert("Y", Imf::Slice::Make(Imf::FLOAT, strip, origin, int64_t(width), rows, xs, ys));
      }
      file.setFrameBuffer(fb);
      file.readPixels(int(y0), int(y1));
      if (!hasRgb)
        for (size_t i = width * row; i < newSize; ++i) image.pixels[i] = glm::vec3(image.pixels[i].x);
    }
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw Error(name + ": out of memory reading the OpenEXR file");
  } catch (const std::exception& e) {
    throw Error(name + ": corrupt, truncated or unsupported OpenEXR file (" + oneLine(e.what()) + ")");
  }
  return image;
}

}  // namespace

namespace {

ImageRGB readExrFile(const std::string& path, bool headerOnly = false) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open " + path + ": " + std::strerror(errno));
  // A directory opens fine as a stream on Linux and would only fail later.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw Error("cannot open " + path + ": is a directory");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw Error("cannot open " + path + ": " + ec.message());
  try {
    Imf::StdIFStream stream(in, path.c_str());
    return readExrStream(stream, size, path, headerOnly);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(path + ": corrupt, truncated or unsupported OpenEXR file (" + oneLine(e.what()) + ")");
  }
}

}  // namespace

ImageRGB readExr(const std::string& path) {
  try {
    return readExrFile(path);
  } catch (const Error& e) {
    throw Error(oneLine(e.what()));  // the path may hold a newline
  }
}

bool readExrSize(const std::string& path, int& width, int& height) {
  try {
    const ImageRGB header = readExrFile(path, true);
    width = header.width;
    height = header.height;
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

ImageRGB readExrFromMemory(const void* data, size_t size, const std::string& name) {
  MemoryIStream stream(static_cast<const char*>(data), size, name);
  try {
    return readExrStream(stream, size, name);
  } catch (const Error& e) {
    throw Error(oneLine(e.what()));
  } catch (const std::exception& e) {
    throw Error(oneLine(name + ": corrupt, truncated or unsupported OpenEXR file (" + e.what() + ")"));
  }
}

namespace {

// A file output stream for OpenEXR that remembers every failure. OpenEXR
// writes the offset table from OutputFile's destructor, which swallows
// exceptions, and std::ofstream reports a full disk only when it flushes:
// without this a small image could be lost with no error at all.
class CheckedOStream final : public Imf::OStream {
 public:
  explicit CheckedOStream(const std::string& path) : Imf::OStream(path.c_str()), out_(path, std::ios::binary) {
    if (!out_) throw Iex::IoExc(record());
  }
  void write(const char c[], int n) override {
    out_.write(c, n);
    if (!out_) throw Iex::IoExc(record());
  }
  uint64_t tellp() override { return uint64_t(std::streamoff(out_.tellp())); }
  void seekp(uint64_t pos) override {
    out_.seekp(std::streamoff(pos));
    if (!out_) throw Iex::IoExc(record());
  }
  // Flushes and closes; the first error seen anywhere, or "".
  std::string finish() {
    if (out_.is_open()) {
      errno = 0;
      out_.flush();
      if (!out_) record();
      out_.close();
      if (out_.fail()) record();
    }
    return error_;
  }

 private:
  const std::string& record() {
    const int e = errno;
    if (error_.empty()) error_ = e != 0 ? std::strerror(e) : "write failed";
    return error_;
  }
  std::ofstream out_;
  std::string error_;
};

}  // namespace

void writeExr(OutputFile& file, const ImageRGB& image) {
  const std::string& path = file.target();
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * image.height)
    throw Error(oneLine("cannot write " + path + ": image has inconsistent size"));
  std::string error;
  try {
    errno = 0;
    CheckedOStream stream(file.path());
    try {
      Imf::Header header(image.width, image.height);
      header.compression() = Imf::ZIP_COMPRESSION;
      for (const char* name : {"R", "G", "B"}) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
      Imf::OutputFile exr(stream, header);
      // OpenEXR only reads through the frame buffer, the cast is safe.
      char* base = const_cast<char*>(reinterpret_cast<const char*>(image.pixels.data()));
      const size_t xs = sizeof(glm::vec3), ys = xs * image.width;
      Imf::FrameBuffer fb;
      fb.insert("R", Imf::Slice(Imf::FLOAT, base + 0 * sizeof(float), xs, ys));
      fb.insert("G", Imf::Slice(Imf::FLOAT, base + 1 * sizeof(float), xs, ys));
      fb.insert("B", Imf::Slice(Imf::FLOAT, base + 2 * sizeof(float), xs, ys));
      exr.setFrameBuffer(fb);
      exr.writePixels(image.height);
    } catch (const std::exception& e) {
      error = e.what();
    }
    // The stream's own record wins: it also covers the destructor's writes.
    const std::string streamError = stream.finish();
    if (!streamError.empty()) error = streamError;
  } catch (const std::exception& e) {
    if (error.empty()) error = e.what();
  }
  if (!error.empty()) {
    file.discard();  // no partial image left behind
    throw Error(oneLine("cannot write " + path + ": " + error));
  }
}

void writeExr(const std::string& path, const ImageRGB& image) {
  OutputFile file(path);
  writeExr(file, image);
  file.commit();
}

void writePng(OutputFile& file, const ImageRGB& image, float exposure) {
  const std::string& path = file.target();
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * image.height)
    throw Error(oneLine("cannot write " + path + ": image has inconsistent size"));
  const float scale = std::exp2(exposure);
  std::vector<uint8_t> bytes(image.pixels.size() * 3);
  for (size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) bytes[3 * i + c] = encodeSrgb8(image.pixels[i][c] * scale);

  // libpng's simplified API reports errors through the struct instead of
  // longjmp, which would skip C++ destructors. It encodes into memory so
  // that the file is written (and checked) by writeBytes.
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = png_uint_32(image.width);
  png.height = png_uint_32(image.height);
  png.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  std::vector<uint8_t> encoded;
  if (png_image_write_to_memory(&png, nullptr, &size, 0, bytes.data(), 3 * image.width, nullptr)) {
    encoded.resize(size);
    if (!png_image_write_to_memory(&png, encoded.data(), &size, 0, bytes.data(), 3 * image.width, nullptr)) size = 0;
  }
  if (size == 0) {
    const std::string message = png.message[0] ? png.message : "PNG encoding failed";
    png_image_free(&png);
    throw Error(oneLine("cannot write " + path + ": " + message));
  }
  png_image_free(&png);
  writeBytes(file, encoded.data(), size);
}

void writePng(const std::string& path, const ImageRGB& image, float exposure) {
  OutputFile file(path);
  writePng(file, image, exposure);
  file.commit();
}

ImageError compareImages(const ImageRGB& ref, const ImageRGB& test) {
  ImageError e;
  e.pixels = ref.pixels.size();
  double se = 0.0, rel = 0.0, absRel = 0.0, lumRel = 0.0;
  for (size_t i = 0; i < ref.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      double r = ref.pixels[i][c], d = double(test.pixels[i][c]) - r;
      se += d * d;
      rel += d * d / (r * r + 1e-2);
      absRel += std::abs(d) / (std::abs(r) + 1e-2);
    }
    double r = luminance(ref.pixels[i]), d = double(luminance(test.pixels[i])) - r;
    lumRel += d * d / (r * r + 1e-2);
  }
  double n = 3.0 * double(std::max<uint64_t>(e.pixels, 1));
  e.rmse = std::sqrt(se / n);
  e.relMse = rel / n;
  e.meanAbsRelError = absRel / n;
  e.luminanceRelMse = lumRel / double(std::max<uint64_t>(e.pixels, 1));
  return e;
}

}  // namespace ht
