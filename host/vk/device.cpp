#include "vk/device.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <fmt/format.h>

#include "error.h"  // ht::Error

namespace ht::vk {
namespace {

constexpr uint32_t kApiVersion = VK_API_VERSION_1_2;
constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr size_t kKeptMessages = 16;

std::string versionString(uint32_t v) {
  return fmt::format("{}.{}.{}", VK_API_VERSION_MAJOR(v), VK_API_VERSION_MINOR(v), VK_API_VERSION_PATCH(v));
}

const char* typeName(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
  }
}

int typeRank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
    default: return 0;
  }
}

VKAPI_ATTR VkBool32 VKAPI_CALL onValidationMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                   VkDebugUtilsMessageTypeFlagsEXT,
                                                   const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* counters = static_cast<ValidationLog*>(user);
  const bool error = severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  const bool warning = severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT;
  if (!error && !warning) return VK_FALSE;
  (error ? counters->errors : counters->warnings)++;
  std::string text = fmt::format("vulkan validation {}: {}", error ? "error" : "warning",
                                 data && data->pMessage ? data->pMessage : "(no message)");
  if (counters->messages.size() < kKeptMessages) counters->messages.push_back(text);
  if (counters->print) std::fprintf(stderr, "%s\n", text.c_str());
  return VK_FALSE;
}

