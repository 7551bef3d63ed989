// The CPU reference renderer: one primary ray through each pixel centre,
// direct illumination from the environment at the first hit, the environment
// itself where the ray escapes.
#pragma once

#include <cstdint>
#include <vector>

#include "image.h"
#include "integrator.h"
#include "scene.h"

namespace ht {

struct RenderSettings {
  Method method = Method::Mis;
  int spp = 16;
  uint32_t seed = 1;
  int width = 512;
  int height = 288;
  bool progress = false;  // percentage on stderr
  bool pixelCounts = false;  // keep each pixel's count of directions drawn
  MethodOptions options;
};

struct RenderResult {
  ImageRGB image;
  double seconds = 0.0;
  uint64_t shadedPixels = 0;
  EstimateCounters counters;
  std::vector<uint32_t> pixelDirections;  // with RenderSettings::pixelCounts: per pixel, y * width + x
};

// The options a render of `spp` samples per pixel runs with: those given,
// with the defaults that depend on spp settled (ht-cut's K, cutNodesFor).
MethodOptions optionsForSpp(MethodOptions options, int spp);

// Random stream of a pixel: the same for every method, device and thread count.
inline uint32_t pixelStream(int x, int y, int width) { return uint32_t(y) * uint32_t(width) + uint32_t(x); }

// `tables`: prepareTables of the settings' method and options.
RenderResult renderCpu(const Scene& scene, const RenderSettings& settings, const MethodTables& tables);
// The same, building the tables first (their time counted in the render's).
RenderResult renderCpu(const Scene& scene, const RenderSettings& settings);

}  // namespace ht
