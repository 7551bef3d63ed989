#include "bvh.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numeric>

#include <glm/common.hpp>

#include "shapes.h"

namespace ht {
namespace {

struct Box {
  glm::vec3 lo{INFINITY}, hi{-INFINITY};
  void add(const glm::vec3& a, const glm::vec3& b) {
    lo = glm::min(lo, a);
    hi = glm::max(hi, b);
  }
  float area() const {
    const glm::vec3 d = glm::max(hi - lo, glm::vec3(0.0f));
    return d.x * d.y + d.y * d.z + d.z * d.x;
  }
};

constexpr int kBins = 12;
// Past this depth splits are at the median: the depth, and so the
// traversal's stack, stays bounded whatever the spheres.
constexpr int kSahDepth = 40;
static_assert(kSahDepth + 32 < kBvhMaxDepth, "median splits add at most log2(spheres) levels");

struct Builder {
  const std::vector<Sphere>& spheres;
  std::vector<uint32_t> items;
  Bvh& bvh;

  glm::vec3 lo(uint32_t i) const { return spheres[i].center - glm::vec3(spheres[i].radius); }
  glm::vec3 hi(uint32_t i) const { return spheres[i].center + glm::vec3(spheres[i].radius); }

  uint32_t build(size_t begin, size_t end, int depth) {
    const uint32_t node = uint32_t(bvh.nodes.size());
    bvh.nodes.push_back({});
    Box box, centres;
    for (size_t k = begin; k < end; ++k) {
      box.add(lo(items[k]), hi(items[k]));
      centres.add(spheres[items[k]].center, spheres[items[k]].center);
    }
    // Padded so that rounding in the slab test never cuts off a sphere.
    const glm::vec3 pad = 1e-5f * (glm::max(glm::abs(box.lo), glm::abs(box.hi)) + (box.hi - box.lo)) + 1e-30f;
    bvh.nodes[node].lo = box.lo - pad;
    bvh.nodes[node].hi = box.hi + pad;
    const size_t count = end - begin;
    if (count <= kBvhLeafSize) {
      bvh.nodes[node].first = uint32_t(bvh.order.size());
      bvh.nodes[node].count = uint32_t(count);
      bvh.order.insert(bvh.order.end(), items.begin() + long(begin), items.begin() + long(end));
      return node;
    }
    const glm::vec3 extent = centres.hi - centres.lo;
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : extent.y >= extent.z ? 1 : 2;
    size_t mid = 0;
    bool partitioned = false;
    // Binned SAH where the centres' spread gives a finite bin scale (not for
    // centres too close together or too far apart for floats).
    const float scale = float(kBins) / extent[axis];
    if (extent[axis] > 0.0f && std::isfinite(extent[axis]) && std::isfinite(scale) && scale > 0.0f &&
        depth < kSahDepth) {
      // The plane between bins with the least n x area on both sides.
      auto binOf = [&](uint32_t i) {
        const float f = (spheres[i].center[axis] - centres.lo[axis]) * scale;
        return f > 0.0f ? std::min(kBins - 1, int(std::min(f, float(kBins)))) : 0;
      };
      std::array<Box, kBins> bins;
      std::array<size_t, kBins> counts{};
      for (size_t k = begin; k < end; ++k) {
        const int b = binOf(items[k]);
        bins[b].add(lo(items[k]), hi(items[k]));
        ++counts[b];
      }
      float best = INFINITY;
      int split = -1;
      for (int s = 1; s < kBins; ++s) {
        Box left, right;
        size_t nl = 0, nr = 0;
        for (int b = 0; b < s; ++b)
          if (counts[b]) left.add(bins[b].lo, bins[b].hi), nl += counts[b];
        for (int b = s; b < kBins; ++b)
          if (counts[b]) right.add(bins[b].lo, bins[b].hi), nr += counts[b];
        if (nl == 0 || nr == 0) continue;
        const float cost = float(nl) * left.area() + float(nr) * right.area();
        if (cost < best) best = cost, split = s;
      }
      if (split > 0) {
        // A stable partition keeps the build the same with any library.
        auto it = std::stable_partition(items.begin() + long(begin), items.begin() + long(end),
                                        [&](uint32_t i) { return binOf(i) < split; });
        mid = size_t(it - items.begin());
        partitioned = true;
      }
    }
    if (!partitioned) {  // all centres in one point, or deep: the median by centre, ties by index
      mid = begin + count / 2;
      std::sort(items.begin() + long(begin), items.begin() + long(end), [&](uint32_t a, uint32_t b) {
        const float ca = spheres[a].center[axis], cb = spheres[b].center[axis];
        return ca < cb || (ca == cb && a < b);
      });
    }
    build(begin, mid, depth + 1);  // the node right after this one
    const uint32_t right = build(mid, end, depth + 1);
    bvh.nodes[node].first = right;
    bvh.nodes[node].count = 0;
    return node;
  }
};

}  // namespace

Bvh buildBvh(const std::vector<Sphere>& spheres) {
  const auto start = std::chrono::steady_clock::now();
  Bvh bvh;
  bvh.spheres = uint32_t(spheres.size());
  if (!spheres.empty()) {
    Builder b{spheres, std::vector<uint32_t>(spheres.size()), bvh};
    std::iota(b.items.begin(), b.items.end(), 0u);
    bvh.nodes.reserve(2 * spheres.size());
    bvh.order.reserve(spheres.size());
    b.build(0, spheres.size(), 0);
  }
  bvh.buildSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return bvh;
}

namespace {
// std::fmin / std::fmax, inline: with one argument NaN, the other.
float minNum(float a, float b) { return b < a || a != a ? b : a; }
float maxNum(float a, float b) { return b > a || a != a ? b : a; }
}  // namespace

bool rayBox(const BvhNode& node, const glm::vec3& o, const glm::vec3& inv, float tMax, float& t0) {
  // minNum/maxNum never return the NaN of 0 x inf (a ray parallel to a
  // slab, starting on its plane): such a box is missed, and no sphere lies
  // there, every one being inside its box by the pad.
  float enter = 0.0f, exit = tMax;
  for (int a = 0; a < 3; ++a) {
    const float ta = (node.lo[a] - o[a]) * inv[a], tb = (node.hi[a] - o[a]) * inv[a];
    enter = maxNum(enter, minNum(ta, tb));
    exit = minNum(exit, maxNum(ta, tb));
  }
  t0 = enter;
  // The slack covers the slabs' rounding, which grows with the ray's
  // distance rather than with the box's coordinates: it only prunes less.
  return enter <= exit + 1e-5f * (std::fabs(enter) + std::fabs(exit));
}

}  // namespace ht
