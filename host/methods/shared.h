// What the method families' files share: the GPU states made in the
// *_gpu.cpp files and the visibility caps' limit on the GPU.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "method.h"

namespace ht {

std::unique_ptr<GpuMethodState> makeCompensatedGpuState();  // baselines_gpu.cpp
std::unique_ptr<GpuMethodState> makeHtGpuState();           // ht_gpu.cpp
std::unique_ptr<GpuMethodState> makeCompetitorGpuState();   // competitors_gpu.cpp
std::unique_ptr<GpuMethodState> makeFrontierGpuState();     // frontier_gpu.cpp
std::unique_ptr<GpuMethodState> makeRestirGpuState();       // reuse_gpu.cpp
std::unique_ptr<GpuMethodState> makeCutGpuState();          // cut_gpu.cpp

// --ris-candidates, which restir* shares (competitors.cpp).
extern const MethodOption kRisCandidates;

// The shaders hold HT_MAX_CAPS visibility caps per shading point, every
// plane's and the largest spheres' (capSpheres): a method whose density has
// them refuses scenes with more planes.
std::string gpuCapsLimit(Method method, const Scene& scene);

}  // namespace ht
