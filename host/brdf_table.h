// Tabulated BRDF bounds, the talk's way: for a set of outgoing elevations,
// the maximum and the average of luminance(f cos) over cells of the
// incoming hemisphere, read through the rotation from world to local frame.
//
// Isotropic materials only depend on (theta_i, |phi_i - phi_o|), so each
// table is a grid over theta_i in [0, pi/2] and the relative azimuth in
// [0, pi]. A node of the HEALPix hierarchy (a cone) covers a (theta, phi)
// rectangle in that grid: its bound is the maximum over the cells of the
// rectangle, enlarged by a margin, read from a max pyramid; its average is
// interpolated bilinearly from the 4 cells around its centre.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/vec3.hpp>

#include "bsdf.h"

namespace ht {

class BrdfTable {
 public:
  static constexpr int kThetaO = 16;  // outgoing elevation bins over [0, pi/2]
  static constexpr int kTheta = 64;   // incoming elevation cells over [0, pi/2]
  static constexpr int kPhi = 128;    // relative azimuth cells over [0, pi]
  static constexpr float kMargin = 1.25f;

  explicit BrdfTable(const Material& m);

  // Bound of luminance(f cos) over the directions within `radius` of `wi`
  // (local frame: normal +z, wo in the x-z plane with x >= 0), for
  // outgoing elevation thetaO.
  float bound(float thetaO, const glm::vec3& wiLocal, float cosRadius, float sinRadius) const;
  // Average interpolated at a direction.
  float average(float thetaO, const glm::vec3& wiLocal) const;

  // The averages, then the max pyramid's levels, back to back (the GPU's copy).
  std::vector<float> flattened() const;

 private:
  int levels_ = 0;
  // maxima_[level][k] : pyramid of maxima per thetaO bin, level 0 = cells
  std::vector<std::vector<float>> maxima_;
  std::vector<float> averages_;  // per thetaO bin, per cell centre

  float maxAt(int level, int k, int it, int ip) const;
};

// ht*'s own table with tabulated bounds: one per scene material, in the scene's order.
struct BrdfTables {
  std::vector<std::shared_ptr<const BrdfTable>> perMaterial;
  // Throws an internal ht::Error for a material without its table.
  const BrdfTable& at(size_t material) const;
};

}  // namespace ht