VkDebugUtilsMessengerCreateInfoEXT messengerInfo(ValidationLog* counters) {
  VkDebugUtilsMessengerCreateInfoEXT info{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  info.pfnUserCallback = onValidationMessage;
  info.pUserData = counters;
  return info;
}

// volkInitialize + vkCreateInstance with one-line errors for the two usual
// failures: no loader, and no driver (VK_ERROR_INCOMPATIBLE_DRIVER, also what
// a wrong VK_DRIVER_FILES gives).
VkInstance createInstance(bool validation, ValidationLog* counters) {
  // lavapipe hands each of its threads one run of a dispatch's workgroups,
  // so the slowest run sets the dispatch's time; with four times as many
  // threads as cores the system evens the runs out (docs/ht.md, "The
  // traversal on the GPU"). Read when the driver loads; a value set by the
  // user is kept, and other drivers ignore it.
  const unsigned threads = std::clamp(4 * std::thread::hardware_concurrency(), 4u, 32u);
  setenv("LP_NUM_THREADS", std::to_string(threads).c_str(), 0);
  if (volkInitialize() != VK_SUCCESS)
    throw Error("no Vulkan loader: libvulkan.so.1 not found (Debian: apt-get install libvulkan1 mesa-vulkan-drivers)");
  const uint32_t loaderVersion = volkGetInstanceVersion();
  if (loaderVersion < kApiVersion)
    throw Error(fmt::format("Vulkan loader {} is older than the 1.2 this renderer needs", versionString(loaderVersion)));

  std::vector<const char*> layers, extensions;
  if (validation) {
    uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> available(n);
    vkEnumerateInstanceLayerProperties(&n, available.data());
    bool found = std::any_of(available.begin(), available.end(),
                             [](const VkLayerProperties& l) { return std::strcmp(l.layerName, kValidationLayer) == 0; });
    if (!found)
      throw Error(fmt::format("Vulkan validation layer {} is not installed (Debian: vulkan-validationlayers)",
                              kValidationLayer));
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }

  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "htrender";
  app.applicationVersion = VK_MAKE_API_VERSION(0, 0, 1, 0);
  app.pEngineName = "htrender";
  app.apiVersion = kApiVersion;
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pApplicationInfo = &app;
  info.enabledLayerCount = uint32_t(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = uint32_t(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();
  VkDebugUtilsMessengerCreateInfoEXT debug = messengerInfo(counters);
  if (validation) info.pNext = &debug;  // also reports on instance creation and destruction

  VkInstance instance = VK_NULL_HANDLE;
  VkResult r = vkCreateInstance(&info, nullptr, &instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER)
    throw Error("no Vulkan driver found (vkCreateInstance: VK_ERROR_INCOMPATIBLE_DRIVER; check VK_DRIVER_FILES, "
                "or install mesa-vulkan-drivers or a GPU driver)");
  check(r, "vkCreateInstance");
  volkLoadInstanceOnly(instance);
  return instance;
}

std::vector<VkPhysicalDevice> physicalDevices(VkInstance instance) {
  uint32_t n = 0;
  check(vkEnumeratePhysicalDevices(instance, &n, nullptr), "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> devices(n);
  check(vkEnumeratePhysicalDevices(instance, &n, devices.data()), "vkEnumeratePhysicalDevices");
  devices.resize(n);
  return devices;
}

// Index of the first queue family with compute, or UINT32_MAX.
uint32_t computeFamily(VkPhysicalDevice pd, uint32_t* timestampBits) {
  uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, families.data());
  for (uint32_t i = 0; i < n; ++i)
    if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
      if (timestampBits) *timestampBits = families[i].timestampValidBits;
      return i;
    }
  return UINT32_MAX;
}

PhysicalDeviceInfo describe(VkPhysicalDevice pd, uint32_t index) {
  PhysicalDeviceInfo d;
  d.index = index;
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(pd, &props);
  d.name = props.deviceName;
  d.type = props.deviceType;
  d.typeName = typeName(props.deviceType);
  d.apiVersion = props.apiVersion;
  d.apiVersionString = versionString(props.apiVersion);
  d.maxStorageBufferRange = props.limits.maxStorageBufferRange;
  d.maxTexelBufferElements = props.limits.maxTexelBufferElements;
  d.maxPushConstantsSize = props.limits.maxPushConstantsSize;
  d.timestampPeriodNs = props.limits.timestampPeriod;

  VkPhysicalDeviceFeatures features;
  vkGetPhysicalDeviceFeatures(pd, &features);
  d.shaderFloat64 = features.shaderFloat64;
  d.shaderInt64 = features.shaderInt64;

  const bool v12 = props.apiVersion >= kApiVersion;
  if (v12) {
    VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
    VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
    subgroup.pNext = &driver;
    VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    props2.pNext = &subgroup;
    vkGetPhysicalDeviceProperties2(pd, &props2);
    d.driverName = driver.driverName;
    d.driverInfo = driver.driverInfo;
    d.subgroupSize = subgroup.subgroupSize;
    d.subgroupVote = (subgroup.supportedOperations & VK_SUBGROUP_FEATURE_VOTE_BIT) != 0 &&
                     (subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) != 0;

    VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceFeatures2 features2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    features2.pNext = &f12;
    vkGetPhysicalDeviceFeatures2(pd, &features2);
    d.scalarBlockLayout = f12.scalarBlockLayout;
    d.bufferDeviceAddress = f12.bufferDeviceAddress;
  }

  VkPhysicalDeviceMemoryProperties mem;
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  for (uint32_t i = 0; i < mem.memoryHeapCount; ++i)
    if (mem.memoryHeaps[i].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT) d.deviceLocalBytes += mem.memoryHeaps[i].size;

  const uint32_t family = computeFamily(pd, &d.timestampValidBits);
  if (!v12)
    d.unusableReason = fmt::format("Vulkan {} (1.2 needed)", d.apiVersionString);
  else if (family == UINT32_MAX)
    d.unusableReason = "no compute queue";
  else if (!d.scalarBlockLayout)
    d.unusableReason = "no scalarBlockLayout";
  else if (!d.bufferDeviceAddress)
    d.unusableReason = "no bufferDeviceAddress";
  else if (!d.shaderInt64)
    d.unusableReason = "no shaderInt64";
  d.usable = d.unusableReason.empty();
  return d;
}

}  // namespace

const char* resultName(VkResult r) {
  switch (r) {
#define HT_VK_RESULT(x) case x: return #x;
    HT_VK_RESULT(VK_SUCCESS)
    HT_VK_RESULT(VK_NOT_READY)
    HT_VK_RESULT(VK_TIMEOUT)
    HT_VK_RESULT(VK_INCOMPLETE)
    HT_VK_RESULT(VK_ERROR_OUT_OF_HOST_MEMORY)
    HT_VK_RESULT(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    HT_VK_RESULT(VK_ERROR_INITIALIZATION_FAILED)
    HT_VK_RESULT(VK_ERROR_DEVICE_LOST)
    HT_VK_RESULT(VK_ERROR_MEMORY_MAP_FAILED)
    HT_VK_RESULT(VK_ERROR_LAYER_NOT_PRESENT)
    HT_VK_RESULT(VK_ERROR_EXTENSION_NOT_PRESENT)
    HT_VK_RESULT(VK_ERROR_FEATURE_NOT_PRESENT)
    HT_VK_RESULT(VK_ERROR_INCOMPATIBLE_DRIVER)
    HT_VK_RESULT(VK_ERROR_TOO_MANY_OBJECTS)
    HT_VK_RESULT(VK_ERROR_FORMAT_NOT_SUPPORTED)
    HT_VK_RESULT(VK_ERROR_FRAGMENTED_POOL)
    HT_VK_RESULT(VK_ERROR_OUT_OF_POOL_MEMORY)
    HT_VK_RESULT(VK_ERROR_INVALID_EXTERNAL_HANDLE)
    HT_VK_RESULT(VK_ERROR_FRAGMENTATION)
    HT_VK_RESULT(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
    HT_VK_RESULT(VK_ERROR_UNKNOWN)
#undef HT_VK_RESULT
    default: return "VkResult";
  }
}

void check(VkResult r, const char* what) {
  if (r == VK_SUCCESS) return;
  if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY)
    throw Error(fmt::format("{}: out of GPU memory (VK_ERROR_OUT_OF_DEVICE_MEMORY)", what));
  throw Error(fmt::format("{}: {} ({})", what, resultName(r), int(r)));
}

std::vector<PhysicalDeviceInfo> listPhysicalDevices() {
  VkInstance instance = createInstance(false, nullptr);
  std::vector<PhysicalDeviceInfo> list;
  try {
    std::vector<VkPhysicalDevice> devices = physicalDevices(instance);
    for (uint32_t i = 0; i < devices.size(); ++i) list.push_back(describe(devices[i], i));
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
  vkDestroyInstance(instance, nullptr);
  return list;
}

int bestDevice(const std::vector<PhysicalDeviceInfo>& devices) {
  int best = -1;
  for (const PhysicalDeviceInfo& d : devices)
    if (d.usable && (best < 0 || typeRank(d.type) > typeRank(devices[best].type))) best = int(d.index);
  return best;
}

Context::Context(const ContextOptions& options)
    : log_(options.validationLog ? options.validationLog : std::make_shared<ValidationLog>()),
      submitTimeoutSeconds_(options.submitTimeoutSeconds) {
  try {
    instance = createInstance(options.validation, log_.get());
    if (options.validation) {
      VkDebugUtilsMessengerCreateInfoEXT info = messengerInfo(log_.get());
      check(vkCreateDebugUtilsMessengerEXT(instance, &info, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
    }
    std::vector<VkPhysicalDevice> devices = physicalDevices(instance);
    if (devices.empty()) throw Error("no Vulkan device found (the driver lists none)");
    std::vector<PhysicalDeviceInfo> infos;
    for (uint32_t i = 0; i < devices.size(); ++i) infos.push_back(describe(devices[i], i));
    int chosen = options.deviceIndex;
    if (chosen >= 0) {
      if (chosen >= int(infos.size()))
        throw Error(fmt::format("--gpu-index {}: there are {} Vulkan device(s) (see `htrender info`)", chosen,
                                infos.size()));
      if (!infos[chosen].usable)
        throw Error(fmt::format("--gpu-index {}: {} cannot run the renderer: {}", chosen, infos[chosen].name,
                                infos[chosen].unusableReason));
    } else {
      chosen = bestDevice(infos);
      if (chosen < 0)
        throw Error(fmt::format("no usable Vulkan device ({}: {})", infos[0].name, infos[0].unusableReason));
    }
    info = infos[chosen];
    physical = devices[chosen];
    queueFamily = computeFamily(physical, nullptr);
    vkGetPhysicalDeviceMemoryProperties(physical, &memory);
    float64 = options.useFloat64 && info.shaderFloat64;

    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queueInfo{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queueInfo.queueFamilyIndex = queueFamily;
    queueInfo.queueCount = 1;
    queueInfo.pQueuePriorities = &priority;
    VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    f12.scalarBlockLayout = VK_TRUE;
    f12.bufferDeviceAddress = VK_TRUE;
    VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    features.pNext = &f12;
    features.features.shaderFloat64 = float64 ? VK_TRUE : VK_FALSE;
    features.features.shaderInt64 = VK_TRUE;
    VkDeviceCreateInfo deviceInfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    deviceInfo.pNext = &features;
    deviceInfo.queueCreateInfoCount = 1;
    deviceInfo.pQueueCreateInfos = &queueInfo;
    check(vkCreateDevice(physical, &deviceInfo, nullptr, &device), "vkCreateDevice");
    volkLoadDeviceTable(&fn, device);
    fn.vkGetDeviceQueue(device, queueFamily, 0, &queue);

    VkCommandPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    poolInfo.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT | VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    poolInfo.queueFamilyIndex = queueFamily;
    check(fn.vkCreateCommandPool(device, &poolInfo, nullptr, &commandPool), "vkCreateCommandPool");
    VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(fn.vkCreateFence(device, &fenceInfo, nullptr, &fence_), "vkCreateFence");
  } catch (...) {
    destroy();
    throw;
  }
}

Context::~Context() { destroy(); }

void Context::destroy() {
  if (device) {
    fn.vkDeviceWaitIdle(device);
    if (fence_) fn.vkDestroyFence(device, fence_, nullptr);
    if (commandPool) fn.vkDestroyCommandPool(device, commandPool, nullptr);
    fn.vkDestroyDevice(device, nullptr);
  }
  if (messenger_) vkDestroyDebugUtilsMessengerEXT(instance, messenger_, nullptr);
  if (instance) vkDestroyInstance(instance, nullptr);
  fence_ = VK_NULL_HANDLE;
  commandPool = VK_NULL_HANDLE;
  device = VK_NULL_HANDLE;
  messenger_ = VK_NULL_HANDLE;
  instance = VK_NULL_HANDLE;
}

void Context::submitAndWait(const std::function<void(VkCommandBuffer)>& record) {
  VkCommandBufferAllocateInfo alloc{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  alloc.commandPool = commandPool;
  alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  alloc.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  check(fn.vkAllocateCommandBuffers(device, &alloc, &cmd), "vkAllocateCommandBuffers");
  struct Free {
    const VolkDeviceTable& fn;
    VkDevice device;
    VkCommandPool pool;
    VkCommandBuffer cmd;
    bool pending = false;  // still executing: left to the pool's destruction
    ~Free() {
      if (!pending) fn.vkFreeCommandBuffers(device, pool, 1, &cmd);
    }
  } freeLater{fn, device, commandPool, cmd};
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(fn.vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
  record(cmd);
  check(fn.vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cmd;
  check(fn.vkResetFences(device, 1, &fence_), "vkResetFences");
  check(fn.vkQueueSubmit(queue, 1, &submit, fence_), "vkQueueSubmit");
  const VkResult waited =
      fn.vkWaitForFences(device, 1, &fence_, VK_TRUE, uint64_t(std::max(submitTimeoutSeconds_, 0.0) * 1e9));
  freeLater.pending = waited != VK_SUCCESS;
  if (waited == VK_TIMEOUT)
    throw Error(fmt::format("the GPU did not finish within {:g} s (device hung or far too slow; "
                            "try --device cpu)",
                            submitTimeoutSeconds_));
  if (waited == VK_ERROR_DEVICE_LOST)
    throw Error("the Vulkan device was lost while rendering (VK_ERROR_DEVICE_LOST: driver reset or GPU fault)");
  check(waited, "vkWaitForFences");
}

}  // namespace ht::vk
