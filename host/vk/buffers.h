// Storage buffers with device addresses: device-local for what the shaders
// read, host-visible for what the host reads back.
#pragma once

#include <volk.h>

#include <cstddef>
#include <cstdint>

#include "vk/device.h"

namespace ht::vk {

enum class MemoryUse {
  DeviceLocal,  // uploaded once (directly when the memory is also host-visible, else via staging)
  Readback,     // written by shaders, read by the host (host-visible, cached where possible)
  Upload,       // staging: written by the host
};

class Buffer {
 public:
  Buffer() = default;
  Buffer(Context& ctx, VkDeviceSize size, MemoryUse use, VkBufferUsageFlags usage = 0);
  ~Buffer();
  Buffer(Buffer&& other) noexcept;
  Buffer& operator=(Buffer&& other) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  VkDeviceAddress address() const { return address_; }
  void* mapped() const { return mapped_; }
  // The buffer's first 32-bit words (as many as a texel buffer view may
  // hold) as a uniform texel buffer of `format` (R32_SFLOAT or R32_UINT),
  // made at the first call.
  VkBufferView texelView(VkFormat format);

  // Copies `bytes` from `data` into the start of the buffer (DeviceLocal or Upload).
  void upload(const void* data, size_t bytes);
  // Makes shader writes visible to the host before reading mapped() (Readback).
  void invalidate();

 private:
  Context* ctx_ = nullptr;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkBufferView view_ = VK_NULL_HANDLE;
  VkFormat viewFormat_ = VK_FORMAT_UNDEFINED;
  VkDeviceSize size_ = 0;
  VkDeviceAddress address_ = 0;
  void* mapped_ = nullptr;
  bool coherent_ = true;
  void release();
};

}  // namespace ht::vk
