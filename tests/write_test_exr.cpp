// write_test_exr: writes small EXR files with exact texel values, including
// the ones no sane map holds (NaN, Inf, negatives), for the command-line
// tests and the fuzzing seed corpus.
//
//   write_test_exr --out f.exr --width 8 --height 4 --fill 1 --set 5,1,nan,1,1 --set 2,3,-5
//
// --fill and --set take one grey value or R,G,B; values are parsed by
// strtof, so "nan", "inf" and "-inf" work. --set x,y,... overrides one pixel.
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfTiledOutputPart.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <Imath/half.h>

namespace {

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> parts;
  std::stringstream ss(s);
  for (std::string p; std::getline(ss, p, ',');) parts.push_back(p);
  return parts;
}

float number(const std::string& s) {
  char* end = nullptr;
  errno = 0;
  float v = std::strtof(s.c_str(), &end);
  if (s.empty() || *end != '\0') throw std::runtime_error("not a number: \"" + s + "\"");
  return v;
}

// One grey value or three: R,G,B.
void colour(const std::vector<std::string>& parts, size_t first, float rgb[3]) {
  if (parts.size() == first + 1) {
    rgb[0] = rgb[1] = rgb[2] = number(parts[first]);
  } else if (parts.size() == first + 3) {
    for (int c = 0; c < 3; ++c) rgb[c] = number(parts[first + c]);
  } else {
    throw std::runtime_error("expected one value or R,G,B");
  }
}

