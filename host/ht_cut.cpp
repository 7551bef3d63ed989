#include "ht_cut.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>

#include <glm/geometric.hpp>

#include "env_sampler.h"
#include "healpix.h"
#include "ht.h"
#include "rng.h"

namespace ht {

float cutDiscSin(int level) { return float(std::sin(1.0 / (std::sqrt(3.0) * std::ldexp(1.0, level)))); }

namespace {

// Calls store(level, i, sum) for each node i of `level` and of every level
// above it: `below` holds the sums of `level`'s nodes, and a node's sum is
// its four children's.
template <class T, class Store>
void sumUpward(std::vector<T> below, int level, Store&& store) {
  for (;; --level) {
    for (uint64_t i = 0; i < below.size(); ++i) store(level, i, below[i]);
    if (level == 0) return;
    std::vector<T> above(below.size() / 4);
    for (uint64_t i = 0; i < above.size(); ++i)
      above[i] = ((below[4 * i] + below[4 * i + 1]) + below[4 * i + 2]) + below[4 * i + 3];
    below = std::move(above);
  }
}

// The tree's first moments down to `levels`, summed in double from the
// leaves.
std::vector<glm::vec3> firstMoments(const Environment& env, const HtGeometry& g, int levels) {
  const int order = env.order;
  std::vector<glm::dvec3> leafMoments(size_t(MaxAvgTree::levelSize(order)));
  const uint64_t leaves = MaxAvgTree::levelOffset(order);
  const double omega = healpix::pixelSolidAngle(order);
  for (uint64_t i = 0; i < leafMoments.size(); ++i)
    leafMoments[i] = double(env.tree.avgv[leaves + i]) * omega * glm::dvec3(g.centers[leaves + i]);
  std::vector<glm::vec3> moment(size_t(MaxAvgTree::levelOffset(levels + 1)));
  sumUpward(std::move(leafMoments), order, [&](int level, uint64_t i, const glm::dvec3& m) {
    if (level <= levels) moment[MaxAvgTree::levelOffset(level) + i] = glm::vec3(m);
  });
  return moment;
}

// The tree's chroma down to `levels` (at most the map's order): each node's
// radiance over its luminance, both summed in double over its leaves (0
// where it has no light).
std::vector<glm::vec3> nodeChroma(const Environment& env, int levels) {
  const uint64_t leaves = uint64_t(1) << (2 * (env.order - levels));
  std::vector<glm::dvec4> sums(size_t(MaxAvgTree::levelSize(levels)), glm::dvec4(0.0));
  for (uint64_t i = 0; i < sums.size(); ++i)
    for (uint64_t l = i * leaves; l < (i + 1) * leaves; ++l)
      sums[i] += glm::dvec4(glm::dvec3(env.radiance[l]), double(luminance(env.radiance[l])));
  std::vector<glm::vec3> chroma(size_t(MaxAvgTree::levelOffset(levels + 1)));
  sumUpward(std::move(sums), levels, [&](int level, uint64_t i, const glm::dvec4& s) {
    chroma[MaxAvgTree::levelOffset(level) + i] = s.w > 0.0 ? glm::vec3(glm::dvec3(s) / s.w) : glm::vec3(0.0f);
  });
  return chroma;
}

}  // namespace

EnvCut buildEnvCut(const Environment& env, const HtGeometry& g, int nodes) {
  const MaxAvgTree& tree = env.tree;
  const int order = env.order;
  EnvCut cut;
  cut.momentLevel = std::min(kCutMomentLevel, order);
  cut.moment = firstMoments(env, g, cut.momentLevel);
  cut.chroma = nodeChroma(env, cut.momentLevel);
  for (int level = 0; level <= order; ++level) {
    const double omega = healpix::pixelSolidAngle(level);
    cut.discSin[size_t(level)] = cutDiscSin(level);
    cut.discChord[size_t(level)] = float(std::sqrt(omega / 3.14159265358979323846));
    cut.omega[size_t(level)] = float(omega);
  }

  // The largest power first; ties by level, then index, so that the cut is
  // the same on every platform.
  struct Item {
    double power;
    int level;
    uint64_t node;
    bool operator<(const Item& o) const {
      if (power != o.power) return power < o.power;
      if (level != o.level) return level > o.level;
      return node > o.node;
    }
  };
  auto item = [&](int level, uint64_t node) {
    return Item{double(tree.avg(level, node)) * healpix::pixelSolidAngle(level), level, node};
  };
  const int maxLevel = std::min(kCutMaxLevel, order);
  const size_t target = size_t(std::clamp(nodes, 12, HT_CUT_MAX_NODES));
  std::priority_queue<Item> open;
  std::vector<Item> done;
  for (uint64_t f = 0; f < 12; ++f) open.push(item(0, f));
  while (!open.empty() && open.size() + done.size() + 3 <= target) {
    const Item top = open.top();
    open.pop();
    if (top.level >= maxLevel || !(top.power > 0.0)) {
      done.push_back(top);
      continue;
    }
    for (uint64_t c = 0; c < 4; ++c) open.push(item(top.level + 1, 4 * top.node + c));
  }
  for (; !open.empty(); open.pop()) done.push_back(open.top());
  auto firstBelow = [&](const Item& i) { return i.node << (2 * (maxLevel - i.level)); };
  std::sort(done.begin(), done.end(), [&](const Item& a, const Item& b) { return firstBelow(a) < firstBelow(b); });

  cut.lookupLevel = maxLevel;
  cut.lookup.assign(MaxAvgTree::levelSize(maxLevel), 0);
  for (const Item& i : done) {
    glm::dvec3 radiance(0.0);
    double lum = 0.0;
    const uint64_t leaves = uint64_t(1) << (2 * (order - i.level)), first = i.node * leaves;
    for (uint64_t l = first; l < first + leaves; ++l) {
      radiance += glm::dvec3(env.radiance[l]);
      lum += double(luminance(env.radiance[l]));
    }
    const uint32_t k = uint32_t(cut.nodes.size());
    cut.nodes.push_back({i.level, i.node, lum > 0.0 ? glm::vec3(radiance / lum) : glm::vec3(0.0f)});
    std::fill_n(cut.lookup.begin() + int64_t(firstBelow(i)), uint64_t(1) << (2 * (maxLevel - i.level)), k);
  }
  const size_t K = cut.nodes.size();
  cut.lights.assign(5 * K, CutLight{glm::vec3(0.0f), 0.0f, glm::vec3(0.0f), 0});
  for (size_t k = 0; k < K; ++k) {
    const CutNode& n = cut.nodes[k];
    cut.lights[k] = cut.light(tree, g, n.level, MaxAvgTree::levelOffset(n.level) + n.node);
    if (n.level < cut.momentLevel)
      for (uint64_t j = 0; j < 4; ++j)
        cut.lights[K + 4 * k + j] = cut.light(tree, g, n.level + 1, MaxAvgTree::levelOffset(n.level + 1) + 4 * n.node + j);
  }
  cut.columns.fill(cut.lights.data(), K, cut.entry);
  return cut;
}

void CutColumns::fill(const CutLight* lights, size_t count, std::vector<uint32_t>& entry) {
  levelBegin.assign(size_t(kCutMomentLevel) + 2, 0);
  for (size_t k = 0; k < count; ++k) ++levelBegin[size_t(lights[k].level) + 1];
  for (size_t l = 1; l < levelBegin.size(); ++l) levelBegin[l] += levelBegin[l - 1];
  entry.resize(count);
  for (auto* column : {&x, &y, &z, &power, &mx, &my, &mz}) column->resize(count);
  for (size_t k = 0; k < count; ++k) {
    const CutLight& n = lights[k];
    const size_t i = levelBegin[size_t(n.level)]++;
    entry[k] = uint32_t(i);
    x[i] = n.centre.x;
    y[i] = n.centre.y;
    z[i] = n.centre.z;
    power[i] = n.power;
    mx[i] = n.moment.x;
    my[i] = n.moment.y;
    mz[i] = n.moment.z;
  }
  // Each level's begin, from its end.
  for (size_t l = levelBegin.size() - 1; l > 0; --l) levelBegin[l] = levelBegin[l - 1];
  levelBegin[0] = 0;
}

CutPoint::CutPoint(const Scene& scene, const ShadingPoint& sp, const Shading& sh, const CutOptions& options,
                   const EnvCut& cut, const HtGeometry& g)
    : cut(cut), g(g), tree(scene.environment.tree), minPartial(options.minPartialVisibility) {
  const Environment& env = scene.environment;
  s = glm::vec3(env.toHealpixFrame(sh.frame.s));
  t = glm::vec3(env.toHealpixFrame(sh.frame.t));
  normal = glm::vec3(env.toHealpixFrame(sh.frame.n));
  woLocal = sh.woLocal;
  const Material& m = *sp.material;
  const bool hasLobe = m.type != MaterialType::Lambert && luminance(m.specular) > 0.0f;
  apart = hasLobe && luminance(m.diffuse) > 0.0f;
  lobeOnly = hasLobe && !apart;
  // A lobe alone: every node's weight reads it at the node's light's
  // centroid, the cut's and those below it.
  diffuse = luminance(m.diffuse) * kInvPi;
  lobe = m;
  lobe.diffuse = glm::vec3(0.0f);
  if (!options.visibility) return;
  const float cm = std::cos(kCapMargin), sm = std::sin(kCapMargin);
  thread_local std::vector<LightCap> kept;
  kept.clear();
  // The first kCutMaxCaps occluders (more only with more planes than that):
  // a cap left out only leaves density where shadow rays return 0.
  const std::vector<Occluder> blockers = occluders(scene, sp, kCutMaxCaps);
  for (size_t i = 0; i < std::min(blockers.size(), kCutMaxCaps); ++i) {
    const Occluder& o = blockers[i];
    // The plane the point lies on: its cap is the point's horizon, which
    // the weights already hold.
    if (glm::dot(o.axis, normal) < -0.9999f) continue;
    LightCap c;
    if (!frontierCap(o.axis, o.sinHalfAngle, g, c)) continue;
    kept.push_back(c);
    // frontierCap's cos of the half-angle less the margin.
    const float s0 = o.sinHalfAngle, c0 = std::sqrt(1.0f - s0 * s0);
    const float cosA = c0 * cm + s0 * sm;
    caps.chord[kept.size() - 1] = std::sqrt(std::max(2.0f - 2.0f * cosA, 0.0f));
  }
  const size_t levels = size_t(g.order) + 1;
  caps.count = int(kept.size());
  const float never = std::numeric_limits<float>::infinity();
  caps.inside.assign(levels * kCutMaxCaps, never);
  caps.outside.assign(levels * kCutMaxCaps, never);
  for (size_t j = 0; j < kept.size(); ++j) {
    caps.x[j] = kept[j].axis.x;
    caps.y[j] = kept[j].axis.y;
    caps.z[j] = kept[j].axis.z;
    for (size_t l = 0; l < levels; ++l) {
      caps.inside[l * kCutMaxCaps + j] = kept[j].cosInside[l];
      caps.outside[l * kCutMaxCaps + j] = kept[j].cosOutside[l];
    }
  }
}

// The cap that covers the node deepest in part: the largest depth past the
// node's outside threshold over the span from there to its inside one
// (compared by cross products, no division), the first of equals; its
// covered share alone.
float CutPoint::visibleShare(const glm::vec3& centre, int level) const {
  const size_t l = size_t(level);
  const float* inside = caps.inside.data() + l * kCutMaxCaps;
  const float* outside = caps.outside.data() + l * kCutMaxCaps;
  const float *x = caps.x.data(), *y = caps.y.data(), *z = caps.z.data();
  const float cx = centre.x, cy = centre.y, cz = centre.z;
  float depth = 0.0f, span = 1.0f, dot = 0.0f, chord = 0.0f;
  for (size_t j = 0; j < kCutMaxCaps; ++j) {
    const float d = (cx * x[j] + cy * y[j]) + cz * z[j];
    const float past = d - outside[j];
    const float range = std::min(inside[j], 1.0f) - outside[j];
    // Selections, not branches: which cap wins is data the branch
    // predictor cannot learn. The slots past count have infinite
    // thresholds, past = -inf, and never win.
    const bool deeper = (past > 0.0f) & (past * span > depth * range);
    depth = deeper ? past : depth;
    span = deeper ? range : span;
    dot = deeper ? d : dot;
    chord = deeper ? caps.chord[j] : chord;
  }
  if (!(depth > 0.0f)) return 1.0f;
  const float rn = cut.discChord[l];
  const float small = std::min(rn, chord);
  const float dist = std::sqrt(std::max(2.0f - 2.0f * dot, 0.0f));
  const float s = std::min(std::max((dist - std::abs(rn - chord)) / (2.0f * small), 0.0f), 1.0f);
  const float ratio = small / rn;
  const float covered = (1.0f - cutSegmentShare(s)) * (ratio * ratio);
  return 1.0f - covered;
}

// The diffuse part is exact where the node lies above the horizon; where
// the horizon cuts its disc, at least the clipped disc's estimate; and at
// least kCutHorizonFloor x its power x the cos of its bounding cone's
// highest point. A partly covered node's visible share: the node and the
// cap as discs in the plane (chords for radii and distance), the smaller's
// covered share 1 - cutSegmentShare of how far it reaches past the
// larger's edge (0 touching it from inside, 1 from outside), as if that
// edge were straight; under the cap that reaches deepest into the node
// (visibleShare; where a ball stands on a plane their caps overlap), at
// least minPartial.
float CutPoint::weight(const CutLight& n, bool withLobe, bool* uncertain) const {
  const size_t l = size_t(n.level);
  const float power = n.power;
  if (!(power > 0.0f)) return 0.0f;
  const glm::vec3& m = n.moment;
  const glm::vec3& centre = n.centre;
  const float sinE = glm::dot(centre, normal), sinR = cut.discSin[l];
  float w = 0.0f;
  if (withLobe) {
    const float len = std::sqrt(glm::dot(m, m));
    if (len > 0.0f) {
      const glm::vec3 c = m / len;
      w = power * luminance(evalBsdf(lobe, woLocal, glm::vec3(glm::dot(c, s), glm::dot(c, t), glm::dot(c, normal))));
    }
  } else if (diffuse > 0.0f) {
    float d = glm::dot(m, normal);
    if (sinE < sinR) {
      d = sinE <= -sinR ? 0.0f : std::max(d, power * cutClippedCosine(sinE, sinR));
      if (uncertain && sinE > -sinR) *uncertain = true;
    }
    const float cosR = g.levelCosRadius[l], sinRb = g.levelSinRadius[l];
    const float cosE = std::sqrt(std::max(0.0f, 1.0f - sinE * sinE));
    const float top = sinE >= cosR ? 1.0f : sinE * cosR + cosE * sinRb;
    d = std::max(d, kCutHorizonFloor * power * std::max(top, 0.0f));
    w = diffuse * d;
  }
  if (!(w > 0.0f) || caps.count == 0) return w;
  // Every slot's tests in one loop without branches, then the covered
  // shares of the caps that cover the node in part.
  const float* inside = caps.inside.data() + l * kCutMaxCaps;
  const float* outside = caps.outside.data() + l * kCutMaxCaps;
  const float *x = caps.x.data(), *y = caps.y.data(), *z = caps.z.data();
  const float cx = centre.x, cy = centre.y, cz = centre.z;
  int covered = 0, partial = 0;
  for (size_t j = 0; j < kCutMaxCaps; ++j) {
    const float d = (cx * x[j] + cy * y[j]) + cz * z[j];
    covered |= d >= inside[j] ? 1 : 0;
    partial |= d > outside[j] ? 1 : 0;
  }
  if (covered) return 0.0f;
  if (!partial) return w;
  const float visible = visibleShare(centre, n.level);
  if (uncertain && visible < 1.0f) *uncertain = true;
  return w * std::max(visible, minPartial);
}

namespace {

// The columns a level's loops read and write.
struct LevelColumns {
  const float *__restrict x, *__restrict y, *__restrict z, *__restrict power;
  const float *__restrict mx, *__restrict my, *__restrict mz;
  float* __restrict w;
  int32_t* __restrict flags;
  size_t count;
};

// CutPoint::weight's diffuse part over a level's columns, each branch a
// selection: w, and flags bit 0 where the horizon cuts the node.
void diffuseWeights(const LevelColumns& c, glm::vec3 n, float diffuse, float sinR, float cosR, float sinRb) {
  const float nx = n.x, ny = n.y, nz = n.z;
  for (size_t i = 0; i < c.count; ++i) {
    const float power = c.power[i];
    const float sinE = (c.x[i] * nx + c.y[i] * ny) + c.z[i] * nz;
    const float dm = (c.mx[i] * nx + c.my[i] * ny) + c.mz[i] * nz;
    const float clipped = power * cutClippedCosine(sinE, sinR);
    const float cutBy = sinE <= -sinR ? 0.0f : (dm < clipped ? clipped : dm);
    const float d = sinE < sinR ? cutBy : dm;
    const float e = 1.0f - sinE * sinE;
    const float cosE = std::sqrt(0.0f < e ? e : 0.0f);
    const float top = sinE >= cosR ? 1.0f : sinE * cosR + cosE * sinRb;
    const float floorW = kCutHorizonFloor * power * (top < 0.0f ? 0.0f : top);
    const bool lit = power > 0.0f;
    const float weighted = diffuse * (d < floorW ? floorW : d);
    c.w[i] = lit ? weighted : 0.0f;
    c.flags[i] = int32_t(lit & (sinE < sinR) & (sinE > -sinR));
  }
}

// One cap's tests over a level's columns: flags bit 2 where it covers the
// node, bit 1 where it covers it in part.
void capTests(const LevelColumns& c, float ax, float ay, float az, float inside, float outside) {
  for (size_t i = 0; i < c.count; ++i) {
    const float d = (c.x[i] * ax + c.y[i] * ay) + c.z[i] * az;
    c.flags[i] |= (d >= inside ? 4 : 0) | (d > outside ? 2 : 0);
  }
}

}  // namespace

// Each cap's tests a pass of their own, so that every loop over a level's
// columns runs in vector registers.
void CutPoint::openWeights(const CutColumns& c, float* w, int32_t* flags) const {
  for (size_t l = 0; l + 1 < c.levelBegin.size(); ++l) {
    const size_t b = c.levelBegin[l];
    const LevelColumns level{c.x.data() + b,  c.y.data() + b,  c.z.data() + b,  c.power.data() + b, c.mx.data() + b,
                             c.my.data() + b, c.mz.data() + b, w + b,           flags + b,          c.levelBegin[l + 1] - b};
    if (level.count == 0) continue;
    diffuseWeights(level, normal, diffuse, cut.discSin[l], g.levelCosRadius[l], g.levelSinRadius[l]);
    for (size_t j = 0; j < size_t(caps.count); ++j)
      capTests(level, caps.x[j], caps.y[j], caps.z[j], caps.inside[l * kCutMaxCaps + j], caps.outside[l * kCutMaxCaps + j]);
  }
  // weight's order: a covered node has no weight, a node of none no caps.
  float* __restrict weights = w;
  int32_t* __restrict bits = flags;
  for (size_t i = 0, count = c.x.size(); i < count; ++i) {
    const int32_t tested = weights[i] > 0.0f ? 1 : 0, covered = (bits[i] >> 2) & 1;
    weights[i] = (tested & covered) != 0 ? 0.0f : weights[i];
    bits[i] &= 1 | ((tested & (covered ^ 1)) << 1);
  }
}

float CutPoint::diffuseWeight(const CutColumns& c, size_t i, int level, float w, int32_t flags,
                              bool* uncertain) const {
  if (uncertain && (flags & 1) != 0) *uncertain = true;
  if ((flags & 2) == 0) return w;
  const float visible = visibleShare(glm::vec3(c.x[i], c.y[i], c.z[i]), level);
  if (uncertain && visible < 1.0f) *uncertain = true;
  return w * std::max(visible, minPartial);
}

void CutDensity::reset(const CutPoint& point, const Environment& env, const CutOptions& options) {
  point_ = &point;
  env_ = &env;
  productLevel_ = std::min(options.productLevel, point.cut.momentLevel);
  const EnvCut& cut = point.cut;
  const size_t K = cut.nodes.size();
  const bool lobe = point.lobeOnly;
  cum_.resize(K + 1);
  children_.resize(4 * K);
  kept_.assign(K, 0);
  // A diffuse point's weights by the columns, and its refined nodes'
  // children's by columns of their own; a lobe alone's node by node.
  const bool columns = !lobe && point.diffuse > 0.0f;
  if (columns) {
    open_.resize(K);
    flags_.resize(K);
    nodeWeight_.resize(K);
    point.openWeights(cut.columns, open_.data(), flags_.data());
    refined_.clear();
    childLights_.clear();
    for (size_t k = 0; k < K; ++k) {
      const uint32_t i = cut.entry[k];
      const int level = cut.nodes[k].level;
      bool uncertain = false;
      nodeWeight_[k] = point.diffuseWeight(cut.columns, i, level, open_[i], flags_[i], &uncertain);
      if (uncertain && level < cut.momentLevel) {
        refined_.push_back(uint32_t(k));
        const auto first = cut.lights.begin() + int64_t(K + 4 * k);
        childLights_.insert(childLights_.end(), first, first + 4);
      }
    }
    if (!refined_.empty()) {
      childColumns_.fill(childLights_.data(), childLights_.size(), refinedEntry_);
      childOpen_.resize(childLights_.size());
      childFlags_.resize(childLights_.size());
      point.openWeights(childColumns_, childOpen_.data(), childFlags_.data());
      for (size_t r = 0; r < refined_.size(); ++r) {
        const uint32_t k = refined_[r];
        float* cw = &children_[4 * k];
        for (size_t j = 0; j < 4; ++j) {
          const uint32_t e = refinedEntry_[4 * r + j];
          cw[j] = point.diffuseWeight(childColumns_, e, cut.nodes[k].level + 1, childOpen_[e], childFlags_[e], nullptr);
        }
        nodeWeight_[k] = keepChildren(k, nodeWeight_[k]);
      }
    }
  }
  float total = 0.0f;
  glm::vec3 chromaSum(0.0f);
  for (size_t k = 0; k < K; ++k) {
    const CutNode& c = cut.nodes[k];
    float w;
    if (columns) {
      w = nodeWeight_[k];
    } else {
      bool uncertain = false;
      w = point.weight(cut.lights[k], lobe, &uncertain);
      // Its four children's weights where the horizon or a cap cuts it: the
      // descent's first step draws by them, so any weight keeps the pdf.
      if (uncertain && c.level < cut.momentLevel) {
        float* cw = &children_[4 * k];
        for (size_t j = 0; j < 4; ++j) cw[j] = point.weight(cut.lights[K + 4 * k + j], lobe);
        w = keepChildren(uint32_t(k), w);
      }
    }
    cum_[k] = total;
    total += w;
    chromaSum += (total - cum_[k]) * c.chroma;
  }
  cum_[K] = total;
  total_ = total;
  colourMean_ = total > 0.0f ? chromaSum / total : glm::vec3(0.0f);
}

float CutDensity::keepChildren(uint32_t k, float w) {
  kept_[k] = 1;
  const float* cw = &children_[4 * k];
  const float children = ((cw[0] + cw[1]) + cw[2]) + cw[3];
  return children > 0.0f ? children : w;
}

uint32_t CutDensity::node(double x) const {
  const size_t K = point_->cut.nodes.size();
  const float target = float(x) * total_;
  size_t k = size_t(std::upper_bound(cum_.begin() + 1, cum_.begin() + int64_t(K), target) - cum_.begin()) - 1;
  while (k > 0 && !(cum_[k + 1] - cum_[k] > 0.0f)) --k;  // a target at the very end
  return uint32_t(k);
}

double CutDensity::nodeProbability(uint32_t k) const { return double((cum_[k + 1] - cum_[k]) / total_); }

namespace {
// Children of no weight (under a cap, say) keep the environment's.
void environmentWhereZero(const MaxAvgTree& tree, uint64_t first, float (&w)[4]) {
  if (!(((w[0] + w[1]) + w[2]) + w[3] > 0.0f))
    for (int j = 0; j < 4; ++j) w[j] = tree.avgv[first + uint64_t(j)];
}
}  // namespace

void CutDensity::childWeights(int level, uint64_t parent, float (&w)[4]) const {
  const uint64_t first = MaxAvgTree::levelOffset(level) + 4 * parent;
  for (int j = 0; j < 4; ++j) w[j] = point_->weight(level, first + uint64_t(j), point_->lobeOnly);
  environmentWhereZero(env_->tree, first, w);
}

void CutDensity::firstChildWeights(uint32_t k, float (&w)[4]) const {
  const EnvCut& cut = point_->cut;
  const size_t K = cut.nodes.size();
  if (kept_[k])
    std::copy_n(&children_[4 * k], 4, w);
  else
    for (size_t j = 0; j < 4; ++j) w[j] = point_->weight(cut.lights[K + 4 * k + j], point_->lobeOnly);
  const CutNode& c = cut.nodes[k];
  environmentWhereZero(env_->tree, MaxAvgTree::levelOffset(c.level + 1) + 4 * c.node, w);
}

EnvSample CutDensity::sample(uint32_t k, glm::dvec2 u, glm::dvec3* colourDrift) const {
  const EnvCut& cut = point_->cut;
  const CutNode& c = cut.nodes[k];
  double p = nodeProbability(k);
  uint64_t node = c.node;
  const int below = std::max(c.level, productLevel_);
  glm::dvec3 drift(0.0);
  glm::vec3 chroma = c.chroma;
  for (int l = c.level + 1; l <= below; ++l) {
    float w[4], prob;
    if (l == c.level + 1)
      firstChildWeights(k, w);
    else
      childWeights(l, node, w);
    // The chroma the step draws on average, less the chroma of the child it draws.
    const uint64_t first = MaxAvgTree::levelOffset(l) + 4 * node;
    glm::dvec3 expected(0.0);
    if (colourDrift) {
      const double sum = ((double(w[0]) + double(w[1])) + double(w[2])) + double(w[3]);
      for (uint64_t j = 0; j < 4; ++j) expected += (double(w[j]) / sum) * glm::dvec3(cut.chroma[first + j]);
    }
    node = 4 * node + uint64_t(pickRescaled4(w, u.x, prob));
    if (colourDrift) {
      chroma = cut.chroma[MaxAvgTree::levelOffset(l) + node];
      drift += expected - glm::dvec3(chroma);
    }
    p *= double(prob);
  }
  EnvSample es = sampleEnvironmentBelow(*env_, env_->tree, below, node, u);
  // Below `below` the average tree draws the pixels by luminance, so the
  // pixel's chroma has the node's as its mean.
  if (colourDrift && es.pdf > 0.0f) {
    const glm::vec3 radiance = env_->radiance[es.pixel];
    drift += glm::dvec3(chroma) - glm::dvec3(radiance / luminance(radiance));
  }
  es.pdf = float(p * double(es.pdf));
  if (colourDrift) *colourDrift = drift;
  return es;
}

float CutDensity::pdf(uint64_t pixel) const {
  const EnvCut& cut = point_->cut;
  const uint32_t k = cut.cutNodeOf(*env_, pixel);
  const CutNode& c = cut.nodes[k];
  double p = nodeProbability(k);
  const int below = std::max(c.level, productLevel_);
  for (int l = c.level + 1; l <= below && p > 0.0; ++l) {
    float w[4];
    if (l == c.level + 1)
      firstChildWeights(k, w);
    else
      childWeights(l, pixel >> (2 * (env_->order - l + 1)), w);
    const int j = int((pixel >> (2 * (env_->order - l))) & 3);
    const float sum = ((w[0] + w[1]) + w[2]) + w[3];
    p = w[j] > 0.0f ? p * double(w[j] / sum) : 0.0;
  }
  return float(p * environmentPixelProbabilityBelow(env_->tree, below, pixel) / env_->pixelSolidAngle());
}

glm::vec3 estimateHtCut(const Scene& scene, const ShadingPoint& sp, const CutOptions& options, int n, Rng& rng,
                        PixelSampler& sampler, EstimateCounters& counters, const EnvCut& cut, const HtGeometry& g) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || n <= 0) return glm::vec3(0.0f);
  const Shading sh(scene, sp, counters);
  const Material& mat = *sp.material;
  const CutPoint point(scene, sp, sh, options, cut, g);
  thread_local CutDensity densityStore;
  CutDensity* density = &densityStore;
  density->reset(point, env, options);
  const float total = density->total();
  if (!(total > 0.0f)) return glm::vec3(0.0f);

  // The BRDF technique and its count. A diffuse point has none. With both
  // lobes the weights hold the diffuse one and the BRDF technique samples
  // the specular lobe for its share of the light (ht-frontier's
  // frontierLobeCount: reflectance x the map's average around the mirror
  // direction against the weights' total). A specular lobe alone gives
  // cutLobeShare of the directions to the BRDF.
  const Material& bm = point.apart ? point.lobe : mat;
  float share = 0.0f;
  if (point.apart) {
    const int lobeLevel = std::min(kFrontierLobeLevel, env.order);
    const glm::vec3 mirror = sh.frame.toWorld(glm::vec3(-sh.woLocal.x, -sh.woLocal.y, sh.woLocal.z));
    const float mirrorRadiance = env.tree.avgv[MaxAvgTree::levelOffset(lobeLevel) +
                                               healpix::vecToPix(lobeLevel, env.toHealpixFrame(mirror))];
    const float f0 = luminance(mat.specular);
    const float q = 1.0f - std::clamp(sh.woLocal.z, 0.0f, 1.0f);
    const float reflectance = mat.type == MaterialType::Ggx ? f0 + (1.0f - f0) * (q * q * q * q * q) : f0;
    const float lobeLight = reflectance * mirrorRadiance;
    share = std::clamp(lobeLight / (lobeLight + total), kCutMinShare, 1.0f - kCutMinShare);
  } else if (point.lobeOnly) {
    share = cutLobeShare(mat, cutLobeSpan(options, cut, g));
  }
  // Fixed counts, at least one of each technique that has a share; one
  // direction picks its technique with the shares as probabilities.
  const bool mixture = n == 1 && share > 0.0f;
  const int nb = share > 0.0f && n > 1 ? std::clamp(int(std::floor(double(share) * n + 0.5)), 1, n - 1) : 0;
  const float cWeight = mixture ? 1.0f - share : float(n - nb);
  const float bWeight = mixture ? share : float(nb);
  double offset = double(rng.next());
  int cutCount = n - nb, brdfCount = nb;
  if (mixture) {
    const bool fromCut = offset >= double(share);
    cutCount = fromCut ? 1 : 0;
    brdfCount = 1 - cutCount;
    offset = fromCut ? (offset - double(share)) / (1.0 - double(share)) : offset / double(share);
  }
  counters.directions += uint64_t(n);

  // The control variate: a cut direction's f / p is about total / cWeight x
  // the diffuse colour x its light's chroma, and the chroma of the node
  // drawn has the mean colourMean. A lobe alone has none: its weights are
  // not its density's product.
  const bool colourControl = options.colourControl && cutCount > 0 && !point.lobeOnly;
  const glm::vec3 fColour = colourControl ? mat.diffuse / luminance(mat.diffuse) : glm::vec3(0.0f);
  const glm::dvec3 colourScale = glm::dvec3(fColour) * (double(total) / double(cWeight));
  const glm::vec3 colourMean = density->colourMean();

  glm::dvec3 sum(0.0);
  // Systematic points on the cut's prefix sums, one offset per point; below
  // its node a direction takes the sampler's point of sample i, dimension
  // 0, and the BRDF's directions dimension 1.
  for (int i = 0; i < cutCount; ++i) {
    const uint32_t k = density->node((double(i) + offset) / double(cutCount));
    sampler.startSample(uint32_t(i));
    glm::dvec3 drift(0.0);
    const EnvSample es = density->sample(k, sampler.get2DPrecise(), colourControl ? &drift : nullptr);
    if (colourControl) sum += colourScale * (glm::dvec3(colourMean - cut.nodes[k].chroma) + drift);
    if (!(es.pdf > 0.0f)) continue;
    const float pb = bWeight > 0.0f ? bsdfPdf(bm, sh.woLocal, sh.frame.toLocal(es.dir)) : 0.0f;
    sum += glm::dvec3(sh.reflected(es.dir, env.radiance[es.pixel]) / (cWeight * es.pdf + bWeight * pb));
  }
  for (int i = 0; i < brdfCount; ++i) {
    sampler.startSample(uint32_t(i));
    sampler.setDimension(1);
    const glm::vec3 local = sampleBsdf(bm, sh.woLocal, sampler.get2D());
    const float pb = bsdfPdf(bm, sh.woLocal, local);
    if (!(pb > 0.0f)) continue;
    const glm::vec3 wi = sh.frame.toWorld(local);
    const uint64_t pixel = env.pixelOf(wi);
    sum += glm::dvec3(sh.reflected(wi, env.radiance[pixel]) / (cWeight * density->pdf(pixel) + bWeight * pb));
  }
  // The control variate can take a dark channel below 0, rarely.
  return glm::vec3(glm::max(sum, glm::dvec3(0.0)));
}

}  // namespace ht
