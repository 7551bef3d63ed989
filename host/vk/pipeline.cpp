#include "vk/pipeline.h"

#include <algorithm>
#include <fstream>
#include <map>

#include <fmt/format.h>

#include "error.h"  // ht::Error

namespace ht::vk {
namespace {

// SPIR-V opcodes, decorations and storage classes used below (SPIR-V 1.5 spec).
enum : uint32_t {
  OpExecutionMode = 16, OpTypeInt = 21, OpTypeFloat = 22, OpTypeVector = 23, OpTypeArray = 28,
  OpTypeRuntimeArray = 29, OpTypeStruct = 30, OpTypePointer = 32, OpConstant = 43, OpVariable = 59,
  OpDecorate = 71, OpMemberDecorate = 72,
};
enum : uint32_t { DecArrayStride = 6, DecBinding = 33, DecDescriptorSet = 34, DecOffset = 35 };
enum : uint32_t { ScUniformConstant = 0, ScUniform = 2, ScPushConstant = 9, ScStorageBuffer = 12, ScPhysicalStorageBuffer = 5349 };
constexpr uint32_t kExecutionModeLocalSize = 17;
constexpr uint32_t kSpirvMagic = 0x07230203;

struct Type {
  uint32_t op = 0;
  std::vector<uint32_t> operands;  // words after the result id
};

struct Module {
  std::map<uint32_t, Type> types;
  std::map<uint32_t, uint32_t> constants;
  std::map<uint32_t, uint32_t> arrayStride;
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> memberOffset;
  std::map<uint32_t, uint32_t> binding, set;

  // Size in bytes under the offsets and strides the module declares; a
  // trailing runtime array counts as 0.
  uint64_t size(uint32_t id) const {
    const Type& t = types.at(id);
    switch (t.op) {
      case OpTypeInt:
      case OpTypeFloat: return t.operands[0] / 8;
      case OpTypeVector: return size(t.operands[0]) * t.operands[1];
      case OpTypeArray: return uint64_t(arrayStride.at(id)) * constants.at(t.operands[1]);
      case OpTypeRuntimeArray: return 0;
      case OpTypePointer: return 8;  // physical storage buffer reference
      case OpTypeStruct: {
        uint64_t end = 0;
        for (uint32_t m = 0; m < t.operands.size(); ++m)
          end = std::max(end, memberOffset.at({id, m}) + size(t.operands[m]));
        return end;
      }
      default: throw Error(fmt::format("SPIR-V reflection: unexpected type (opcode {})", t.op));
    }
  }
};

}  // namespace

std::vector<uint32_t> loadSpirv(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in)
    throw Error(fmt::format("{}: SPIR-V shader not found (the shaders/ folder of the build must sit next to the "
                            "htrender binary)", path));
  const std::streamsize bytes = in.tellg();
  in.seekg(0);
  std::vector<uint32_t> code(size_t(std::max<std::streamsize>(bytes, 0)) / 4);
  in.read(reinterpret_cast<char*>(code.data()), std::streamsize(code.size() * 4));
  if (!in || bytes % 4 != 0 || code.size() < 5 || code[0] != kSpirvMagic)
    throw Error(fmt::format("{}: not a SPIR-V module", path));
  return code;
}