Imf::Compression compression(const std::string& name) {
  if (name == "none") return Imf::NO_COMPRESSION;
  if (name == "rle") return Imf::RLE_COMPRESSION;
  if (name == "zips") return Imf::ZIPS_COMPRESSION;
  if (name == "zip") return Imf::ZIP_COMPRESSION;
  if (name == "piz") return Imf::PIZ_COMPRESSION;
  if (name == "pxr24") return Imf::PXR24_COMPRESSION;
  if (name == "b44") return Imf::B44_COMPRESSION;
  if (name == "dwab") return Imf::DWAB_COMPRESSION;
  throw std::runtime_error("unknown compression \"" + name + "\"");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"write_test_exr: small EXR files with exact (also invalid) texel values"};
  std::string out, fill = "1", channels = "RGB", type = "float", comp = "zip";
  std::vector<std::string> sets;
  int width = 8, height = 4, tile = 0, parts = 1;
  bool mipmap = false;
  app.add_option("--out", out, "output EXR")->required();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--fill", fill, "value of every texel: v or R,G,B")->capture_default_str();
  app.add_option("--set", sets, "x,y,v or x,y,R,G,B for one texel (repeatable)");
  app.add_option("--channels", channels, "RGB, RGBA, Y, Z or YC (luminance/chroma, half)")->capture_default_str();
  app.add_option("--type", type, "float or half")->capture_default_str();
  app.add_option("--compression", comp, "none, rle, zips, zip, piz, pxr24, b44, dwab")->capture_default_str();
  app.add_option("--tile", tile, "write tiles of this size instead of scan lines");
  app.add_flag("--mipmap", mipmap, "tiled: with mipmap levels (each the top-left corner of the image)");
  app.add_option("--parts", parts, "write a multi-part file of this many identical parts");
  CLI11_PARSE(app, argc, argv);

  try {
    if (width < 1 || height < 1) throw std::runtime_error("--width and --height must be positive");
    std::vector<float> rgb(size_t(width) * height * 3);
    float base[3];
    colour(split(fill), 0, base);
    for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = base[i % 3];
    for (const std::string& s : sets) {
      std::vector<std::string> parts = split(s);
      if (parts.size() < 3) throw std::runtime_error("--set needs x,y,value");
      int x = int(number(parts[0])), y = int(number(parts[1]));
      if (x < 0 || x >= width || y < 0 || y >= height) throw std::runtime_error("--set outside the image: " + s);
      colour(parts, 2, &rgb[(size_t(y) * width + x) * 3]);
    }

    if (channels == "YC") {
      // OpenEXR's own luminance/chroma encoding (subsampled chroma).
      std::vector<Imf::Rgba> px(size_t(width) * height);
      for (size_t i = 0; i < px.size(); ++i) px[i] = Imf::Rgba(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2], 1.0f);
      Imf::RgbaOutputFile file(out.c_str(), width, height, Imf::WRITE_YC, 1.0f, Imath::V2f(0, 0), 1.0f,
                               Imf::INCREASING_Y, compression(comp));
      file.setFrameBuffer(px.data(), 1, width);
      file.writePixels(height);
      return 0;
    }
    std::vector<std::string> names;
    if (channels == "RGB" || channels == "RGBA") names = {"R", "G", "B"};
    else if (channels == "Y") names = {"Y"};
    else if (channels == "Z") names = {"Z"};
    else throw std::runtime_error("unknown --channels \"" + channels + "\"");
    if (channels == "RGBA") names.push_back("A");
    const bool useHalf = type == "half";
    if (!useHalf && type != "float") throw std::runtime_error("unknown --type \"" + type + "\"");

    // Planar copies in the file's pixel type: R G B from rgb, Y and Z from R, A = 1.
    const size_t n = size_t(width) * height;
    std::vector<std::vector<float>> planesF(names.size(), std::vector<float>(n));
    std::vector<std::vector<::half>> planesH;
    for (size_t c = 0; c < names.size(); ++c)
      for (size_t i = 0; i < n; ++i)
        planesF[c][i] = names[c] == "A" ? 1.0f : rgb[i * 3 + (names[c] == "G" ? 1 : names[c] == "B" ? 2 : 0)];
    Imf::Header header(width, height);
    header.compression() = compression(comp);
    Imf::FrameBuffer fb;
    const Imf::PixelType pt = useHalf ? Imf::HALF : Imf::FLOAT;
    const size_t elem = useHalf ? sizeof(::half) : sizeof(float);
    if (useHalf) {
      for (auto& p : planesF) {
        planesH.emplace_back(p.size());
        for (size_t i = 0; i < p.size(); ++i) planesH.back()[i] = ::half(p[i]);
      }
    }
    for (size_t c = 0; c < names.size(); ++c) {
      header.channels().insert(names[c], Imf::Channel(pt));
      char* data = useHalf ? reinterpret_cast<char*>(planesH[c].data()) : reinterpret_cast<char*>(planesF[c].data());
      fb.insert(names[c], Imf::Slice(pt, data, elem, elem * width));
    }
    if (tile > 0)
      header.setTileDescription(Imf::TileDescription(tile, tile, mipmap ? Imf::MIPMAP_LEVELS : Imf::ONE_LEVEL));
    if (parts > 1) {
      std::vector<Imf::Header> headers(size_t(parts), header);
      for (int p = 0; p < parts; ++p) {
        headers[p].setName("part" + std::to_string(p));
        headers[p].setType(tile > 0 ? Imf::TILEDIMAGE : Imf::SCANLINEIMAGE);
      }
      Imf::MultiPartOutputFile file(out.c_str(), headers.data(), parts);
      for (int p = 0; p < parts; ++p) {
        if (tile > 0) {
          Imf::TiledOutputPart part(file, p);
          part.setFrameBuffer(fb);
          for (int l = 0; l < part.numLevels(); ++l)
            part.writeTiles(0, part.numXTiles(l) - 1, 0, part.numYTiles(l) - 1, l);
        } else {
          Imf::OutputPart part(file, p);
          part.setFrameBuffer(fb);
          part.writePixels(height);
        }
      }
    } else if (tile > 0) {
      Imf::TiledOutputFile file(out.c_str(), header);
      file.setFrameBuffer(fb);
      // Every level gets the top-left corner of the full-resolution frame
      // buffer: test files only need a valid structure.
      for (int l = 0; l < file.numLevels(); ++l)
        file.writeTiles(0, file.numXTiles(l) - 1, 0, file.numYTiles(l) - 1, l);
    } else {
      Imf::OutputFile file(out.c_str(), header);
      file.setFrameBuffer(fb);
      file.writePixels(height);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_test_exr: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
