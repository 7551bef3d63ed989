// Max/average trees over the HEALPix hierarchy.
//
// Level l (0 <= l <= order) holds 12 * 4^l nodes indexed by their nested
// HEALPix index at Nside = 2^l, so each base face's quadtree is a contiguous
// block of every level and the children of node p are 4p+0..3 one level
// down. Levels are stored back to back in one flat array (the layout the GPU
// receives as is): level l starts at levelOffset(l) = 12 (4^l - 1) / 3.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace ht {

struct MaxAvgTree {
  int order = 0;             // finest level
  uint64_t id = 0;           // distinct for every tree built in the process (copies keep it)
  std::vector<float> maxv;   // per node: maximum over its leaves
  std::vector<float> avgv;   // per node: mean over its leaves

  static constexpr uint64_t levelOffset(int level) { return 4ull * ((1ull << (2 * level)) - 1); }
  static constexpr uint64_t levelSize(int level) { return 12ull << (2 * level); }

  float max(int level, uint64_t node) const { return maxv[levelOffset(level) + node]; }
  float avg(int level, uint64_t node) const { return avgv[levelOffset(level) + node]; }
  // Sum over all leaves, accumulated in double.
  double total() const;
};

// Builds the tree bottom-up from the leaf values (12 * 4^order of them).
MaxAvgTree buildMaxAvgTree(int order, std::span<const float> leaves);

}  // namespace ht
