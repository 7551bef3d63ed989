// libFuzzer target: arbitrary bytes as an OpenEXR environment map.
// readExrFromMemory must either return a consistent image or throw
// ht::Error with a one-line message; the same goes for the checks and the
// resampling that follow in the renderer. Anything else (a crash, a
// sanitizer report, another exception, a huge allocation) is a finding.
#include <cstddef>
#include <cstdint>

#include "decoded_map.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ht::fuzz::requireDecodedMap([&] { return ht::readExrFromMemory(data, size, "fuzz.exr"); }, "fuzz.exr");
  return 0;
}
