// libFuzzer target: arbitrary bytes as a Radiance .hdr environment map.
// readHdrFromMemory must either return a consistent image or throw ht::Error
// with a one-line message; the same goes for the checks and the resampling
// that follow in the renderer. Anything else (a crash, a sanitizer report,
// another exception, a huge allocation) is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "environment.h"
#include "image_io.h"
#include "one_line.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    ht::ImageRGB image = ht::readHdrFromMemory(data, size, "fuzz.hdr");
    if (image.width <= 0 || image.height <= 0 || image.width > ht::kMaxImageDimension ||
        image.height > ht::kMaxImageDimension || image.pixels.size() != size_t(image.width) * size_t(image.height))
      std::abort();
    ht::sanitizeEnvironmentImage(image, "fuzz.hdr");
    for (const glm::vec3& p : image.pixels)
      if (!(p.x >= 0.0f && p.y >= 0.0f && p.z >= 0.0f)) std::abort();  // finite and not negative
    ht::Environment env = ht::environmentFromEquirect(image, 1, 0.0f, 1.0f);
    if (env.radiance.size() != 48) std::abort();
  } catch (const ht::Error& e) {
    ht::fuzz::requireOneLine(e.what());
  }
  return 0;
}
