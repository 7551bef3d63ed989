#include <gtest/gtest.h>

#include <random>

#include "healpix.h"
#include "tree.h"

using namespace ht;

namespace {

std::vector<float> randomLeaves(int order, uint32_t seed) {
  std::mt19937 gen(seed);
  std::lognormal_distribution<float> dist(0.0f, 3.0f);  // HDR-like spread
  std::vector<float> v(MaxAvgTree::levelSize(order));
  for (float& x : v) x = gen() % 7 == 0 ? 0.0f : dist(gen);
  return v;
}

}  // namespace

TEST(Tree, LayoutMatchesHealpixLevels) {
  for (int l = 0; l <= healpix::kMaxOrder; ++l) {
    EXPECT_EQ(MaxAvgTree::levelSize(l), healpix::pixelCount(l));
    EXPECT_EQ(MaxAvgTree::levelOffset(l + 1), MaxAvgTree::levelOffset(l) + MaxAvgTree::levelSize(l));
  }
  EXPECT_EQ(MaxAvgTree::levelOffset(0), 0u);
}

TEST(Tree, MaxBoundsChildrenAndAverageIsMeanOfChildren) {
  const int order = 5;
  MaxAvgTree t = buildMaxAvgTree(order, randomLeaves(order, 7));
  for (int l = 0; l < order; ++l)
    for (uint64_t p = 0; p < MaxAvgTree::levelSize(l); ++p) {
      double mean = 0.0;
      for (uint64_t c = 4 * p; c < 4 * p + 4; ++c) {
        EXPECT_GE(t.max(l, p), t.max(l + 1, c));
        mean += 0.25 * t.avg(l + 1, c);
      }
      EXPECT_NEAR(t.avg(l, p), mean, 1e-6 * mean + 1e-30) << "level " << l << " node " << p;
      EXPECT_GE(t.max(l, p), t.avg(l, p));
    }
}

TEST(Tree, RootsMatchBruteForce) {
  const int order = 6;
  std::vector<float> leaves = randomLeaves(order, 11);
  MaxAvgTree t = buildMaxAvgTree(order, leaves);
  const uint64_t perFace = uint64_t(1) << (2 * order);
  double total = 0.0;
  for (int f = 0; f < 12; ++f) {
    double sum = 0.0;
    float mx = 0.0f;
    for (uint64_t i = f * perFace; i < (f + 1) * perFace; ++i) {
      sum += leaves[i];
      mx = std::max(mx, leaves[i]);
    }
    total += sum;
    EXPECT_EQ(t.max(0, f), mx);
    EXPECT_NEAR(t.avg(0, f), sum / perFace, 1e-5 * sum / perFace);
  }
  EXPECT_NEAR(t.total(), total, 1e-5 * total);
  // Leaves are stored unchanged.
  for (uint64_t i = 0; i < leaves.size(); ++i) ASSERT_EQ(t.avg(order, i), leaves[i]);
}
