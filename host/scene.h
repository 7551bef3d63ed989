// Scenes: a pinhole camera, analytic spheres and infinite planes, materials
// and the environment light. Nothing more.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "bsdf.h"
#include "bvh.h"
#include "shapes.h"
#include "environment.h"

namespace ht {

struct Camera {
  glm::vec3 position{0.0f, 0.0f, 5.0f};
  glm::vec3 lookAt{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fovY = 40.0f;  // degrees
};

struct EnvironmentDesc {
  std::string file;  // absolute or relative to the scene file
  int nside = 256;
  float yaw = 0.0f;  // degrees
  float scale = 1.0f;
  bool repairNonFinite = false;  // set NaN/Inf texels to 0 instead of refusing the map
};

struct Scene {
  std::string path;
  Camera camera;
  int width = 512, height = 288;
  std::vector<Material> materials;
  std::vector<std::string> materialNames;
  std::vector<Sphere> spheres;
  std::vector<Plane> planes;
  // Over `spheres`, made by parseScene; where it covers another number of
  // spheres (a scene assembled by hand), rays scan them all.
  Bvh sphereBvh;
  EnvironmentDesc environmentDesc;
  Environment environment;
  EnvironmentStats environmentStats;
};

struct Hit {
  float t = 0.0f;
  glm::vec3 position{0.0f};
  glm::vec3 normal{0.0f};  // geometric normal, unit, facing the incoming ray
  int material = -1;
  bool flat = false;       // on a plane: every point of the surface has this normal
};

// Parses and validates the JSON scene; throws ht::Error (with line and
// column for syntax errors). Does not load the environment.
Scene parseScene(const std::string& jsonText, const std::string& path);
Scene readSceneFile(const std::string& path);
// Reads, validates and resamples the environment map named by the scene.
void loadEnvironment(Scene& scene);

Ray cameraRay(const Camera& camera, int width, int height, float px, float py);
// Nearest hit with t in (tMin, tMax).
bool intersectScene(const Scene& scene, const Ray& ray, float tMin, float tMax, Hit& hit);
// True if anything blocks the ray leaving `origin` in direction `dir`.
bool occluded(const Scene& scene, const glm::vec3& origin, const glm::vec3& dir);
// Origin for rays leaving a surface point, pushed off along the normal.
glm::vec3 offsetRayOrigin(const glm::vec3& p, const glm::vec3& n);

// The spheres whose visibility caps a shading point keeps, in increasing
// index order: every sphere when the scene has at most `k`; else the k
// largest as seen from `origin` (the sine of the angular radius,
// min(1, r / d)) among those not wholly below the plane through `origin`
// with normal `normal`, ties to the lower index. Found through the BVH with
// a bound that skips a box none of whose spheres can rank.
std::vector<uint32_t> capSpheres(const Scene& scene, const glm::vec3& origin, const glm::vec3& normal, size_t k);
// A sphere's rank as capSpheres sees it; false where it is not ranked (at
// the origin, or wholly below the plane).
bool capRank(const Sphere& s, const glm::vec3& origin, const glm::vec3& normal, float& sine);

}  // namespace ht
