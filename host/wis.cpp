#include "wis.h"

#include <algorithm>
#include <memory>

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "error.h"
#include "healpix.h"

namespace ht {

bool splitUnit(double& u, double p) {
  bool first = u < p;
  u = first ? u / p : (u - p) / (1.0 - p);
  u = std::clamp(u, 0.0, kBelowOneD);
  return first;
}

HealpixFrameBrdf::HealpixFrameBrdf(const Environment& env, const Material& m, const glm::vec3& normalWorld,
                                   const glm::vec3& woWorld)
    : material(m), frame(glm::normalize(glm::vec3(env.toHealpixFrame(normalWorld)))) {
  n = frame.n;
  wo = glm::normalize(glm::vec3(env.toHealpixFrame(woWorld)));
  woLocal = frame.toLocal(wo);
}

float HealpixFrameBrdf::scale() const {
  float s = luminance(material.diffuse);
  if (material.type != MaterialType::Lambert) s += luminance(material.specular);
  return s * kInvPi;
}

std::vector<glm::vec3> healpixNodeCenters(int order) {
  std::vector<glm::vec3> centers(MaxAvgTree::levelOffset(order + 1));
  for (int l = 0; l <= order; ++l) {
    glm::vec3* out = centers.data() + MaxAvgTree::levelOffset(l);
    tbb::parallel_for(uint64_t(0), MaxAvgTree::levelSize(l),
                      [&](uint64_t p) { out[p] = glm::vec3(healpix::pixToVec(l, p)); });
  }
  return centers;
}

int WisPoint::orderFor(const Environment& env, int order) { return std::clamp(order, 0, std::min(env.order, kMaxOrder)); }

WisPoint::WisPoint(const Environment& env, const Material& m, const glm::vec3& normalWorld,
                   const glm::vec3& woWorld, int order, const std::vector<glm::vec3>& centers)
    : env_(env),
      brdf_(env, m, normalWorld, woWorld),
      centers_(centers),
      order_(orderFor(env, order)),
      exactLevel_(std::min(kExactLevels, order_)),
      floor_(kBrdfFloor * brdf_.scale()) {
  if (centers_.size() < MaxAvgTree::levelOffset(order_ + 1))
    throw Error("internal: wis node centres of a lower order than the point's");
  top_.assign(MaxAvgTree::levelOffset(exactLevel_ + 1), 0.0);
  const uint64_t base = MaxAvgTree::levelOffset(exactLevel_);
  for (uint64_t p = 0; p < MaxAvgTree::levelSize(exactLevel_); ++p) top_[base + p] = leafWeight(exactLevel_, p);
  for (int l = exactLevel_ - 1; l >= 0; --l) {
    double* parent = top_.data() + MaxAvgTree::levelOffset(l);
    const double* child = top_.data() + MaxAvgTree::levelOffset(l + 1);
    for (uint64_t p = 0; p < MaxAvgTree::levelSize(l); ++p)
      parent[p] = child[4 * p] + child[4 * p + 1] + child[4 * p + 2] + child[4 * p + 3];
  }
  for (int f = 0; f < 12; ++f) total_ += top_[f];
  memo_.reserve(64);
}

double WisPoint::leafWeight(int level, uint64_t node) const {
  const float e = env_.tree.avg(level, node);
  if (!(e > 0.0f)) return 0.0;
  const glm::vec3& c = centers_[MaxAvgTree::levelOffset(level) + node];
  return double(e) * (double(brdf_.value(c)) + double(floor_));
}

std::array<double, 4> WisPoint::childWeights(int level, uint64_t node) const {
  if (level + 1 <= exactLevel_) {
    const double* w = top_.data() + MaxAvgTree::levelOffset(level + 1) + 4 * node;
    return {w[0], w[1], w[2], w[3]};
  }
  const uint64_t key = MaxAvgTree::levelOffset(level + 1) + 4 * node;
  auto it = memo_.find(key);
  if (it != memo_.end()) return it->second;
  std::array<double, 4> w;
  for (int c = 0; c < 4; ++c) w[c] = leafWeight(level + 1, 4 * node + c);
  memo_.emplace(key, w);
  return w;
}

WisSample WisPoint::warp(glm::dvec2 u) const {
  WisSample s{glm::vec3(0.0f, 1.0f, 0.0f), 0, 0.0, 0.0};
  if (empty()) return s;
  // Face: a 1D warp of x over the twelve face weights.
  const double target = u.x * total_;
  double acc = 0.0;
  int face = -1;
  for (int f = 0; f < 12; ++f) {
    if (!(top_[f] > 0.0)) continue;
    face = f;
    if (target < acc + top_[f]) break;
    acc += top_[f];
  }
  double x = std::clamp((target - acc) / top_[face], 0.0, 1.0 - 0x1p-53);
  double y = u.y;
  double prob = top_[face] / total_;
  uint64_t node = uint64_t(face);
  for (int level = 0; level < order_; ++level) {
    const std::array<double, 4> w = childWeights(level, node);
    const double sum = w[0] + w[1] + w[2] + w[3];
    const int col = splitUnit(x, (w[0] + w[2]) / sum) ? 0 : 1;
    const int row = splitUnit(y, w[col] / (w[col] + w[col + 2])) ? 0 : 1;
    const int child = col + 2 * row;
    prob *= w[child] / sum;
    node = 4 * node + uint64_t(child);
  }
  s.pixel = node;
  s.probability = prob;
  s.pdf = prob / healpix::pixelSolidAngle(order_);
  s.dir = env_.fromHealpixFrame(healpix::pixToVec(order_, node, x, y));
  return s;
}

double WisPoint::pixelProbability(uint64_t pixel) const {
  if (empty()) return 0.0;
  const int face = int(pixel >> (2 * order_));
  double prob = top_[face] / total_;
  for (int level = 0; level < order_ && prob > 0.0; ++level) {
    const uint64_t node = pixel >> (2 * (order_ - level));
    const int child = int((pixel >> (2 * (order_ - level - 1))) & 3u);
    const std::array<double, 4> w = childWeights(level, node);
    prob *= w[child] / (w[0] + w[1] + w[2] + w[3]);
  }
  return prob;
}

double WisPoint::pdf(const glm::vec3& worldDir) const {
  return pixelProbability(healpix::vecToPix(order_, env_.toHealpixFrame(worldDir))) /
         healpix::pixelSolidAngle(order_);
}

glm::vec3 WisPoint::approximateProduct(uint64_t pixel) const {
  const uint64_t count = uint64_t(1) << (2 * (env_.order - order_));
  glm::dvec3 sum(0.0);
  for (uint64_t p = pixel * count; p < (pixel + 1) * count; ++p) sum += glm::dvec3(env_.radiance[p]);
  const glm::vec3 average(sum / double(count));
  if (average == glm::vec3(0.0f)) return average;
  return average * brdf_.rgb(centers_[MaxAvgTree::levelOffset(order_) + pixel]);
}

glm::vec3 estimateWis(const Scene& scene, const ShadingPoint& sp, int spp, int order, bool biased,
                      const std::vector<glm::vec3>& centers, PixelSampler& sampler,
                      EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || spp <= 0) return glm::vec3(0.0f);
  const Material& mat = *sp.material;
  WisPoint wis(env, mat, sp.normal, sp.wo, order, centers);
  if (wis.empty()) return glm::vec3(0.0f);
  const Frame frame(sp.normal);
  const glm::vec3 woLocal = frame.toLocal(sp.wo);
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);
  const double pixelSolidAngle = healpix::pixelSolidAngle(wis.order());
  glm::dvec3 sum(0.0);
  for (int i = 0; i < spp; ++i) {
    sampler.startSample(uint32_t(i));
    const WisSample s = wis.warp(sampler.get2DPrecise());
    ++counters.directions;
    if (!(s.probability > 0.0)) continue;
    glm::dvec3 value;
    if (biased) {
      const glm::vec3 product = wis.approximateProduct(s.pixel);
      if (product == glm::vec3(0.0f)) continue;
      value = glm::dvec3(product) * (pixelSolidAngle / s.probability);
    } else {
      const glm::vec3 radiance = env.eval(s.dir);
      if (radiance == glm::vec3(0.0f)) continue;
      const glm::vec3 fcos = evalBsdf(mat, woLocal, frame.toLocal(s.dir));
      if (fcos == glm::vec3(0.0f)) continue;
      value = glm::dvec3(radiance * fcos) / s.pdf;
    }
    if (unoccluded(scene, origin, s.dir, counters)) sum += value;
  }
  return glm::vec3(sum / double(spp));
}

}  // namespace ht
