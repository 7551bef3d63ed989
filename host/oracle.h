// The variance floor of product sampling at a given resolution: per shading
// point, the discrete product env x BRDF x visibility over every HEALPix node
// of one level (environment average times f cos V averaged over 2 x 2 points
// of the node), a node drawn in proportion to it, then a pixel below it in
// proportion to the environment and a uniform direction in that pixel.
// Brute force: 4 x 12 x 4^order BRDF evaluations and shadow rays per point.
#pragma once

#include "integrator.h"

namespace ht {

glm::vec3 estimateOracle(const Scene& scene, const ShadingPoint& sp, int spp, int order, Rng& rng,
                         EstimateCounters& counters);

}  // namespace ht
