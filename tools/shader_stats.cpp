// shader_stats: a pipeline's statistics as the Vulkan driver's compiler
// reports them (VK_KHR_pipeline_executable_properties): registers, spills,
// instructions. Needs no GPU with Mesa's RADV on its null winsys (its
// --help has the command line).
#include <volk.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common.h"
#include "error.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace {

VkDescriptorType descriptorType(ht::vk::BindingKind kind) {
  switch (kind) {
    case ht::vk::BindingKind::Uniform: return VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    case ht::vk::BindingKind::UniformTexel: return VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
    default: return VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  }
}

nlohmann::json statValue(const VkPipelineExecutableStatisticKHR& s) {
  switch (s.format) {
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR: return bool(s.value.b32);
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR: return s.value.i64;
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR: return s.value.u64;
    case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_FLOAT64_KHR: return s.value.f64;
    default: return nullptr;
  }
}

int run(const std::string& spirvPath, uint32_t method, uint32_t capSlots, bool texels, bool brdfTable, bool fp64,
        int deviceIndex) {
  using ht::vk::check;
  if (volkInitialize() != VK_SUCCESS) throw ht::Error("no Vulkan loader");
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.apiVersion = VK_API_VERSION_1_2;
  VkInstanceCreateInfo instanceInfo{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  instanceInfo.pApplicationInfo = &app;
  VkInstance instance = VK_NULL_HANDLE;
  check(vkCreateInstance(&instanceInfo, nullptr, &instance), "vkCreateInstance");
  volkLoadInstance(instance);
  uint32_t count = 0;
  vkEnumeratePhysicalDevices(instance, &count, nullptr);
  std::vector<VkPhysicalDevice> devices(count);
  vkEnumeratePhysicalDevices(instance, &count, devices.data());
  if (deviceIndex < 0 || uint32_t(deviceIndex) >= count)
    throw ht::Error(fmt::format("--gpu-index {}: there are {} Vulkan device(s)", deviceIndex, count));
  VkPhysicalDevice physical = devices[size_t(deviceIndex)];
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(physical, &props);

  uint32_t extensionCount = 0;
  vkEnumerateDeviceExtensionProperties(physical, nullptr, &extensionCount, nullptr);
  std::vector<VkExtensionProperties> extensions(extensionCount);
  vkEnumerateDeviceExtensionProperties(physical, nullptr, &extensionCount, extensions.data());
  bool statistics = false;
  for (const VkExtensionProperties& e : extensions)
    statistics = statistics || std::string(e.extensionName) == VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME;
  if (!statistics)
    throw ht::Error(fmt::format("{} reports no pipeline statistics ({}); Mesa's RADV does, without a GPU: "
                                "VK_DRIVER_FILES=/usr/share/vulkan/icd.d/radeon_icd.x86_64.json RADV_FORCE_FAMILY=navi21",
                                props.deviceName, VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME));

  const float priority = 1.0f;
  VkDeviceQueueCreateInfo queueInfo{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  queueInfo.queueFamilyIndex = 0;
  queueInfo.queueCount = 1;
  queueInfo.pQueuePriorities = &priority;
  VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR fExec{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
  fExec.pipelineExecutableInfo = VK_TRUE;
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  f12.pNext = &fExec;
  f12.scalarBlockLayout = VK_TRUE;
  f12.bufferDeviceAddress = VK_TRUE;
  VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  features.pNext = &f12;
  features.features.shaderFloat64 = fp64 ? VK_TRUE : VK_FALSE;
  features.features.shaderInt64 = VK_TRUE;
  const char* extension = VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME;
  VkDeviceCreateInfo deviceInfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  deviceInfo.pNext = &features;
  deviceInfo.queueCreateInfoCount = 1;
  deviceInfo.pQueueCreateInfos = &queueInfo;
  deviceInfo.enabledExtensionCount = 1;
  deviceInfo.ppEnabledExtensionNames = &extension;
  VkDevice device = VK_NULL_HANDLE;
  check(vkCreateDevice(physical, &deviceInfo, nullptr, &device), "vkCreateDevice");
  volkLoadDevice(device);

  const std::vector<uint32_t> code = ht::vk::loadSpirv(spirvPath);
  const ht::vk::SpirvInterface iface = ht::vk::reflectSpirv(code);
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  for (const auto& b : iface.bindings)
    bindings.push_back({b.binding, descriptorType(b.kind), 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  setInfo.bindingCount = uint32_t(bindings.size());
  setInfo.pBindings = bindings.data();
  VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
  check(vkCreateDescriptorSetLayout(device, &setInfo, nullptr, &setLayout), "vkCreateDescriptorSetLayout");
  VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, uint32_t(iface.pushConstantSize)};
  VkPipelineLayoutCreateInfo layoutInfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  layoutInfo.setLayoutCount = 1;
  layoutInfo.pSetLayouts = &setLayout;
  layoutInfo.pushConstantRangeCount = push.size > 0 ? 1 : 0;
  layoutInfo.pPushConstantRanges = &push;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  check(vkCreatePipelineLayout(device, &layoutInfo, nullptr, &layout), "vkCreatePipelineLayout");
  VkShaderModuleCreateInfo moduleInfo{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  moduleInfo.codeSize = code.size() * sizeof(uint32_t);
  moduleInfo.pCode = code.data();
  VkShaderModule module = VK_NULL_HANDLE;
  check(vkCreateShaderModule(device, &moduleInfo, nullptr, &module), "vkCreateShaderModule");

  uint32_t specialization[4];
  specialization[HT_SPEC_METHOD] = method;
  specialization[HT_SPEC_TEXELS] = texels ? 1u : 0u;
  specialization[HT_SPEC_CAP_SLOTS] = capSlots;
  specialization[HT_SPEC_BRDF_TABLE] = brdfTable ? 1u : 0u;
  VkSpecializationMapEntry entries[4];
  for (uint32_t i = 0; i < 4; ++i) entries[i] = {i, 4 * i, 4};
  VkSpecializationInfo specInfo{4, entries, sizeof(specialization), specialization};
  VkComputePipelineCreateInfo pipelineInfo{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  pipelineInfo.flags = VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR;
  pipelineInfo.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  pipelineInfo.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  pipelineInfo.stage.module = module;
  pipelineInfo.stage.pName = "main";
  pipelineInfo.stage.pSpecializationInfo = &specInfo;
  pipelineInfo.layout = layout;
  VkPipeline pipeline = VK_NULL_HANDLE;
  check(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &pipelineInfo, nullptr, &pipeline),
        "vkCreateComputePipelines");

  VkPipelineInfoKHR info{VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR};
  info.pipeline = pipeline;
  uint32_t executables = 0;
  check(vkGetPipelineExecutablePropertiesKHR(device, &info, &executables, nullptr), "executable properties");
  std::vector<VkPipelineExecutablePropertiesKHR> execProps(executables,
                                                           {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR});
  check(vkGetPipelineExecutablePropertiesKHR(device, &info, &executables, execProps.data()), "executable properties");
  nlohmann::json out = {{"device", props.deviceName}, {"shader", spirvPath}, {"method", method},
                        {"executables", nlohmann::json::array()}};
  for (uint32_t e = 0; e < executables; ++e) {
    VkPipelineExecutableInfoKHR exec{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR};
    exec.pipeline = pipeline;
    exec.executableIndex = e;
    uint32_t n = 0;
    check(vkGetPipelineExecutableStatisticsKHR(device, &exec, &n, nullptr), "executable statistics");
    std::vector<VkPipelineExecutableStatisticKHR> stats(n, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR});
    check(vkGetPipelineExecutableStatisticsKHR(device, &exec, &n, stats.data()), "executable statistics");
    nlohmann::json j = {{"name", execProps[e].name}, {"subgroup", execProps[e].subgroupSize}};
    for (const auto& st : stats) j[st.name] = statValue(st);
    out["executables"].push_back(j);
  }
  std::printf("%s\n", out.dump().c_str());
  vkDestroyPipeline(device, pipeline, nullptr);
  vkDestroyShaderModule(device, module, nullptr);
  vkDestroyPipelineLayout(device, layout, nullptr);
  vkDestroyDescriptorSetLayout(device, setLayout, nullptr);
  vkDestroyDevice(device, nullptr);
  vkDestroyInstance(instance, nullptr);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "A compute pipeline's statistics from the Vulkan driver's compiler (registers, spills, instructions), as JSON.\n"
      "Without a GPU, Mesa's RADV compiles for an AMD part on its null winsys:\n"
      "  VK_DRIVER_FILES=/usr/share/vulkan/icd.d/radeon_icd.x86_64.json RADV_FORCE_FAMILY=navi21 \\\n"
      "  build/tools/shader_stats build/shaders/frontier.fp32.spv --method 14 --cap-slots 6"};
  std::string spirv;
  uint32_t method = HT_METHOD_HT_FRONTIER, capSlots = HT_MAX_CAPS;
  bool noTexels = false, brdfTable = false, fp64 = false;
  int deviceIndex = 0;
  app.add_option("spirv", spirv, "SPIR-V file (build/shaders/*.spv)")->required();
  app.add_option("--method", method, "HT_METHOD_* of shaders/common.h (specialization constant)");
  app.add_option("--cap-slots", capSlots, "visibility caps the pipeline holds (specialization constant)");
  app.add_flag("--no-texels", noTexels, "large arrays through storage buffers instead of texel buffers");
  app.add_flag("--brdf-table", brdfTable, "HT's tabulated BRDF bounds");
  app.add_flag("--fp64", fp64, "enable shaderFloat64 (the fp64 variant)");
  app.add_option("--gpu-index", deviceIndex, "Vulkan device");
  CLI11_PARSE(app, argc, argv);
  try {
    return run(spirv, method, capSlots, !noTexels, brdfTable, fp64, deviceIndex);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "shader_stats: %s\n", e.what());
    return 1;
  }
}
