#include "tree.h"

#include <algorithm>
#include <atomic>
#include <cassert>

namespace ht {

MaxAvgTree buildMaxAvgTree(int order, std::span<const float> leaves) {
  assert(leaves.size() == MaxAvgTree::levelSize(order));
  static std::atomic<uint64_t> nextId{1};
  MaxAvgTree t;
  t.order = order;
  t.id = nextId.fetch_add(1, std::memory_order_relaxed);
  uint64_t nodes = MaxAvgTree::levelOffset(order + 1);
  t.maxv.resize(nodes);
  t.avgv.resize(nodes);
  std::copy(leaves.begin(), leaves.end(), t.maxv.begin() + MaxAvgTree::levelOffset(order));
  std::copy(leaves.begin(), leaves.end(), t.avgv.begin() + MaxAvgTree::levelOffset(order));
  for (int level = order - 1; level >= 0; --level) {
    float* maxParent = t.maxv.data() + MaxAvgTree::levelOffset(level);
    float* avgParent = t.avgv.data() + MaxAvgTree::levelOffset(level);
    const float* maxChild = t.maxv.data() + MaxAvgTree::levelOffset(level + 1);
    const float* avgChild = t.avgv.data() + MaxAvgTree::levelOffset(level + 1);
    for (uint64_t p = 0; p < MaxAvgTree::levelSize(level); ++p) {
      const uint64_t c = 4 * p;
      maxParent[p] = std::max({maxChild[c], maxChild[c + 1], maxChild[c + 2], maxChild[c + 3]});
      avgParent[p] = float(0.25 * (double(avgChild[c]) + avgChild[c + 1] + avgChild[c + 2] + avgChild[c + 3]));
    }
  }
  return t;
}

double MaxAvgTree::total() const {
  double sum = 0.0;
  for (uint64_t f = 0; f < 12; ++f) sum += avgv[f];
  return sum * double(1ull << (2 * order));
}

}  // namespace ht
