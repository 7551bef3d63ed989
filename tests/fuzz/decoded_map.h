// What a fuzz target of an image reader asks of what it decoded: a
// consistent image that the renderer's checks and resampling take or refuse
// with a one-line ht::Error. Anything else aborts, a finding.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <string>

#include "environment.h"
#include "image_io.h"
#include "one_line.h"

namespace ht::fuzz {

// `read` decodes the input (throwing ht::Error on bad input); `name` stands
// for the file in messages.
template <class Read>
void requireDecodedMap(Read read, const std::string& name) {
  try {
    ht::ImageRGB image = read();
    if (image.width <= 0 || image.height <= 0 || image.width > ht::kMaxImageDimension ||
        image.height > ht::kMaxImageDimension || image.pixels.size() != size_t(image.width) * size_t(image.height))
      std::abort();
    ht::sanitizeEnvironmentImage(image, name);
    for (const glm::vec3& p : image.pixels)
      if (!(p.x >= 0.0f && p.y >= 0.0f && p.z >= 0.0f)) std::abort();  // finite and not negative
    ht::Environment env = ht::environmentFromEquirect(image, 1, 0.0f, 1.0f);
    if (env.radiance.size() != 48) std::abort();
  } catch (const ht::Error& e) {
    requireOneLine(e.what());
  }
}

}  // namespace ht::fuzz
