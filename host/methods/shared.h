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

// The shaders hold HT_MAX_CAPS visibility caps per shading point: a method
// whose density has them refuses scenes with more spheres and planes.
std::string gpuCapsLimit(Method method, size_t occluders);

}  // namespace ht