SpirvInterface reflectSpirv(std::span<const uint32_t> code) {
  Module m;
  SpirvInterface iface;
  std::vector<std::pair<uint32_t, uint32_t>> variables;  // (pointer type, id)
  for (size_t i = 5; i < code.size();) {
    const uint32_t words = code[i] >> 16, op = code[i] & 0xFFFF;
    if (words == 0 || i + words > code.size()) throw Error("SPIR-V reflection: truncated module");
    const uint32_t* w = &code[i];
    switch (op) {
      case OpExecutionMode:
        if (w[2] == kExecutionModeLocalSize) iface.localSize = {w[3], w[4], w[5]};
        break;
      case OpTypeInt:
      case OpTypeFloat:
      case OpTypeVector:
      case OpTypeArray:
      case OpTypeRuntimeArray:
      case OpTypeStruct:
      case OpTypePointer:
        m.types[w[1]] = Type{op, std::vector<uint32_t>(w + 2, w + words)};
        break;
      case OpConstant:
        m.constants[w[2]] = w[3];
        break;
      case OpVariable:
        variables.emplace_back(w[1], w[2]);
        break;
      case OpDecorate:
        if (w[2] == DecArrayStride) m.arrayStride[w[1]] = w[3];
        if (w[2] == DecBinding) m.binding[w[1]] = w[3];
        if (w[2] == DecDescriptorSet) m.set[w[1]] = w[3];
        break;
      case OpMemberDecorate:
        if (w[3] == DecOffset) m.memberOffset[{w[1], w[2]}] = w[4];
        break;
      default:
        break;
    }
    i += words;
  }
  for (auto [pointerType, id] : variables) {
    const Type& ptr = m.types.at(pointerType);
    const uint32_t storage = ptr.operands[0], block = ptr.operands[1];
    if (storage == ScPushConstant) {
      iface.pushConstantSize = m.size(block);
    } else if (storage == ScUniformConstant && m.binding.count(id)) {
      SpirvInterface::Binding b;
      b.set = m.set.count(id) ? m.set.at(id) : 0;
      b.binding = m.binding.at(id);
      b.kind = BindingKind::UniformTexel;
      iface.bindings.push_back(b);
    } else if ((storage == ScStorageBuffer || storage == ScUniform) && m.binding.count(id)) {
      SpirvInterface::Binding b;
      b.set = m.set.count(id) ? m.set.at(id) : 0;
      b.binding = m.binding.at(id);
      b.staticSize = m.size(block);
      b.kind = storage == ScUniform ? BindingKind::Uniform : BindingKind::Storage;
      const Type& s = m.types.at(block);
      if (s.op == OpTypeStruct && !s.operands.empty()) {
        const Type& last = m.types.at(s.operands.back());
        if (last.op == OpTypeRuntimeArray) b.runtimeStride = m.arrayStride.at(s.operands.back());
      }
      iface.bindings.push_back(b);
    }
  }
  return iface;
}

