// Compute pipelines from SPIR-V files, with the shader's interface checked
// against the host's structs (shaders/common.h) when the pipeline is made:
// binding sizes, array strides, push-constant size and workgroup size.
#pragma once

#include <volk.h>

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "vk/buffers.h"
#include "vk/device.h"

namespace ht::vk {

// Reads a SPIR-V file; a missing or malformed file is a one-line ht::Error.
std::vector<uint32_t> loadSpirv(const std::string& path);

// How a shader reads a binding: storage buffer, uniform block (small data
// read by all lanes alike), or uniform texel buffer (large read-only arrays
// gathered lane by lane).
enum class BindingKind { Storage, Uniform, UniformTexel };

// What a compute shader declares (set 0 buffers and texel buffers, push constants).
struct SpirvInterface {
  struct Binding {
    uint32_t set = 0, binding = 0;
    uint64_t staticSize = 0;     // bytes before a trailing runtime array
    uint64_t runtimeStride = 0;  // element stride of the trailing runtime array, 0 if none
    BindingKind kind = BindingKind::Storage;
  };
  std::vector<Binding> bindings;
  uint64_t pushConstantSize = 0;
  std::array<uint32_t, 3> localSize{0, 0, 0};
};
SpirvInterface reflectSpirv(std::span<const uint32_t> code);

// The host's side of one binding: the struct it holds, or the element of
// its array (set stride and leave staticSize 0).
struct BindingLayout {
  uint32_t binding;
  uint64_t staticSize;  // 0 for a texel buffer
  uint64_t runtimeStride;
  BindingKind kind = BindingKind::Storage;
};

class ComputePipeline {
 public:
  // specialization[i] is the value of the shader's constant_id i.
  ComputePipeline(Context& ctx, const std::string& spirvPath, std::span<const BindingLayout> bindings,
                  uint32_t pushConstantSize, std::array<uint32_t, 3> localSize,
                  std::span<const uint32_t> specialization = {});
  ~ComputePipeline();
  ComputePipeline(const ComputePipeline&) = delete;
  ComputePipeline& operator=(const ComputePipeline&) = delete;

  // Points `binding` at the whole of `buffer` (not while a dispatch using it is in flight).
  void setBuffer(uint32_t binding, const Buffer& buffer);
  // Points a texel buffer binding at `view`.
  void setTexelBuffer(uint32_t binding, VkBufferView view);
  // Binds the pipeline and its set, pushes the constants and dispatches.
  void dispatch(VkCommandBuffer cmd, const void* pushConstants, uint32_t groupsX, uint32_t groupsY,
                uint32_t groupsZ = 1) const;

 private:
  Context& ctx_;
  uint32_t pushSize_ = 0;
  VkShaderModule module_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  std::vector<std::pair<uint32_t, VkDescriptorType>> types_;  // per binding
  void destroy();
  VkDescriptorType descriptorType(uint32_t binding) const;
};

}  // namespace ht::vk
