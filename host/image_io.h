// HDR and preview image files: OpenEXR and Radiance .hdr in, OpenEXR and PNG out.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "error.h"
#include "image.h"

namespace ht {

// Largest width or height accepted from a file; bigger images are refused
// before anything is allocated.
constexpr int kMaxImageDimension = 32768;
// Throws ht::Error naming `name` unless width x height is a size the readers
// accept: both positive, at most kMaxImageDimension, at most 2^28 pixels.
void checkImageDimensions(const std::string& name, long long width, long long height);

// Either format, told apart by the name (.hdr, .pic, .rgbe) or the Radiance
// "#?" signature; OpenEXR otherwise.
ImageRGB readImage(const std::string& path);
// The size from the checked header alone; false if the file cannot be read.
// `decodeBytes`, if given, gets what reading the image holds for a while
// beyond its pixels (a .hdr file's bytes and the decoder's own copy).
bool readImageSize(const std::string& path, int& width, int& height, uint64_t* decodeBytes = nullptr);

// Radiance RGBE: flat or run-length scanlines, -Y H +X W orientation only
// (others are refused), FORMAT=32-bit_rle_rgbe, values divided by the
// header's EXPOSURE= factors. Throws ht::Error with a one-line message.
ImageRGB readHdr(const std::string& path);
ImageRGB readHdrFromMemory(const void* data, size_t size, const std::string& name);

// Reads scanline or tiled EXR, half or float, RGB or RGBA (Y only is read as
// grey). Throws ht::Error with a one-line message on any problem.
ImageRGB readExr(const std::string& path);
// The size from the checked header alone; false if the file cannot be read.
bool readExrSize(const std::string& path, int& width, int& height);
// The same as readExr from `size` bytes in memory; `name` stands for the file in messages.
ImageRGB readExrFromMemory(const void* data, size_t size, const std::string& name);
class OutputFile;
// Writes linear float RGB (uncompressed-size ZIP). Throws ht::Error. The
// path form replaces the file whole (host/output_file.h); the OutputFile
// form fills the temporary and leaves the commit to the caller.
void writeExr(const std::string& path, const ImageRGB& image);
void writeExr(OutputFile& file, const ImageRGB& image);
// Writes an 8-bit sRGB preview: value * 2^exposure, clamped, sRGB encoded.
void writePng(const std::string& path, const ImageRGB& image, float exposure = 0.0f);
void writePng(OutputFile& file, const ImageRGB& image, float exposure = 0.0f);

// Error of `test` against `ref` over all pixels and channels.
struct ImageError {
  double rmse = 0.0;             // sqrt(mean (t - r)^2)
  double relMse = 0.0;           // mean (t - r)^2 / (r^2 + 1e-2)
  double meanAbsRelError = 0.0;  // mean |t - r| / (|r| + 1e-2)
  double luminanceRelMse = 0.0;  // relMse of the luminance alone: without colour noise
  uint64_t pixels = 0;
};
ImageError compareImages(const ImageRGB& ref, const ImageRGB& test);

}  // namespace ht
