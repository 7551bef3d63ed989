// ReSTIR-style spatial reuse for one still image (Bitterli, Wyman, Pharr,
// Shirley, Lefohn, Jarosz, "Spatiotemporal reservoir resampling for
// real-time ray tracing with dynamic direct lighting", SIGGRAPH 2020).
//
// --spp N runs N independent reuse chains per pixel; each shades one sample.
// A chain's passes run over the whole image, each reading the previous
// pass's reservoirs:
//   0. every pixel resamples M candidates from the environment and the BRDF
//      (ris.h: RisSampler::sample, the `ris` method's draws) towards
//      p_hat = luminance(L f cos) and keeps one sample y with its unbiased
//      contribution weight W and confidence M;
//   1..r. every pixel q takes its own reservoir and those of up to k
//      neighbours (uniform in a square of the given radius, rejected by
//      normal and depth as RTXDI does) from the same chain, and resamples
//      one of them;
//   r+1. every pixel shades its chain's y: L f cos V W, one shadow ray.
// restir (unbiased) weighs reservoir i's sample y_i by the generalized
// balance heuristic over the reservoirs taken,
//   m_i = M_i p_hat_i(y_i) / sum_j M_j p_hat_j(y_i),
// and resamples with m_i p_hat_q(y_i) W_i; W = sum / p_hat_q(y). The m_i
// of every x sum to one over the reservoirs whose pixel can produce x, as
// each reservoir's samples cover where its p_hat is positive (its
// candidates' mixture covers L f cos > 0, and no shadow ray zeroes a W
// before the final one). restir-biased is Bitterli's biased combination:
// a shadow ray zeroes W where the initial sample is blocked (visibility
// reuse), and W = sum_i p_hat_q(y_i) W_i M_i / (p_hat_q(y) sum_i M_i): it
// darkens where neighbours see light that q does not, and brightens the
// reverse, and its weights p_hat_q / p_hat_i are unbounded.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "common.h"  // shaders/common.h: GpuRestirPoint, GpuRestirReservoir
#include "render.h"
#include "scene.h"
#include "shading.h"
#include "tables.h"

namespace ht {

using RestirPoint = gpu::GpuRestirPoint;
using Reservoir = gpu::GpuRestirReservoir;

struct RestirOptions {
  int candidates = 32;  // M per chain and pixel
  int neighbours = 5;   // k per round
  int radius = 30;      // pixels, in x and in y
  int rounds = 2;       // r
  bool unbiased = true;
};
RestirOptions restirOptionsFor(Method method, const MethodOptions& options);

// Neighbours share a reservoir when their normals are within about 25
// degrees and their depths within 10 % (RTXDI's defaults).
inline constexpr float kRestirNormalCos = 0.9063f;
inline constexpr float kRestirDepthShare = 0.1f;

// The shading point behind pixel (x, y).
RestirPoint restirPoint(const Scene& scene, int width, int height, int x, int y);
ShadingPoint shadingPointOf(const Scene& scene, const RestirPoint& p);

// The random stream of a chain's round: the same on both devices.
uint32_t restirRoundSeed(uint32_t seed, int round, int chain);

// Pass 0 at one pixel (`sampler` seeded as estimateDirect seeds it).
Reservoir restirInitial(const Scene& scene, const RestirPoint& p, const RestirOptions& o, int chain,
                        PixelSampler& sampler, EstimateCounters& counters);
// One round at pixel (x, y) from the previous pass's reservoirs of one chain.
Reservoir restirRound(const Scene& scene, const std::vector<RestirPoint>& points, const Reservoir* previous,
                      int width, int height, int x, int y, const RestirOptions& o, uint32_t roundSeed);
// L f cos V W of a chain's final reservoir.
glm::dvec3 restirShade(const Scene& scene, const RestirPoint& p, const Reservoir& r, const RestirOptions& o,
                       EstimateCounters& counters);

// The whole image (render.h: renderCpu's part for these methods).
void renderRestir(const Scene& scene, const RenderSettings& s, RenderResult& out);

}  // namespace ht
