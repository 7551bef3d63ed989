// write_test_hdr: writes an EXR's pixels as a Radiance RGBE (.hdr) file, for
// the command-line tests and the fuzzing seed corpus.
//
//   write_test_hdr --in map.exr --out map.hdr [--flat] [--resolution "+Y 4 +X 8"] [--header EXPOSURE=2]
//
// Run-length scanlines by default (where the width allows them), flat ones
// with --flat; --header lines replace the default FORMAT line, and
// --resolution replaces "-Y height +X width", so that bad files can be made too.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "image_io.h"
#include "rgbe_writer.h"

int main(int argc, char** argv) {
  CLI::App app{"write_test_hdr: an EXR as a Radiance .hdr file"};
  std::string in, out, resolution;
  std::vector<std::string> header;
  bool flat = false;
  app.add_option("--in", in, "EXR file")->required();
  app.add_option("--out", out, ".hdr file")->required();
  app.add_flag("--flat", flat, "flat scanlines (four bytes a pixel)");
  app.add_option("--header", header, "header lines (default: FORMAT=32-bit_rle_rgbe)");
  app.add_option("--resolution", resolution, "resolution line (default: -Y height +X width)");
  CLI11_PARSE(app, argc, argv);
  try {
    const ht::ImageRGB image = ht::readExr(in);
    ht::test::RgbeFile f;
    f.width = image.width;
    f.height = image.height;
    f.pixels = image.pixels;
    f.runLength = !flat && image.width >= 8 && image.width < 32768;
    if (!header.empty()) f.headerLines = header;
    f.resolution = resolution;
    const std::string bytes = ht::test::encodeRgbeFile(f);
    std::ofstream file(out, std::ios::binary);
    if (!file.write(bytes.data(), std::streamsize(bytes.size())) || !file.flush()) {
      std::fprintf(stderr, "write_test_hdr: cannot write %s\n", out.c_str());
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_test_hdr: %s\n", e.what());
    return 1;
  }
  return 0;
}
