#include "image_io.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfTiledRgbaFile.h>
#include <Imath/half.h>
#include <png.h>

namespace fs = std::filesystem;

namespace {

const fs::path kData = HT_TEST_DATA;

class ImageIo : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("ht_image_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string file(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

std::vector<char> slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void spit(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// Expects readExr(path) to throw ht::Error whose one-line message names the
// file and contains `word`.
void expectReadError(const std::string& path, const std::string& word) {
  try {
    ht::readExr(path);
    FAIL() << "no error reading " << path;
  } catch (const ht::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(word), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST_F(ImageIo, ExrRoundTripIsBitExact) {
  ht::ImageRGB img;
  img.width = 61;
  img.height = 17;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> logMag(-6.0f, 5.0f);
  for (int i = 0; i < img.width * img.height; ++i) {
    glm::vec3 p;
    for (int c = 0; c < 3; ++c) p[c] = std::pow(10.0f, logMag(rng));
    img.pixels.push_back(p);
  }
  // Values that a lossy or half-precision path would alter.
  img.pixels[0] = {0.0f, -0.0f, -1.5f};
  img.pixels[1] = {std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::max(),
                   1.0f + std::numeric_limits<float>::epsilon()};
  img.pixels[2] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN(), 1e-6f};

  const std::string path = file("round trip.exr");
  ht::writeExr(path, img);
  const ht::ImageRGB back = ht::readExr(path);
  ASSERT_EQ(back.width, img.width);
  ASSERT_EQ(back.height, img.height);
  ASSERT_EQ(back.pixels.size(), img.pixels.size());
  for (size_t i = 0; i < img.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      ASSERT_EQ(bits(back.pixels[i][c]), bits(img.pixels[i][c])) << "pixel " << i << " channel " << c;
}

TEST_F(ImageIo, ShippedEnvironmentMapsLoad) {
  for (const char* name : {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"}) {
    SCOPED_TRACE(name);
    const ht::ImageRGB img = ht::readExr((kData / "env" / (std::string(name) + ".exr")).string());
    EXPECT_EQ(img.width, 1024);
    EXPECT_EQ(img.height, 512);
    ASSERT_EQ(img.pixels.size(), size_t(1024) * 512);
    float maxValue = 0.0f;
    for (const glm::vec3& p : img.pixels)
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(p[c]));
        maxValue = std::max(maxValue, p[c]);
      }
    // All eight are real HDR captures; a clipped or mis-scaled read would not reach this.
    EXPECT_GT(maxValue, 10.0f);
  }
}

TEST_F(ImageIo, SyntheticEnvironmentMaps) {
  const double pi = 3.14159265358979323846;
  auto texelSolidAngle = [&](int y, int w, int h) {
    return 2.0 * pi / w * (std::cos(pi * y / h) - std::cos(pi * (y + 1) / h));
  };

  const ht::ImageRGB constant = ht::readExr((kData / "env/synthetic-constant.exr").string());
  ASSERT_EQ(constant.width, 64);
  ASSERT_EQ(constant.height, 32);
  for (const glm::vec3& p : constant.pixels) ASSERT_EQ(p, glm::vec3(1.0f));

  const ht::ImageRGB hemi = ht::readExr((kData / "env/synthetic-black-hemisphere.exr").string());
  ASSERT_EQ(hemi.width, 64);
  ASSERT_EQ(hemi.height, 32);
  for (int y = 0; y < hemi.height; ++y)
    for (int x = 0; x < hemi.width; ++x) ASSERT_EQ(hemi.at(x, y), glm::vec3(y < 16 ? 1.0f : 0.0f)) << x << "," << y;

  // One texel at theta 40, phi 30 degrees carries power 10; the rest is 0.05.
  const ht::ImageRGB sun = ht::readExr((kData / "env/synthetic-sun.exr").string());
  ASSERT_EQ(sun.width, 256);
  ASSERT_EQ(sun.height, 128);
  const int sx = int(30.0 / 360.0 * 256), sy = int(40.0 / 180.0 * 128);
  for (int y = 0; y < sun.height; ++y)
    for (int x = 0; x < sun.width; ++x)
      if (x != sx || y != sy) {
        ASSERT_EQ(sun.at(x, y), glm::vec3(0.05f)) << x << "," << y;
      }
  const double sunPower = sun.at(sx, sy).x * texelSolidAngle(sy, 256, 128);
  EXPECT_NEAR(sunPower, 10.0, 1e-5);
  EXPECT_EQ(sun.at(sx, sy).x, sun.at(sx, sy).y);
  EXPECT_EQ(sun.at(sx, sy).x, sun.at(sx, sy).z);

  // Sky 0.4 0.6 1.0 above, ground 0.1 below, a 1-degree disc of radiance
  // 20000 at theta 50, phi 120 degrees.
  const ht::ImageRGB sky = ht::readExr((kData / "env/synthetic-sky-sun.exr").string());
  ASSERT_EQ(sky.width, 256);
  ASSERT_EQ(sky.height, 128);
  EXPECT_EQ(sky.at(0, 0), glm::vec3(0.4f, 0.6f, 1.0f));
  EXPECT_EQ(sky.at(200, 63), glm::vec3(0.4f, 0.6f, 1.0f));
  EXPECT_EQ(sky.at(200, 64), glm::vec3(0.1f));
  EXPECT_EQ(sky.at(0, 127), glm::vec3(0.1f));
  double discPower = 0.0;
  for (int y = 0; y < sky.height; ++y)
    for (int x = 0; x < sky.width; ++x) {
      const glm::vec3 base = y < 64 ? glm::vec3(0.4f, 0.6f, 1.0f) : glm::vec3(0.1f);
      discPower += (sky.at(x, y).z - base.z) * texelSolidAngle(y, 256, 128);
    }
  const double discExpected = (20000.0 - 1.0) * 2.0 * pi * (1.0 - std::cos(pi / 180.0));
  EXPECT_NEAR(discPower, discExpected, 0.01 * discExpected);
  const int cx = int(120.0 / 360.0 * 256), cy = int(50.0 / 180.0 * 128);
  EXPECT_GT(sky.at(cx, cy).x, 1000.0f);
}

TEST_F(ImageIo, ReadsTiledHalfRgbaWithOffsetDataWindow) {
  // A data window away from the origin and not a multiple of the tile size.
  const Imath::Box2i dataWindow({5, -3}, {5 + 36, -3 + 20});
  const int w = 37, h = 21;
  Imf::Header header(Imath::Box2i({0, 0}, {63, 31}), dataWindow);
  header.compression() = Imf::PIZ_COMPRESSION;
  std::vector<Imf::Rgba> pixels(size_t(w) * h);
  auto value = [](int x, int y, int c) { return 0.37f * x - 1.25f * y + 1000.0f * c + 0.001f; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      pixels[size_t(y) * w + x] = Imf::Rgba(value(x, y, 0), value(x, y, 1), value(x, y, 2), 0.5f);

  const std::string path = file("tiled.exr");
  {
    Imf::TiledRgbaOutputFile out(path.c_str(), header, Imf::WRITE_RGBA, 16, 8, Imf::ONE_LEVEL);
    out.setFrameBuffer(pixels.data() - dataWindow.min.x - ptrdiff_t(dataWindow.min.y) * w, 1, w);
    out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
  }

  const ht::ImageRGB img = ht::readExr(path);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        // half -> float is exact, so the read must reproduce the stored halves.
        ASSERT_EQ(img.at(x, y)[c], float(half(value(x, y, c)))) << x << "," << y << " c" << c;
}

TEST_F(ImageIo, LuminanceOnlyReadsAsGrey) {
  const int w = 9, h = 4;
  std::vector<float> lum(size_t(w) * h);
  for (size_t i = 0; i < lum.size(); ++i) lum[i] = 0.1f * float(i) + 1e-3f;
  const std::string path = file("grey.exr");
  {
    Imf::Header header(w, h);
    header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    Imf::OutputFile out(path.c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(lum.data()), sizeof(float), sizeof(float) * w));
    out.setFrameBuffer(fb);
    out.writePixels(h);
  }
  const ht::ImageRGB img = ht::readExr(path);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  for (size_t i = 0; i < lum.size(); ++i) ASSERT_EQ(img.pixels[i], glm::vec3(lum[i])) << i;
}

TEST_F(ImageIo, LuminanceChromaKeepsColour) {
  const int w = 8, h = 6;
  const std::string path = file("yc.exr");
  {
    std::vector<Imf::Rgba> pixels(size_t(w) * h, Imf::Rgba(1.0f, 0.2f, 0.1f, 1.0f));
    Imf::RgbaOutputFile out(path.c_str(), w, h, Imf::WRITE_YC);
    out.setFrameBuffer(pixels.data(), 1, w);
    out.writePixels(h);
  }
  const ht::ImageRGB img = ht::readExr(path);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  for (const glm::vec3& p : img.pixels) {
    EXPECT_NEAR(p.x, 1.0f, 0.02f);
    EXPECT_NEAR(p.y, 0.2f, 0.01f);
    EXPECT_NEAR(p.z, 0.1f, 0.01f);
  }
}

TEST_F(ImageIo, ReadErrors) {
  expectReadError(file("missing.exr"), "cannot open");

  const std::string text = file("notes.exr");
  spit(text, {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', '\n'});
  expectReadError(text, "not an OpenEXR file");

  const std::string tiny = file("tiny.exr");
  spit(tiny, {'v', '/'});
  expectReadError(tiny, "not an OpenEXR file");

  const std::vector<char> real = slurp((kData / "env/studio.exr").string());
  ASSERT_GT(real.size(), 10000u);
  const std::string cut1000 = file("cut1000.exr");
  spit(cut1000, std::vector<char>(real.begin(), real.begin() + 1000));
  expectReadError(cut1000, "truncated");
  const std::string cutHalf = file("cut-half.exr");
  spit(cutHalf, std::vector<char>(real.begin(), real.begin() + real.size() / 2));
  expectReadError(cutHalf, "truncated");

  const std::string noColour = file("depth.exr");
  {
    Imf::Header header(4, 4);
    header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
    std::vector<float> z(16, 1.0f);
    Imf::OutputFile out(noColour.c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert("Z", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(z.data()), sizeof(float), 4 * sizeof(float)));
    out.setFrameBuffer(fb);
    out.writePixels(4);
  }
  expectReadError(noColour, "colour channels");
}

// Writes a valid 1x1 EXR, then rewrites its dataWindow attribute so the
// header claims another size while the file stays a few hundred bytes.
std::string withDataWindow(const std::string& path, int minX, int minY, int maxX, int maxY) {
  ht::ImageRGB one;
  one.width = one.height = 1;
  one.pixels = {glm::vec3(1.0f)};
  ht::writeExr(path, one);
  std::vector<char> bytes = slurp(path);
  const std::string key("dataWindow\0box2i\0", 17);
  auto it = std::search(bytes.begin(), bytes.end(), key.begin(), key.end());
  EXPECT_NE(it, bytes.end());
  if (it == bytes.end()) return path;
  char* box = &*it + key.size() + 4;  // skip the attribute size
  const int32_t v[4] = {minX, minY, maxX, maxY};
  std::memcpy(box, v, sizeof v);  // EXR is little endian, as are our hosts
  spit(path, bytes);
  return path;
}

TEST_F(ImageIo, AbsurdDimensionsAreRefusedFromTheHeader) {
  // Without the header check these would try to allocate up to 120 GB.
  expectReadError(withDataWindow(file("huge.exr"), 0, 0, 99999, 99999), "too large");
  expectReadError(withDataWindow(file("wide.exr"), 0, 0, ht::kMaxImageDimension, 0), "too large");
  // Each side is allowed, the pixel count (4e8 > 2^28) is not.
  expectReadError(withDataWindow(file("many.exr"), -10000, -10000, 9999, 9999), "too large");
  expectReadError(withDataWindow(file("flat.exr"), 0, 0, -1, 0), "empty");
  // The patch itself is sound: the unchanged window still reads.
  EXPECT_EQ(ht::readExr(withDataWindow(file("same.exr"), 0, 0, 0, 0)).pixels.at(0), glm::vec3(1.0f));
}

TEST_F(ImageIo, WriteErrors) {
  ht::ImageRGB img;
  img.width = img.height = 2;
  img.pixels.assign(4, glm::vec3(0.5f));
  const std::string exr = file("no such dir/out.exr");
  const std::string png = file("no such dir/out.png");
  for (auto [path, write] : {std::pair<std::string, std::function<void()>>{exr, [&] { ht::writeExr(exr, img); }},
                             {png, [&] { ht::writePng(png, img); }}}) {
    try {
      write();
      ADD_FAILURE() << "no error writing " << path;
    } catch (const ht::Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("cannot write"), std::string::npos) << e.what();
    }
  }
  img.pixels.pop_back();
  EXPECT_THROW(ht::writeExr(file("bad.exr"), img), ht::Error);
}

std::vector<uint8_t> readPngRgb(const std::string& path, int& w, int& h) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  EXPECT_TRUE(png_image_begin_read_from_file(&png, path.c_str())) << png.message;
  // The file itself must be 8-bit RGB without alpha.
  EXPECT_EQ(png.format, PNG_FORMAT_RGB);
  w = int(png.width);
  h = int(png.height);
  std::vector<uint8_t> bytes(PNG_IMAGE_SIZE(png));
  EXPECT_TRUE(png_image_finish_read(&png, nullptr, bytes.data(), 0, nullptr)) << png.message;
  return bytes;
}

TEST_F(ImageIo, PngIsClampedSrgb) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  ht::ImageRGB img;
  img.width = 3;
  img.height = 2;
  img.pixels = {{0.0f, 0.5f, 1.0f}, {2.0f, nan, -1.0f}, {0.001f, inf, 0.18f},
                {0.25f, 0.09f, 0.5f}, {0.0f, 0.0f, 0.0f}, {1.0f, 1.0f, 1.0f}};
  const std::string path = file("preview.png");
  ht::writePng(path, img);
  int w = 0, h = 0;
  std::vector<uint8_t> got = readPngRgb(path, w, h);
  ASSERT_EQ(w, 3);
  ASSERT_EQ(h, 2);
  const std::vector<uint8_t> expected = {0, 188, 255, 255, 0, 0, 3, 255, 118,
                                         137, 85, 188, 0, 0, 0, 255, 255, 255};
  EXPECT_EQ(got, expected);

  // Exposure +1 doubles before encoding: 0.25 -> 0.5, 0.09 -> 0.18, 0.5 -> 1.
  ht::writePng(path, img, 1.0f);
  got = readPngRgb(path, w, h);
  ASSERT_EQ(got.size(), 18u);
  EXPECT_EQ(got[9], 188);
  EXPECT_EQ(got[10], 118);
  EXPECT_EQ(got[11], 255);
  EXPECT_EQ(got[1], 255);
}

// The error metrics by hand on two pixels: one scaled by 1.1, one whose
// colour changes while its luminance does not (only the RGB metrics see it).
TEST(ImageError, MatchesItsDefinitions) {
  ht::ImageRGB ref, test;
  ref.width = test.width = 2;
  ref.height = test.height = 1;
  ref.pixels = {{1.0f, 2.0f, 3.0f}, {0.5f, 0.5f, 0.5f}};
  const float dr = 0.1f, db = -dr * 0.2126f / 0.0722f;  // luminance unchanged
  test.pixels = {1.1f * ref.pixels[0], {0.5f + dr, 0.5f, 0.5f + db}};
  ht::ImageError e = ht::compareImages(ref, test);
  double se = 0.0, rel = 0.0, absRel = 0.0;
  for (int i = 0; i < 2; ++i)
    for (int c = 0; c < 3; ++c) {
      double r = ref.pixels[i][c], d = double(test.pixels[i][c]) - r;
      se += d * d;
      rel += d * d / (r * r + 1e-2);
      absRel += std::abs(d) / (std::abs(r) + 1e-2);
    }
  EXPECT_NEAR(e.rmse, std::sqrt(se / 6.0), 1e-7);
  EXPECT_NEAR(e.relMse, rel / 6.0, 1e-7);
  EXPECT_NEAR(e.meanAbsRelError, absRel / 6.0, 1e-7);
  const double y = 0.2126 + 0.7152 * 2.0 + 0.0722 * 3.0;  // first pixel's luminance; the second's error is 0
  EXPECT_NEAR(e.luminanceRelMse, (0.01 * y * y / (y * y + 1e-2) + 0.0) / 2.0, 1e-6);
  EXPECT_GT(e.relMse, 2.0 * e.luminanceRelMse);
  EXPECT_EQ(e.pixels, 2u);
}

}  // namespace
