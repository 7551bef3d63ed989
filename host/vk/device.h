// Vulkan instance and device through volk: the loader is opened explicitly
// (volkInitialize -> vkCreateInstance -> volkLoadInstanceOnly -> device ->
// volkLoadDeviceTable), devices are ranked discrete > integrated > virtual >
// CPU, and validation messages, when asked for, are counted.
//
// Each Context calls its device through its own function table (fn), so
// several may live at once, on different devices and drivers.
#pragma once

#include <volk.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vk/validation_log.h"

namespace ht::vk {

// Throws ht::Error("<what>: <VkResult name>") unless r is VK_SUCCESS.
void check(VkResult r, const char* what);
const char* resultName(VkResult r);

struct PhysicalDeviceInfo {
  uint32_t index = 0;         // in vkEnumeratePhysicalDevices order (--gpu-index)
  std::string name;
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  std::string typeName;       // discrete, integrated, virtual, cpu, other
  std::string driverName;     // VkPhysicalDeviceDriverProperties
  std::string driverInfo;
  uint32_t apiVersion = 0;
  std::string apiVersionString;
  bool usable = false;        // meets every requirement below
  std::string unusableReason;
  // Required: Vulkan 1.2, a compute queue, scalarBlockLayout, bufferDeviceAddress,
  // shaderInt64 (HT candidate indices and deep node indices).
  bool scalarBlockLayout = false;
  bool bufferDeviceAddress = false;
  bool shaderInt64 = false;
  // Optional: shaderFloat64 (HEALPix lookups in double), timestamps (GPU time).
  bool shaderFloat64 = false;
  uint32_t timestampValidBits = 0;
  float timestampPeriodNs = 0.0f;
  uint64_t maxStorageBufferRange = 0;
  uint32_t maxTexelBufferElements = 0;
  uint32_t maxPushConstantsSize = 0;
  uint32_t subgroupSize = 0;
  bool subgroupVote = false;  // subgroupAny in compute shaders (ht-cut)
  uint64_t deviceLocalBytes = 0;
};

struct ContextOptions {
  int deviceIndex = -1;     // -1: the best usable device
  bool validation = false;  // VK_LAYER_KHRONOS_validation + counting messenger
  bool useFloat64 = true;   // enable shaderFloat64 where the device has it
  std::shared_ptr<ValidationLog> validationLog;  // where messages are counted; null: a log of its own
  double submitTimeoutSeconds = 300.0;  // a submission still running after this is an error, not a hang
};

// Lists the physical devices without creating one (throws ht::Error when
// there is no loader or no driver).
std::vector<PhysicalDeviceInfo> listPhysicalDevices();
// Index of the device `best` ranking picks, or -1 if none is usable.
int bestDevice(const std::vector<PhysicalDeviceInfo>& devices);

class Context {
 public:
  explicit Context(const ContextOptions& options);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  uint32_t queueFamily = 0;
  VkCommandPool commandPool = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory{};
  VolkDeviceTable fn{};  // the device's functions: ctx.fn.vkCmdDispatch(...)
  PhysicalDeviceInfo info;
  bool float64 = false;  // shaderFloat64 enabled

  // Records `record` into a fresh command buffer, submits it and waits at
  // most submitTimeoutSeconds; device loss and the timeout throw ht::Error.
  void submitAndWait(const std::function<void(VkCommandBuffer)>& record);

  // Validation messages (severity warning or error) since creation.
  const ValidationLog& validationLog() const { return *log_; }

 private:
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
  std::shared_ptr<ValidationLog> log_;
  double submitTimeoutSeconds_ = 300.0;
  void destroy();
};

}  // namespace ht::vk
