// Radiance .hdr input: exact values from flat and run-length scanlines, the
// header's options, and a one-line refusal for every kind of bad file.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "image_io.h"
#include "rgbe_writer.h"

namespace fs = std::filesystem;
using ht::test::RgbeFile;

namespace {

// A map with what real ones hold: smooth rows that run-length code well,
// noisy ones that do not, black texels and a bright sun.
RgbeFile testMap(int width, int height, uint32_t seed = 1) {
  RgbeFile f;
  f.width = width;
  f.height = height;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      glm::vec3 c = y % 3 == 0   ? glm::vec3(0.25f, 0.5f, 1.0f)
                    : y % 3 == 1 ? glm::vec3(u(rng), u(rng), u(rng)) * 3.0f
                                 : glm::vec3(x % 5 == 0 ? 0.0f : 0.01f * float(x));
      if (x == width / 2 && y == height / 2) c = glm::vec3(5.0e4f, 4.0e4f, 3.0e4f);
      f.pixels.push_back(c);
    }
  return f;
}

ht::ImageRGB decode(const std::string& bytes) { return ht::readHdrFromMemory(bytes.data(), bytes.size(), "map.hdr"); }

// The error message of decoding `bytes`, which must be one line.
std::string errorOf(const std::string& bytes) {
  try {
    decode(bytes);
  } catch (const ht::Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.rfind("map.hdr: ", 0), 0u) << what;
    return what;
  }
  ADD_FAILURE() << "decoded without an error";
  return "";
}

std::string withResolution(const std::string& resolution) {
  RgbeFile f = testMap(16, 4);
  f.resolution = resolution;
  return ht::test::encodeRgbeFile(f);
}

void expectExactDecode(const RgbeFile& f, const ht::ImageRGB& image, float divide = 1.0f) {
  ASSERT_EQ(image.width, f.width);
  ASSERT_EQ(image.height, f.height);
  for (size_t i = 0; i < f.pixels.size(); ++i) {
    uint8_t rgbe[4];
    ht::test::encodeRgbe(f.pixels[i], rgbe);
    const glm::vec3 want = ht::test::decodeRgbe(rgbe) / divide;
    ASSERT_EQ(image.pixels[i], want) << "pixel " << i;
    // The shared exponent keeps each channel within 1/256 of the brightest.
    const glm::vec3 p = f.pixels[i] / divide;
    const float tol = std::max(p.x, std::max(p.y, p.z)) / 256.0f;
    ASSERT_NEAR(image.pixels[i].x, p.x, tol);
    ASSERT_NEAR(image.pixels[i].z, p.z, tol);
  }
}

}  // namespace

TEST(HdrIo, RunLengthAndFlatScanlinesDecodeToTheEncodedValues) {
  RgbeFile f = testMap(300, 7);  // runs longer than 127 and dumps longer than 128
  const std::string rle = ht::test::encodeRgbeFile(f);
  f.runLength = false;
  const std::string flat = ht::test::encodeRgbeFile(f);
  EXPECT_LT(rle.size(), flat.size());
  expectExactDecode(f, decode(rle));
  expectExactDecode(f, decode(flat));
}

TEST(HdrIo, NarrowAndSmallMaps) {
  for (int width : {1, 5, 7, 8, 9}) {
    RgbeFile f = testMap(width, 3, uint32_t(width));
    f.runLength = width >= 8;
    expectExactDecode(f, decode(ht::test::encodeRgbeFile(f)));
  }
}

TEST(HdrIo, HeaderVariantsAndExposure) {
  RgbeFile f = testMap(12, 4);
  f.signature = "#?RGBE";
  f.headerLines = {"# made by a test", "GAMMA=1.0", "FORMAT=32-bit_rle_rgbe"};
  expectExactDecode(f, decode(ht::test::encodeRgbeFile(f)));
  // No FORMAT line means RGBE; another program's signature is still Radiance.
  f.signature = "#?hdrgen";
  f.headerLines = {};
  expectExactDecode(f, decode(ht::test::encodeRgbeFile(f)));
  // Stored values are radiance times the product of the EXPOSURE lines.
  f.headerLines = {"EXPOSURE=2", "FORMAT=32-bit_rle_rgbe", "EXPOSURE= 2.5 "};
  expectExactDecode(f, decode(ht::test::encodeRgbeFile(f)), 5.0f);
}

