// An image in memory: linear float RGB (image_io.h reads and writes files).
#pragma once

#include <cstddef>
#include <vector>

#include <glm/vec3.hpp>

namespace ht {

// Linear float RGB, row-major, top row first.
struct ImageRGB {
  int width = 0;
  int height = 0;
  std::vector<glm::vec3> pixels;

  glm::vec3& at(int x, int y) { return pixels[size_t(y) * width + x]; }
  const glm::vec3& at(int x, int y) const { return pixels[size_t(y) * width + x]; }
};

}  // namespace ht