ComputePipeline::ComputePipeline(Context& ctx, const std::string& path, std::span<const BindingLayout> bindings,
                                 uint32_t pushConstantSize, std::array<uint32_t, 3> localSize,
                                 std::span<const uint32_t> specialization)
    : ctx_(ctx), pushSize_(pushConstantSize) {
  const std::vector<uint32_t> code = loadSpirv(path);
  const SpirvInterface iface = reflectSpirv(code);
  auto mismatch = [&](const std::string& what) {
    return Error(fmt::format("{}: {} (shader and host out of step: rebuild)", path, what));
  };
  if (iface.localSize != localSize)
    throw mismatch(fmt::format("workgroup {}x{}x{}, host expects {}x{}x{}", iface.localSize[0], iface.localSize[1],
                               iface.localSize[2], localSize[0], localSize[1], localSize[2]));
  if (iface.pushConstantSize != pushConstantSize)
    throw mismatch(fmt::format("push constants of {} bytes, host has {}", iface.pushConstantSize, pushConstantSize));
  for (const SpirvInterface::Binding& b : iface.bindings) {
    auto host = std::find_if(bindings.begin(), bindings.end(), [&](const BindingLayout& l) { return l.binding == b.binding; });
    if (b.set != 0 || host == bindings.end()) throw mismatch(fmt::format("unknown binding {}.{}", b.set, b.binding));
    if (b.kind != host->kind) throw mismatch(fmt::format("binding {} is another kind of descriptor", b.binding));
    if (b.staticSize != host->staticSize || b.runtimeStride != host->runtimeStride)
      throw mismatch(fmt::format("binding {} holds {} bytes + {}-byte elements, host has {} + {}", b.binding,
                                 b.staticSize, b.runtimeStride, host->staticSize, host->runtimeStride));
  }

  try {
    VkShaderModuleCreateInfo moduleInfo{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    moduleInfo.codeSize = code.size() * 4;
    moduleInfo.pCode = code.data();
    check(ctx.fn.vkCreateShaderModule(ctx.device, &moduleInfo, nullptr, &module_), "vkCreateShaderModule");

    std::vector<VkDescriptorSetLayoutBinding> layoutBindings;
    std::map<VkDescriptorType, uint32_t> typeCounts;
    for (const BindingLayout& b : bindings) {
      const VkDescriptorType type = b.kind == BindingKind::Uniform        ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER
                                    : b.kind == BindingKind::UniformTexel ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER
                                                                          : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      ++typeCounts[type];
      types_.emplace_back(b.binding, type);
      layoutBindings.push_back({b.binding, type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
    }
    VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    setInfo.bindingCount = uint32_t(layoutBindings.size());
    setInfo.pBindings = layoutBindings.data();
    check(ctx.fn.vkCreateDescriptorSetLayout(ctx.device, &setInfo, nullptr, &setLayout_), "vkCreateDescriptorSetLayout");

    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, pushConstantSize};
    VkPipelineLayoutCreateInfo layoutInfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    layoutInfo.setLayoutCount = 1;
    layoutInfo.pSetLayouts = &setLayout_;
    layoutInfo.pushConstantRangeCount = pushConstantSize > 0 ? 1 : 0;
    layoutInfo.pPushConstantRanges = &range;
    check(ctx.fn.vkCreatePipelineLayout(ctx.device, &layoutInfo, nullptr, &layout_), "vkCreatePipelineLayout");

    VkComputePipelineCreateInfo pipelineInfo{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    pipelineInfo.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    pipelineInfo.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    pipelineInfo.stage.module = module_;
    pipelineInfo.stage.pName = "main";
    std::vector<VkSpecializationMapEntry> entries;
    for (uint32_t i = 0; i < specialization.size(); ++i) entries.push_back({i, 4 * i, 4});
    VkSpecializationInfo specInfo{uint32_t(entries.size()), entries.data(), specialization.size_bytes(),
                                  specialization.data()};
    if (!specialization.empty()) pipelineInfo.stage.pSpecializationInfo = &specInfo;
    pipelineInfo.layout = layout_;
    check(ctx.fn.vkCreateComputePipelines(ctx.device, VK_NULL_HANDLE, 1, &pipelineInfo, nullptr, &pipeline_),
          "vkCreateComputePipelines");

    std::vector<VkDescriptorPoolSize> poolSizes;
    for (auto [type, count] : typeCounts) poolSizes.push_back({type, count});
    VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    poolInfo.maxSets = 1;
    poolInfo.poolSizeCount = uint32_t(poolSizes.size());
    poolInfo.pPoolSizes = poolSizes.data();
    check(ctx.fn.vkCreateDescriptorPool(ctx.device, &poolInfo, nullptr, &pool_), "vkCreateDescriptorPool");
    VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    alloc.descriptorPool = pool_;
    alloc.descriptorSetCount = 1;
    alloc.pSetLayouts = &setLayout_;
    check(ctx.fn.vkAllocateDescriptorSets(ctx.device, &alloc, &set_), "vkAllocateDescriptorSets");
  } catch (...) {
    destroy();
    throw;
  }
}

ComputePipeline::~ComputePipeline() { destroy(); }

void ComputePipeline::destroy() {
  if (pool_) ctx_.fn.vkDestroyDescriptorPool(ctx_.device, pool_, nullptr);
  if (pipeline_) ctx_.fn.vkDestroyPipeline(ctx_.device, pipeline_, nullptr);
  if (layout_) ctx_.fn.vkDestroyPipelineLayout(ctx_.device, layout_, nullptr);
  if (setLayout_) ctx_.fn.vkDestroyDescriptorSetLayout(ctx_.device, setLayout_, nullptr);
  if (module_) ctx_.fn.vkDestroyShaderModule(ctx_.device, module_, nullptr);
  pool_ = VK_NULL_HANDLE;
  pipeline_ = VK_NULL_HANDLE;
  layout_ = VK_NULL_HANDLE;
  setLayout_ = VK_NULL_HANDLE;
  module_ = VK_NULL_HANDLE;
}

void ComputePipeline::setBuffer(uint32_t binding, const Buffer& buffer) {
  VkDescriptorBufferInfo info{buffer.handle(), 0, VK_WHOLE_SIZE};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = descriptorType(binding);
  if (write.descriptorType == VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER)
    throw Error(fmt::format("internal: binding {} takes a texel buffer view", binding));
  write.pBufferInfo = &info;
  ctx_.fn.vkUpdateDescriptorSets(ctx_.device, 1, &write, 0, nullptr);
}

void ComputePipeline::setTexelBuffer(uint32_t binding, VkBufferView view) {
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = descriptorType(binding);
  if (write.descriptorType != VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER)
    throw Error(fmt::format("internal: binding {} takes a buffer", binding));
  write.pTexelBufferView = &view;
  ctx_.fn.vkUpdateDescriptorSets(ctx_.device, 1, &write, 0, nullptr);
}

VkDescriptorType ComputePipeline::descriptorType(uint32_t binding) const {
  auto type = std::find_if(types_.begin(), types_.end(), [&](const auto& t) { return t.first == binding; });
  if (type == types_.end()) throw Error(fmt::format("internal: binding {} not in the pipeline's layout", binding));
  return type->second;
}

void ComputePipeline::dispatch(VkCommandBuffer cmd, const void* pushConstants, uint32_t groupsX, uint32_t groupsY,
                               uint32_t groupsZ) const {
  ctx_.fn.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_);
  ctx_.fn.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_, 0, 1, &set_, 0, nullptr);
  if (pushSize_ > 0) ctx_.fn.vkCmdPushConstants(cmd, layout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, pushSize_, pushConstants);
  ctx_.fn.vkCmdDispatch(cmd, groupsX, groupsY, groupsZ);
}

}  // namespace ht::vk