TEST(HdrIo, BadFilesGetOneLineErrors) {
  EXPECT_NE(errorOf("").find("empty file"), std::string::npos);
  EXPECT_NE(errorOf(std::string("\x76\x2f\x31\x01\x02\0\0\0", 8)).find("no #? signature"), std::string::npos);
  EXPECT_NE(errorOf("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n").find("no blank line"), std::string::npos);
  EXPECT_NE(errorOf("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n").find("no resolution line"), std::string::npos);
  EXPECT_NE(errorOf(std::string("#?RADIANCE") + std::string(70000, 'x')).find("within 64 KiB"), std::string::npos);

  RgbeFile xyze = testMap(8, 2);
  xyze.headerLines = {"FORMAT=32-bit_rle_xyze"};
  EXPECT_NE(errorOf(ht::test::encodeRgbeFile(xyze)).find("unsupported Radiance pixel format \"32-bit_rle_xyze\""),
            std::string::npos);
  RgbeFile exposure = testMap(8, 2);
  exposure.headerLines = {"EXPOSURE=-1"};
  EXPECT_NE(errorOf(ht::test::encodeRgbeFile(exposure)).find("EXPOSURE must be a positive number"), std::string::npos);
  exposure.headerLines = {"EXPOSURE=1e39"};
  EXPECT_NE(errorOf(ht::test::encodeRgbeFile(exposure)).find("is outside [1e-6, 1e6]"), std::string::npos);
  exposure.headerLines = {"EXPOSURE=1e-5", "EXPOSURE=1e-5"};
  EXPECT_NE(errorOf(ht::test::encodeRgbeFile(exposure)).find("EXPOSURE 1e-10 (the product"), std::string::npos);

  EXPECT_NE(errorOf(withResolution("+Y 4 +X 16")).find("unsupported Radiance orientation \"+Y 4 +X 16\""),
            std::string::npos);
  EXPECT_NE(errorOf(withResolution("+X 16 -Y 4")).find("unsupported Radiance orientation"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y 4 -X 16")).find("unsupported Radiance orientation"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y four +X 16")).find("bad Radiance resolution line"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y 4 +X 16 extra")).find("bad Radiance resolution line"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y 4 +X 0")).find("empty image (0x4)"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y -4 +X 16")).find("empty image"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y 100000 +X 100000")).find("image too large"), std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y 99999999999999999999 +X 8")).find("bad Radiance resolution line"),
            std::string::npos);
  EXPECT_NE(errorOf(withResolution("-Y 20000 +X 20000")).find("2^28 pixels"), std::string::npos);
  // Within the limits, but the file cannot hold so many scanlines: refused
  // from its size, before the pixels are allocated.
  EXPECT_NE(errorOf(withResolution("-Y 16384 +X 16384")).find("cannot hold 16384x16384 pixels"), std::string::npos);
}

TEST(HdrIo, TruncatedAndCorruptScanlines) {
  RgbeFile f = testMap(64, 16);
  const std::string rle = ht::test::encodeRgbeFile(f);
  const size_t header = rle.find("+X 64\n") + 6;
  // Cut inside the data: the size check passes for run-length data, the
  // decoder runs out of bytes.
  for (size_t keep : {size_t(0), size_t(3), (rle.size() - header) / 2, rle.size() - header - 1})
    EXPECT_NE(errorOf(rle.substr(0, header + keep)).find("truncated Radiance .hdr file"), std::string::npos) << keep;
  f.runLength = false;
  const std::string flat = ht::test::encodeRgbeFile(f);
  EXPECT_NE(errorOf(flat.substr(0, flat.size() - 1)).find("cannot hold 64x16 pixels"), std::string::npos);

  // A run longer than what is left of the scanline.
  std::string bad = rle;
  bad[header + 4] = char(128 + 100);
  EXPECT_NE(errorOf(bad).find("corrupt Radiance .hdr file (bad run-length data in row 0)"), std::string::npos);
  // A dump of no bytes (stb_image would loop on it for ever at the end of a file).
  bad = rle;
  bad[header + 4] = 0;
  EXPECT_NE(errorOf(bad).find("bad run-length data in row 0"), std::string::npos);
  // A run-length scanline that announces another width.
  bad = rle;
  bad[header + 3] = 65;
  EXPECT_NE(errorOf(bad).find("corrupt Radiance .hdr file (a scanline's length is not the image's width, in row 0)"),
            std::string::npos);
  // A flat row after run-length ones: stb_image would restart at the first pixel.
  RgbeFile two = testMap(64, 2);
  RgbeFile firstRow = two, secondRow = two;
  firstRow.height = secondRow.height = 1;
  firstRow.pixels.resize(64);
  secondRow.pixels.erase(secondRow.pixels.begin(), secondRow.pixels.begin() + 64);
  secondRow.runLength = false;
  const std::string a = ht::test::encodeRgbeFile(firstRow), b = ht::test::encodeRgbeFile(secondRow);
  auto scanlines = [](const std::string& file) { return file.substr(file.find("+X 64\n") + 6); };
  const std::string full = ht::test::encodeRgbeFile(two);
  const std::string mixed = full.substr(0, full.find("+X 64\n") + 6) + scanlines(a) + scanlines(b);
  EXPECT_NE(errorOf(mixed).find("unsupported Radiance .hdr file (row 1 is flat after run-length rows)"),
            std::string::npos);
}

TEST(HdrIo, FilesAreReadByTheirFormat) {
  const fs::path dir = fs::temp_directory_path() / ("ht_hdr_io_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  RgbeFile f = testMap(20, 10);
  const std::string bytes = ht::test::encodeRgbeFile(f);
  for (const char* name : {"map.hdr", "map.HDR", "map.pic", "radiance-without-extension"}) {
    const std::string path = (dir / name).string();
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
    expectExactDecode(f, ht::readImage(path));
    int w = 0, h = 0;
    ASSERT_TRUE(ht::readImageSize(path, w, h));
    EXPECT_EQ(w, 20);
    EXPECT_EQ(h, 10);
  }
  // An EXR is an EXR whatever its name... unless the name says .hdr.
  ht::ImageRGB exr;
  exr.width = 4;
  exr.height = 2;
  exr.pixels.assign(8, glm::vec3(0.5f));
  ht::writeExr((dir / "map.exr").string(), exr);
  EXPECT_EQ(ht::readImage((dir / "map.exr").string()).pixels, exr.pixels);
  fs::copy_file(dir / "map.exr", dir / "exr-named.hdr");
  try {
    ht::readImage((dir / "exr-named.hdr").string());
    ADD_FAILURE() << "an EXR named .hdr was read";
  } catch (const ht::Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a Radiance .hdr file (no #? signature)"), std::string::npos) << e.what();
  }
  try {
    ht::readImage((dir / "missing.hdr").string());
    ADD_FAILURE() << "a missing file was read";
  } catch (const ht::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
