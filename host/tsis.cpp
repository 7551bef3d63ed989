#include "tsis.h"

#include <algorithm>
#include <array>

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "healpix.h"
#include "sampling.h"

namespace ht {
namespace {

// First k in [lo, hi) with cum(k) > target for a non-decreasing cum; hi if none.
template <class Cum>
uint32_t firstAbove(uint32_t lo, uint32_t hi, const Cum& cum, double target) {
  while (lo < hi) {
    const uint32_t mid = lo + (hi - lo) / 2;
    if (cum(mid) > target)
      hi = mid;
    else
      lo = mid + 1;
  }
  return lo;
}

}  // namespace

TsisTable buildTsisTable(const Environment& env, int maxLevel) {
  TsisTable t;
  t.level = std::clamp(std::min(env.order, maxLevel), 0, TsisTable::kMaxLevel);
  t.nside = 1u << t.level;
  const uint32_t n = t.nside, stride = n + 1;
  t.sat.assign(size_t(12) * stride * stride, 0.0);
  tbb::parallel_for(0, 12, [&](int face) {
    double* s = t.sat.data() + size_t(face) * stride * stride;
    for (uint32_t y = 0; y < n; ++y) {
      double row = 0.0;
      for (uint32_t x = 0; x < n; ++x) {
        row += double(env.tree.avg(t.level, healpix::xyfToPix(t.level, x, y, face)));
        s[size_t(y + 1) * stride + x + 1] = s[size_t(y) * stride + x + 1] + row;
      }
    }
  });
  return t;
}

TsisPoint::TsisPoint(const Environment& env, std::shared_ptr<const TsisTable> table, const Material& m,
                     const glm::vec3& normalWorld, const glm::vec3& woWorld, int maxRegions)
    : env_(env), table_(std::move(table)) {
  const TsisTable& t = *table_;
  const HealpixFrameBrdf brdf(env, m, normalWorld, woWorld);
  const double floor = double(kBrdfFloor) * brdf.scale();
  const double fn = double(t.nside);

  // The BRDF's peaks (mirror direction, normal), so that no rectangle hides
  // a lobe between its evaluation points.
  struct Peak {
    int face;
    uint32_t ix, iy;
    double value;
  };
  std::array<Peak, 2> peaks;
  const std::array<glm::vec3, 2> peakDirs = {reflectAbout(brdf.wo, brdf.n), brdf.n};
  for (int i = 0; i < 2; ++i) {
    const uint64_t pix = healpix::vecToPix(t.level, glm::dvec3(peakDirs[i]));
    healpix::pixToXYF(t.level, pix, peaks[i].ix, peaks[i].iy, peaks[i].face);
    peaks[i].value = brdf.value(glm::normalize(peakDirs[i]));
  }

  struct Candidate {
    TsisRegion r;
    double priority;
  };
  auto evaluate = [&](int face, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1) {
    Candidate c;
    c.r = {face, x0, y0, x1, y1, t.rect(face, x0, y0, x1, y1), 0.0, 0.0};
    const double xs[3] = {x0 / fn, 0.5 * (x0 + x1) / fn, x1 / fn};
    const double ys[3] = {y0 / fn, 0.5 * (y0 + y1) / fn, y1 / fn};
    const int pts[5][2] = {{1, 1}, {0, 0}, {2, 0}, {0, 2}, {2, 2}};
    double lo = INFINITY, hi = 0.0, sum = 0.0;
    int count = 0;
    auto add = [&](double b) {
      lo = std::min(lo, b);
      hi = std::max(hi, b);
      sum += b;
      ++count;
    };
    for (const auto& p : pts) add(brdf.value(glm::vec3(healpix::faceXYToVec(face, xs[p[0]], ys[p[1]]))));
    for (const Peak& p : peaks)
      if (p.face == face && p.ix >= x0 && p.ix < x1 && p.iy >= y0 && p.iy < y1) add(p.value);
    c.r.brdf = sum / count + floor;
    const bool splittable = x1 - x0 > 1 || y1 - y0 > 1;
    c.priority = splittable ? c.r.energy * (hi - lo) : -1.0;
    return c;
  };

  std::vector<Candidate> work;
  work.reserve(size_t(std::max(maxRegions, 12)) + 1);
  for (int f = 0; f < 12; ++f) work.push_back(evaluate(f, 0, 0, t.nside, t.nside));
  while (int(work.size()) < maxRegions) {
    auto best = std::max_element(work.begin(), work.end(),
                                 [](const Candidate& a, const Candidate& b) { return a.priority < b.priority; });
    if (!(best->priority > 0.0)) break;
    const TsisRegion r = best->r;
    Candidate a, b;
    if (r.x1 - r.x0 >= r.y1 - r.y0) {
      const uint32_t mid = (r.x0 + r.x1) / 2;
      a = evaluate(r.face, r.x0, r.y0, mid, r.y1);
      b = evaluate(r.face, mid, r.y0, r.x1, r.y1);
    } else {
      const uint32_t mid = (r.y0 + r.y1) / 2;
      a = evaluate(r.face, r.x0, r.y0, r.x1, mid);
      b = evaluate(r.face, r.x0, mid, r.x1, r.y1);
    }
    *best = a;
    work.push_back(b);
  }

  regions_.reserve(work.size());
  cdf_.reserve(work.size());
  for (const Candidate& c : work) {
    regions_.push_back(c.r);
    total_ += c.r.energy > 0.0 ? c.r.energy * c.r.brdf : 0.0;
    cdf_.push_back(total_);
  }
  for (TsisRegion& r : regions_) r.probability = empty() ? 0.0 : (r.energy > 0.0 ? r.energy * r.brdf : 0.0) / total_;
}

int TsisPoint::regionOf(uint64_t satPixel) const {
  uint32_t ix, iy;
  int face;
  healpix::pixToXYF(table_->level, satPixel, ix, iy, face);
  for (size_t i = 0; i < regions_.size(); ++i) {
    const TsisRegion& r = regions_[i];
    if (r.face == face && ix >= r.x0 && ix < r.x1 && iy >= r.y0 && iy < r.y1) return int(i);
  }
  return -1;
}

TsisSample TsisPoint::warp(glm::dvec2 u) const {
  TsisSample s{glm::vec3(0.0f, 1.0f, 0.0f), 0, -1, 0.0};
  if (empty()) return s;
  const TsisTable& t = *table_;

  // Stage 1: a region by weight.
  const double target = u.x * total_;
  size_t ri = size_t(std::upper_bound(cdf_.begin(), cdf_.end(), target) - cdf_.begin());
  if (ri >= regions_.size()) ri = regions_.size() - 1;
  while (!(regions_[ri].probability > 0.0)) --ri;  // rounding onto an empty region's edge
  const TsisRegion& r = regions_[ri];
  const double before = ri == 0 ? 0.0 : cdf_[ri - 1];
  double x = std::clamp((target - before) / (cdf_[ri] - before), 0.0, kBelowOneD);
  double y = u.y;

  // Stage 2: a column by the SAT's column sums, then a row inside it.
  const double colTarget = x * r.energy;
  auto colCum = [&](uint32_t k) { return t.rect(r.face, r.x0, r.y0, k, r.y1); };
  uint32_t col = firstAbove(r.x0 + 1, r.x1, colCum, colTarget) - 1;
  while (col > r.x0 && !(colCum(col + 1) - colCum(col) > 0.0)) --col;
  const double c0 = colCum(col), c1 = colCum(col + 1);
  x = c1 > c0 ? std::clamp((colTarget - c0) / (c1 - c0), 0.0, kBelowOneD) : 0.5;

  auto rowCum = [&](uint32_t j) { return t.rect(r.face, col, r.y0, col + 1, j); };
  const double rowTarget = y * rowCum(r.y1);
  uint32_t row = firstAbove(r.y0 + 1, r.y1, rowCum, rowTarget) - 1;
  while (row > r.y0 && !(rowCum(row + 1) - rowCum(row) > 0.0)) --row;
  const double g0 = rowCum(row), g1 = rowCum(row + 1);
  y = g1 > g0 ? std::clamp((rowTarget - g0) / (g1 - g0), 0.0, kBelowOneD) : 0.5;

  uint64_t node = healpix::xyfToPix(t.level, col, row, r.face);
  const float value = env_.tree.avg(t.level, node);
  if (!(value > 0.0f)) return s;
  double prob = r.probability * double(value) / r.energy;
  // Below the SAT's pixels (maps finer than TsisTable::kMaxLevel): warp on
  // down the environment's average tree.
  for (int level = t.level; level < env_.order; ++level) {
    const float* w = &env_.tree.avgv[MaxAvgTree::levelOffset(level + 1) + 4 * node];
    const double sum = double(w[0]) + w[1] + w[2] + w[3];
    const int c = splitUnit(x, (double(w[0]) + w[2]) / sum) ? 0 : 1;
    const int rr = splitUnit(y, double(w[c]) / (double(w[c]) + w[c + 2])) ? 0 : 1;
    prob *= double(w[c + 2 * rr]) / sum;
    node = 4 * node + uint64_t(c + 2 * rr);
  }
  s.pixel = node;
  s.region = int(ri);
  s.pdf = prob / env_.pixelSolidAngle();
  s.dir = env_.direction(env_.order, node, float(x), float(y));
  return s;
}

double TsisPoint::pdf(const glm::vec3& worldDir) const {
  if (empty()) return 0.0;
  const TsisTable& t = *table_;
  const uint64_t leaf = env_.pixelOf(worldDir);
  const uint64_t satPixel = leaf >> (2 * (env_.order - t.level));
  const int ri = regionOf(satPixel);
  if (ri < 0) return 0.0;
  const TsisRegion& r = regions_[size_t(ri)];
  if (!(r.probability > 0.0)) return 0.0;
  double prob = r.probability * double(env_.tree.avg(t.level, satPixel)) / r.energy;
  for (int level = t.level; level < env_.order && prob > 0.0; ++level) {
    const uint64_t node = leaf >> (2 * (env_.order - level));
    const int child = int((leaf >> (2 * (env_.order - level - 1))) & 3u);
    const float* w = &env_.tree.avgv[MaxAvgTree::levelOffset(level + 1) + 4 * node];
    prob *= double(w[child]) / (double(w[0]) + w[1] + w[2] + w[3]);
  }
  return prob / env_.pixelSolidAngle();
}

glm::vec3 estimateTsis(const Scene& scene, const ShadingPoint& sp, int spp, const std::shared_ptr<const TsisTable>& table,
                       PixelSampler& sampler, EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || spp <= 0) return glm::vec3(0.0f);
  const Material& mat = *sp.material;
  TsisPoint tsis(env, table, mat, sp.normal, sp.wo);
  if (tsis.empty()) return glm::vec3(0.0f);
  const Frame frame(sp.normal);
  const glm::vec3 woLocal = frame.toLocal(sp.wo);
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < spp; ++i) {
    sampler.startSample(uint32_t(i));
    const TsisSample s = tsis.warp(sampler.get2DPrecise());
    ++counters.directions;
    if (!(s.pdf > 0.0)) continue;
    const glm::vec3 radiance = env.radiance[s.pixel];
    if (radiance == glm::vec3(0.0f)) continue;
    const glm::vec3 fcos = evalBsdf(mat, woLocal, frame.toLocal(s.dir));
    if (fcos == glm::vec3(0.0f)) continue;
    if (unoccluded(scene, origin, s.dir, counters)) sum += glm::dvec3(radiance * fcos) / s.pdf;
  }
  return glm::vec3(sum / double(spp));
}

}  // namespace ht
