// The scene's analytic shapes and rays (scene.h holds the scene).
#pragma once

#include <glm/vec3.hpp>

namespace ht {

struct Sphere {
  glm::vec3 center;
  float radius;
  int material;
};

struct Plane {
  glm::vec3 point;
  glm::vec3 normal;  // unit
  int material;
};

struct Ray {
  glm::vec3 origin;
  glm::vec3 dir;  // unit
};

}  // namespace ht
