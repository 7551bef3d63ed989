#include "env_sampler.h"

#include <algorithm>
#include <vector>

#include "sampling.h"

namespace ht {
namespace {

// Picks index i of n weights with probability w[i] / sum (returned in prob,
// in float as environmentPixelProbability has it) and rescales u to [0,1)
// inside the pick. The last non-zero weight absorbs rounding.
template <int N>
int pickRescaled(const float* w, double& u, float& prob) {
  float sum = 0.0f;
  for (int i = 0; i < N; ++i) sum += w[i];
  const double target = u * double(sum);
  int last = 0;
  double before = 0.0, acc = 0.0;
  for (int i = 0; i < N; ++i) {
    if (w[i] <= 0.0f) continue;
    last = i;
    before = acc;
    acc += double(w[i]);
    if (target < acc) break;
  }
  prob = w[last] / sum;
  u = std::clamp((target - before) / double(w[last]), 0.0, kBelowOneD);
  return last;
}

}  // namespace

EnvSample sampleEnvironment(const Environment& env, glm::dvec2 u) { return sampleEnvironment(env, env.tree, u); }

namespace {

// Below node `node` of `level`, drawn with probability p: a child in four
// by the average tree at each level down to the leaves, then the point
// inside the leaf (u.x rescaled at each pick).
EnvSample descendFrom(const Environment& env, const MaxAvgTree& t, int level, uint64_t node, double p, glm::dvec2 u) {
  double x = u.x;
  for (int l = level + 1; l <= t.order; ++l) {
    float prob;
    const uint64_t first = 4 * node;
    node = first + uint64_t(pickRescaled<4>(&t.avgv[MaxAvgTree::levelOffset(l) + first], x, prob));
    p *= prob;
  }
  EnvSample s;
  s.pixel = node;
  s.dir = env.direction(env.order, node, std::min(float(x), kBelowOneF), std::min(float(u.y), kBelowOneF));
  s.pdf = float(p / env.pixelSolidAngle());
  return s;
}

}  // namespace

EnvSample sampleEnvironment(const Environment& env, const MaxAvgTree& t, glm::dvec2 u) {
  if (!(t.total() > 0.0)) return {glm::vec3(0.0f, 1.0f, 0.0f), 0, 0.0f};
  float prob;
  const uint64_t face = uint64_t(pickRescaled<12>(&t.avgv[0], u.x, prob));
  return descendFrom(env, t, 0, face, double(prob), u);
}

int pickRescaled4(const float* w, double& u, float& prob) { return pickRescaled<4>(w, u, prob); }

EnvSample sampleEnvironmentBelow(const Environment& env, const MaxAvgTree& t, int level, uint64_t node,
                                 glm::dvec2 u) {
  if (!(t.avg(level, node) > 0.0f)) return {glm::vec3(0.0f, 1.0f, 0.0f), 0, 0.0f};
  return descendFrom(env, t, level, node, 1.0, u);
}

double environmentPixelProbabilityBelow(const MaxAvgTree& t, int level, uint64_t pixel) {
  double p = 1.0;
  for (int l = t.order; l > level; --l) {
    const float* siblings = &t.avgv[MaxAvgTree::levelOffset(l) + (pixel & ~uint64_t(3))];
    float sum = siblings[0] + siblings[1] + siblings[2] + siblings[3];
    float w = siblings[pixel & 3];
    if (w <= 0.0f) return 0.0;
    p *= double(w / sum);
    pixel >>= 2;
  }
  return p;
}

double environmentPixelProbability(const Environment& env, uint64_t pixel) {
  return environmentPixelProbability(env.tree, pixel);
}

double environmentPixelProbability(const MaxAvgTree& t, uint64_t pixel) {
  const double p = environmentPixelProbabilityBelow(t, 0, pixel);
  if (p == 0.0) return 0.0;
  const uint64_t face = pixel >> (2 * t.order);
  float sum = 0.0f;
  for (int f = 0; f < 12; ++f) sum += t.avgv[f];
  if (!(t.avgv[face] > 0.0f)) return 0.0;
  return p * double(t.avgv[face] / sum);
}

float environmentPdf(const Environment& env, const glm::vec3& dir) { return environmentPdf(env, env.tree, dir); }

float environmentPdf(const Environment& env, const MaxAvgTree& tree, const glm::vec3& dir) {
  return float(environmentPixelProbability(tree, env.pixelOf(dir)) / env.pixelSolidAngle());
}

MaxAvgTree compensatedTree(const Environment& env) {
  const MaxAvgTree& t = env.tree;
  const uint64_t pixels = MaxAvgTree::levelSize(t.order);
  const float* leaves = &t.avgv[MaxAvgTree::levelOffset(t.order)];
  // The mean over the sphere: every HEALPix pixel has the same solid angle.
  const float mean = float(t.total() / double(pixels));
  std::vector<float> compensated(pixels);
  for (uint64_t i = 0; i < pixels; ++i) compensated[i] = std::max(0.0f, leaves[i] - mean);
  return buildMaxAvgTree(t.order, compensated);
}

}  // namespace ht
