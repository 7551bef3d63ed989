// A bounding volume hierarchy over the scene's spheres: a binned-SAH build
// on the host, nodes flattened depth first (a node's left child follows it).
// It only prunes: the closest hit it finds is the linear scan's, sphere for
// sphere, ties going to the lower sphere index (host/scene.cpp).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

namespace ht {

struct Sphere;  // shapes.h

struct BvhNode {
  glm::vec3 lo, hi;      // the box of the spheres below, padded for rounding
  uint32_t first = 0;    // leaf: first entry in Bvh::order; inner: the right child's node
  uint32_t count = 0;    // leaf: spheres (> 0); inner: 0
};

struct Bvh {
  std::vector<BvhNode> nodes;    // empty: no spheres
  std::vector<uint32_t> order;   // sphere indices, leaf by leaf
  uint32_t spheres = 0;          // how many it was built over
  double buildSeconds = 0.0;
};

// At most this many spheres per leaf; at most this many levels (the
// traversal's stack).
constexpr uint32_t kBvhLeafSize = 4;
constexpr int kBvhMaxDepth = 80;

Bvh buildBvh(const std::vector<Sphere>& spheres);

// The ray's parameter range [t0, t1] inside the box, or false; for a ray
// origin `o` and the reciprocal of its direction `inv` (infinite where a
// component is 0).
bool rayBox(const BvhNode& node, const glm::vec3& o, const glm::vec3& inv, float tMax, float& t0);

}  // namespace ht
