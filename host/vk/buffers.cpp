#include "vk/buffers.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include <fmt/format.h>

#include "error.h"  // ht::Error

namespace ht::vk {
namespace {

// First memory type allowed by `bits` that has all of `want`; UINT32_MAX if none.
uint32_t findMemoryType(const VkPhysicalDeviceMemoryProperties& mem, uint32_t bits, VkMemoryPropertyFlags want) {
  for (uint32_t i = 0; i < mem.memoryTypeCount; ++i)
    if ((bits & (1u << i)) && (mem.memoryTypes[i].propertyFlags & want) == want) return i;
  return UINT32_MAX;
}

uint32_t chooseMemoryType(const VkPhysicalDeviceMemoryProperties& mem, uint32_t bits, MemoryUse use) {
  constexpr VkMemoryPropertyFlags local = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  constexpr VkMemoryPropertyFlags visible = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
  constexpr VkMemoryPropertyFlags coherent = VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  constexpr VkMemoryPropertyFlags cached = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
  uint32_t t = UINT32_MAX;
  switch (use) {
    case MemoryUse::DeviceLocal:
      t = findMemoryType(mem, bits, local);
      break;
    case MemoryUse::Readback:
      t = findMemoryType(mem, bits, visible | cached);
      if (t == UINT32_MAX) t = findMemoryType(mem, bits, visible | coherent);
      break;
    case MemoryUse::Upload:
      t = findMemoryType(mem, bits, visible | coherent);
      break;
  }
  if (t == UINT32_MAX) t = findMemoryType(mem, bits, use == MemoryUse::DeviceLocal ? 0 : visible);
  if (t == UINT32_MAX) throw Error("no suitable Vulkan memory type for a buffer");
  return t;
}

}  // namespace

Buffer::Buffer(Context& ctx, VkDeviceSize size, MemoryUse use, VkBufferUsageFlags usage) : ctx_(&ctx), size_(size) {
  try {
    // Larger than every heap: refused here, as drivers differ in how they fail.
    VkDeviceSize largestHeap = 0;
    for (uint32_t h = 0; h < ctx.memory.memoryHeapCount; ++h)
      largestHeap = std::max(largestHeap, ctx.memory.memoryHeaps[h].size);
    if (size > largestHeap)
      throw Error(fmt::format("buffer of {:.1f} MiB: out of GPU memory (the largest memory heap holds {:.1f} MiB)",
                              double(size) / (1 << 20), double(largestHeap) / (1 << 20)));
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = size;
    info.usage = usage | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT |
                 VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
                 VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT |
                 VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    check(ctx.fn.vkCreateBuffer(ctx.device, &info, nullptr, &buffer_), "vkCreateBuffer");
    VkMemoryRequirements req;
    ctx.fn.vkGetBufferMemoryRequirements(ctx.device, buffer_, &req);
    const uint32_t type = chooseMemoryType(ctx.memory, req.memoryTypeBits, use);
    const VkMemoryPropertyFlags flags = ctx.memory.memoryTypes[type].propertyFlags;
    VkMemoryAllocateFlagsInfo flagsInfo{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
    flagsInfo.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.pNext = &flagsInfo;
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = type;
    check(ctx.fn.vkAllocateMemory(ctx.device, &alloc, nullptr, &memory_),
          fmt::format("vkAllocateMemory ({:.1f} MiB)", double(req.size) / (1 << 20)).c_str());
    check(ctx.fn.vkBindBufferMemory(ctx.device, buffer_, memory_, 0), "vkBindBufferMemory");
    if (flags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) {
      check(ctx.fn.vkMapMemory(ctx.device, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_), "vkMapMemory");
      coherent_ = flags & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    }
    VkBufferDeviceAddressInfo addressInfo{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    addressInfo.buffer = buffer_;
    address_ = ctx.fn.vkGetBufferDeviceAddress(ctx.device, &addressInfo);
  } catch (...) {
    release();
    throw;
  }
}

Buffer::~Buffer() { release(); }

Buffer::Buffer(Buffer&& o) noexcept { *this = std::move(o); }

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    release();
    ctx_ = std::exchange(o.ctx_, nullptr);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
    viewFormat_ = o.viewFormat_;
    size_ = std::exchange(o.size_, 0);
    address_ = std::exchange(o.address_, 0);
    mapped_ = std::exchange(o.mapped_, nullptr);
    coherent_ = o.coherent_;
  }
  return *this;
}

void Buffer::release() {
  if (!ctx_) return;
  if (mapped_) ctx_->fn.vkUnmapMemory(ctx_->device, memory_);
  if (view_) ctx_->fn.vkDestroyBufferView(ctx_->device, view_, nullptr);
  if (buffer_) ctx_->fn.vkDestroyBuffer(ctx_->device, buffer_, nullptr);
  if (memory_) ctx_->fn.vkFreeMemory(ctx_->device, memory_, nullptr);
  mapped_ = nullptr;
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  view_ = VK_NULL_HANDLE;
  ctx_ = nullptr;
}

VkBufferView Buffer::texelView(VkFormat format) {
  if (view_ && format == viewFormat_) return view_;
  if (view_ || !ctx_ || size_ < sizeof(float)) throw Error("internal: a texel view of an empty buffer or of two formats");
  viewFormat_ = format;
  VkBufferViewCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
  info.buffer = buffer_;
  info.format = format;
  info.offset = 0;
  info.range = std::min<VkDeviceSize>(size_ / sizeof(float), ctx_->info.maxTexelBufferElements) * sizeof(float);
  check(ctx_->fn.vkCreateBufferView(ctx_->device, &info, nullptr, &view_), "vkCreateBufferView");
  return view_;
}

void Buffer::upload(const void* data, size_t bytes) {
  if (bytes == 0) return;
  if (bytes > size_) throw Error("internal: upload larger than its buffer");
  if (mapped_) {
    std::memcpy(mapped_, data, bytes);
    if (!coherent_) {
      VkMappedMemoryRange range{VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
      range.memory = memory_;
      range.size = VK_WHOLE_SIZE;
      check(ctx_->fn.vkFlushMappedMemoryRanges(ctx_->device, 1, &range), "vkFlushMappedMemoryRanges");
    }
    return;
  }
  Buffer staging(*ctx_, bytes, MemoryUse::Upload);
  staging.upload(data, bytes);
  ctx_->submitAndWait([&](VkCommandBuffer cmd) {
    VkBufferCopy region{0, 0, bytes};
    ctx_->fn.vkCmdCopyBuffer(cmd, staging.handle(), buffer_, 1, &region);
  });
}

void Buffer::invalidate() {
  if (!mapped_ || coherent_) return;
  VkMappedMemoryRange range{VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
  range.memory = memory_;
  range.size = VK_WHOLE_SIZE;
  check(ctx_->fn.vkInvalidateMappedMemoryRanges(ctx_->device, 1, &range), "vkInvalidateMappedMemoryRanges");
}

}  // namespace ht::vk
