// libFuzzer target: arbitrary bytes as a scene file. parseScene must either
// return a scene the renderer can use (finite camera rays, sizes in range,
// unit normals, materials that exist) or throw ht::Error with a one-line
// message. Anything else is a finding.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include <glm/geometric.hpp>

#include "one_line.h"
#include "error.h"
#include "scene.h"

namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    ht::Scene scene = ht::parseScene(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
    if (scene.width < 1 || scene.height < 1 || scene.width > 16384 || scene.height > 16384) std::abort();
    if (scene.spheres.empty() && scene.planes.empty()) std::abort();
    const int nside = scene.environmentDesc.nside;
    if (nside < 1 || (nside & (nside - 1)) != 0 || scene.environmentDesc.file.empty()) std::abort();
    const int materials = int(scene.materials.size());
    for (const ht::Sphere& s : scene.spheres)
      if (!finite(s.center) || !(s.radius > 0.0f) || !std::isfinite(s.radius) || s.material < 0 ||
          s.material >= materials)
        std::abort();
    for (const ht::Plane& p : scene.planes)
      if (!finite(p.point) || !finite(p.normal) || std::abs(glm::length(p.normal) - 1.0f) > 1e-3f ||
          p.material < 0 || p.material >= materials)
        std::abort();
    // The camera must give finite unit rays through the corners and the centre.
    const float w = float(scene.width), h = float(scene.height);
    for (auto [px, py] : {std::pair{0.0f, 0.0f}, {w, 0.0f}, {0.0f, h}, {w, h}, {0.5f * w, 0.5f * h}}) {
      ht::Ray ray = ht::cameraRay(scene.camera, scene.width, scene.height, px, py);
      if (!finite(ray.origin) || !finite(ray.dir) || std::abs(glm::length(ray.dir) - 1.0f) > 1e-3f) std::abort();
    }
  } catch (const ht::Error& e) {
    ht::fuzz::requireOneLine(e.what());
  }
  return 0;
}
