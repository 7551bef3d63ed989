// The variance floor of product sampling: per shading point, the product
// env x BRDF x visibility tabulated over every HEALPix node of one level
// (environment average times f cos V at the centres of the node's four
// children), a node drawn in proportion to it, then refined level by level
// down to 3 levels below the environment's pixels, each child drawn in
// proportion to its environment average times f cos V at its centre, and a
// uniform direction in the final cell. A 0.2 % share of every choice goes to
// nodes whose points all missed the light but that are not surely dark (by
// the occluders' and the surface's caps), so that the estimate stays unbiased.
// Brute force: 4 x 12 x 4^order BRDF evaluations and shadow rays per point;
// the table must resolve the sharpest lobe (order 5 does for GGX alpha 0.02).
#pragma once

#include "sampler.h"
#include "shading.h"

namespace ht {

struct HtGeometry;

// `geometry`: buildHtGeometry of the map's order.
glm::vec3 estimateOracle(const Scene& scene, const ShadingPoint& sp, int spp, int order, const HtGeometry& geometry,
                         PixelSampler& sampler, EstimateCounters& counters);

}  // namespace ht
