#include "environment.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <functional>
#include <iterator>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_for.h>

#include "error.h"
#include "healpix.h"
#include "sampling.h"

namespace ht {
namespace {

constexpr double kPiD = 3.14159265358979323846;

void finish(Environment& env) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<float> lum(env.radiance.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, lum.size()), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) lum[i] = luminance(env.radiance[i]);
  });
  env.tree = buildMaxAvgTree(env.order, lum);
  env.treeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void setYaw(Environment& env, float yawDegrees) {
  env.yawRadians = float(double(yawDegrees) * kPiD / 180.0);
  env.cosYaw = std::cos(env.yawRadians);
  env.sinYaw = std::sin(env.yawRadians);
}

}  // namespace

// World (y-up) -> HEALPix frame (pole = world +y), after undoing the yaw.
glm::dvec3 Environment::toHealpixFrame(const glm::vec3& w) const {
  double x = double(cosYaw) * w.x - double(sinYaw) * w.z;
  double z = double(sinYaw) * w.x + double(cosYaw) * w.z;
  return {z, x, double(w.y)};
}

glm::vec3 Environment::fromHealpixFrame(const glm::dvec3& h) const {
  double x = h.y, z = h.x;
  return glm::vec3(float(cosYaw * x + sinYaw * z), float(h.z), float(-sinYaw * x + cosYaw * z));
}

uint64_t Environment::pixelOf(const glm::vec3& worldDir) const {
  return healpix::vecToPix(order, toHealpixFrame(worldDir));
}

glm::vec3 Environment::direction(int level, uint64_t pix, float dx, float dy) const {
  return fromHealpixFrame(healpix::pixToVec(level, pix, dx, dy));
}

double Environment::pixelSolidAngle() const { return healpix::pixelSolidAngle(order); }

glm::vec3 equirectDirection(double u, double v) {
  double theta = v * kPiD, phi = u * 2.0 * kPiD;
  return glm::vec3(float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)),
                   float(-std::sin(theta) * std::cos(phi)));
}

void equirectUV(const glm::vec3& d, double& u, double& v) {
  double len = std::sqrt(double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
  double phi = std::atan2(double(d.x), -double(d.z));
  if (phi < 0.0) phi += 2.0 * kPiD;
  u = std::min(phi / (2.0 * kPiD), std::nextafter(1.0, 0.0));
  v = std::min(std::acos(std::clamp(double(d.y) / len, -1.0, 1.0)) / kPiD, std::nextafter(1.0, 0.0));
}

EnvironmentStats sanitizeEnvironmentImage(ImageRGB& image, const std::string& name, bool repairNonFinite) {
  EnvironmentStats stats;
  // Texel values are visited in parallel over fixed blocks and the blocks'
  // results joined in a fixed order, so the outcome does not depend on the
  // thread count. Indices count values: 3 per pixel.
  constexpr size_t kNone = SIZE_MAX, kBlock = size_t(1) << 14;
  struct Scan {
    uint64_t nonFinite = 0;
    size_t firstNonFinite = kNone;
    double sum = 0.0;
    float lo = INFINITY, hi = -INFINITY;
    bool negative = false;
  };
  const size_t pixels = image.pixels.size();
  const Scan scan = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, pixels, kBlock), Scan{},
      [&](const tbb::blocked_range<size_t>& range, Scan s) {
        for (size_t i = range.begin(); i != range.end(); ++i)
          for (int c = 0; c < 3; ++c) {
            float& v = image.pixels[i][c];
            if (!std::isfinite(v)) {
              if (s.nonFinite++ == 0) s.firstNonFinite = 3 * i + size_t(c);
              if (repairNonFinite) v = 0.0f;
              continue;
            }
            s.lo = std::min(s.lo, v);
            s.hi = std::max(s.hi, v);
            s.sum += std::max(0.0f, v);
            s.negative |= v < 0.0f;
          }
        return s;
      },
      [](Scan a, const Scan& b) {
        a.nonFinite += b.nonFinite;
        a.firstNonFinite = std::min(a.firstNonFinite, b.firstNonFinite);
        a.sum += b.sum;
        a.lo = std::min(a.lo, b.lo);
        a.hi = std::max(a.hi, b.hi);
        a.negative |= b.negative;
        return a;
      });
  stats.repairedNonFiniteTexels = repairNonFinite ? scan.nonFinite : 0;
  if (scan.nonFinite > 0 && !repairNonFinite)
    throw Error(fmt::format("{}: {} NaN/Inf texel value(s), first at pixel ({}, {})", name, scan.nonFinite,
                            scan.firstNonFinite / 3 % image.width, scan.firstNonFinite / 3 / image.width));
  // Lossy EXR compression (DWAB) leaves tiny negatives (down to -4e-3 in the
  // shipped maps); below -max(0.01, 1% of the mean) the map is broken.
  if (scan.negative) {
    const double mean = scan.sum / (3.0 * double(pixels));
    const float tolerance = float(std::max(1e-2 * mean, 1e-2));
    struct Clamp {
      uint64_t clamped = 0;
      size_t firstBroken = kNone;
    };
    const Clamp clamp = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, pixels, kBlock), Clamp{},
        [&](const tbb::blocked_range<size_t>& range, Clamp k) {
          for (size_t i = range.begin(); i != range.end(); ++i)
            for (int c = 0; c < 3; ++c) {
              float& v = image.pixels[i][c];
              if (v >= 0.0f) continue;
              if (v < -tolerance) {
                k.firstBroken = std::min(k.firstBroken, 3 * i + size_t(c));
                continue;
              }
              v = 0.0f;
              ++k.clamped;
            }
          return k;
        },
        [](Clamp a, const Clamp& b) {
          a.clamped += b.clamped;
          a.firstBroken = std::min(a.firstBroken, b.firstBroken);
          return a;
        });
    if (clamp.firstBroken != kNone) {
      const size_t i = clamp.firstBroken / 3;
      throw Error(fmt::format("{}: negative texel value {} at pixel ({}, {}) (tolerance -{})", name,
                              image.pixels[i][int(clamp.firstBroken % 3)], i % image.width, i / image.width,
                              tolerance));
    }
    stats.clampedNegativeTexels = clamp.clamped;
  }
  stats.minTexel = pixels == 0 ? 0.0f : scan.lo;
  stats.maxTexel = pixels == 0 ? 0.0f : scan.hi;
  return stats;
}

namespace {

// A HEALPix pixel edge crossing a band of latitude: its azimuth, as
// tt = phi / (pi/2), at the band's top and bottom, and its mean over the band
// (which sorts the edges).
struct Edge {
  double top, bottom, mean;
};

// The pixel edges crossing the band [zBottom, zTop], one period of them in
// ascending order, for a band that holds no pixel corner. They are the steps
// of healpix::zphiToPix: in the equatorial zone those of
// floor(fn (0.5 + tt) -/+ fn 0.75 z), straight in (tt, z); in the polar caps
// those of floor(tp t) and floor((1 - tp) t), t = fn sqrt(3 (1 - |z|)),
// within each quarter, which curve: there the edge is replaced by a straight
// one with the curve's mean, so that every piece keeps its exact area.
// `zPixel` is a latitude in the band at which the pieces between the edges'
// means lie in their pixels.
void bandEdges(int order, double zTop, double zBottom, std::vector<Edge>& edges, std::vector<Edge>& up,
               std::vector<Edge>& down, double& zPixel) {
  const double fn = double(int64_t(1) << order);
  up.clear();
  down.clear();
  edges.clear();
  const double zMid = 0.5 * (zTop + zBottom);
  zPixel = zMid;
  if (std::abs(zMid) <= 2.0 / 3.0) {
    for (int side = 0; side < 2; ++side) {
      const double sign = side == 0 ? 0.75 : -0.75;
      const double c = sign * fn * zMid;
      for (int64_t k = int64_t(std::floor(0.5 * fn - c)); k <= int64_t(4.5 * fn - c) + 1; ++k) {
        const double mean = (double(k) + c) / fn - 0.5;
        if (mean < 0.0 || mean >= 4.0) continue;
        const double top = (double(k) + sign * fn * zTop) / fn - 0.5;
        const double bottom = (double(k) + sign * fn * zBottom) / fn - 0.5;
        (side == 0 ? up : down).push_back({top, bottom, mean});
      }
    }
  } else {
    auto s = [](double z) { return std::sqrt(3.0 * (1.0 - std::abs(z))); };
    const double sTop = s(zTop), sBottom = s(zBottom);
    // Mean of 1 / s over the band, from the integral of dz / s = -2/3 ds.
    const double invMean = (2.0 / 3.0) * std::abs(sTop - sBottom) / (zTop - zBottom);
    zPixel = std::copysign(1.0 - 1.0 / (3.0 * invMean * invMean), zMid);
    const double t = fn / invMean;
    const double invTop = sTop > 0.0 ? 1.0 / (fn * sTop) : 0.0, invBottom = sBottom > 0.0 ? 1.0 / (fn * sBottom) : 0.0;
    for (int q = 0; q < 4; ++q) {
      up.push_back({double(q), double(q), double(q)});
      for (int64_t k = 1; double(k) < t; ++k) {
        const double shift = k * (invMean / fn - 0.5 * (invTop + invBottom));
        up.push_back({q + k * invTop + shift, q + k * invBottom + shift, q + k * invMean / fn});
      }
      for (int64_t k = int64_t(std::ceil(t)); k >= 1; --k) {
        if (!(double(k) < t)) continue;
        const double shift = k * (invMean / fn - 0.5 * (invTop + invBottom));
        down.push_back({q + 1.0 - k * invTop - shift, q + 1.0 - k * invBottom - shift, q + 1.0 - k * invMean / fn});
      }
    }
  }
  std::merge(up.begin(), up.end(), down.begin(), down.end(), std::back_inserter(edges),
             [](const Edge& a, const Edge& b) { return a.mean < b.mean; });
}

}  // namespace

// Each texel row is cut into bands of latitude at every texel-row boundary
// and at every z where HEALPix pixels have corners. Inside such a band the
// pixel edges do not cross, and the piece of the band between two
// neighbouring edges lies in one pixel; the texel-constant map is integrated
// over it exactly (along straight edges the integral of the azimuthal
// cumulative sum is a second cumulative sum). Equatorial pixel edges are
// straight, so there every pixel gets its exact integral; polar edges are
// replaced by chords with the same mean, which keeps every pixel's area and
// moves energy only across texel edges near the pixel's edges. The total is
// kept exactly.
Environment environmentFromEquirect(const ImageRGB& image, int order, float yawDegrees, float scale) {
  Environment env;
  env.order = order;
  const int width = image.width, height = image.height;
  const int64_t n = int64_t(1) << order;

  // Band boundaries in z, descending from 1 to -1, each band with its texel
  // row and the HEALPix ring (1..4n-1) whose centre is the nearest at or
  // above its top (0 for the pole): its pieces lie in that ring and the next.
  const int64_t rings = 4 * n - 1;
  std::vector<double> ringZ(size_t(rings) + 1);
  ringZ[0] = 1.0;
  std::vector<double> levels;
  for (int64_t m = 1; m < n; ++m) levels.push_back(1.0 - double(m * m) / double(3 * n * n));
  const size_t polar = levels.size();
  for (size_t i = 0; i < polar; ++i) {
    ringZ[i + 1] = levels[i];
    ringZ[size_t(rings) - i] = -levels[i];
  }
  for (size_t i = 0; i < polar; ++i) levels.push_back(-levels[i]);
  for (int64_t m = 0; m <= 2 * n; ++m) {
    levels.push_back((2.0 / 3.0) * double(n - m) / double(n));
    ringZ[size_t(n + m)] = levels.back();
  }
  for (int y = 1; y < height; ++y) levels.push_back(std::cos(kPiD * y / height));
  std::sort(levels.begin(), levels.end(), std::greater<double>());
  levels.push_back(-1.0);
  struct Band {
    double zTop, zBottom;
    int row;
    int64_t ring;
  };
  std::vector<Band> bands;
  double zTop = 1.0;
  int row = 0;
  int64_t ring = 0;
  for (double z : levels) {
    if (!(z < zTop)) continue;
    while (row + 1 < height && zTop <= std::cos(kPiD * (row + 1) / height)) ++row;
    while (ring < rings && ringZ[size_t(ring) + 1] >= zTop) ++ring;
    bands.push_back({zTop, z, row, ring});
    zTop = z;
  }

  env.radiance.assign(healpix::pixelCount(order), glm::vec3(0.0f));
  const double dphi = 2.0 * kPiD / width;
  const double toRadiance = double(scale) / healpix::pixelSolidAngle(order);
  struct Scratch {
    // Over a row, in texel units t: first[x] = integral of L over [0, x],
    // second[x] = integral of that over [0, x].
    std::vector<glm::dvec3> first, second;
    std::vector<Edge> edges, up, down;
    int row = -1;
    // The energy of a group's pixels, by ring and position in the ring,
    // and each one's nested index.
    std::vector<glm::dvec3> energy;
    std::vector<uint64_t> pixel;
    std::vector<size_t> ringStart;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  // The rings are split into groups integrated in parallel; each group takes
  // every band that reaches its rings and keeps the pieces that fall in
  // them, so each pixel sums its pieces in band order on one thread and the
  // result does not depend on the thread count. The bands next to a group's
  // edge rings are integrated by both neighbours.
  const int64_t ringsPerGroup = resampleRingsPerGroup(order);
  const int64_t groups = (rings + ringsPerGroup - 1) / ringsPerGroup;
  constexpr uint64_t kNoPixel = ~uint64_t(0);
  tbb::parallel_for(int64_t(0), groups, [&](int64_t group) {
    Scratch& sc = scratch.local();
    const int64_t ringA = group * ringsPerGroup + 1, ringB = std::min(rings, ringA + ringsPerGroup - 1);
    sc.ringStart.assign(1, 0);
    for (int64_t r = ringA; r <= ringB; ++r)
      sc.ringStart.push_back(sc.ringStart.back() + size_t(healpix::ringPixelCount(order, r)));
    sc.energy.assign(sc.ringStart.back(), glm::dvec3(0.0));
    sc.pixel.assign(sc.ringStart.back(), kNoPixel);
    std::vector<glm::dvec3>& first = sc.first;
    std::vector<glm::dvec3>& second = sc.second;
    std::vector<Edge>& edges = sc.edges;
    first.resize(size_t(width) + 1);
    second.resize(size_t(width) + 1);
    auto begin = std::lower_bound(bands.begin(), bands.end(), ringA - 1,
                                  [](const Band& b, int64_t r) { return b.ring < r; });
    auto end = std::upper_bound(bands.begin(), bands.end(), ringB,
                                [](int64_t r, const Band& b) { return r < b.ring; });
    for (auto band = begin; band != end; ++band) {
      const glm::vec3* texels = &image.at(0, band->row);
      if (band->row != sc.row) {
        sc.row = band->row;
        for (int x = 0; x < width; ++x) {
          first[x + 1] = first[x] + glm::dvec3(texels[x]);
          second[x + 1] = second[x] + first[x] + 0.5 * glm::dvec3(texels[x]);
        }
      }
      // The two cumulative sums at t in [-W, W), continued periodically.
      auto at = [&](double t, glm::dvec3& f, glm::dvec3& g) {
        const bool wrapped = t < 0.0;
        if (wrapped) t += width;
        const int x = std::clamp(int(t), 0, width - 1);
        const double d = t - x;
        const glm::dvec3 l(texels[x]);
        f = first[x] + d * l;
        g = second[x] + d * first[x] + 0.5 * d * d * l;
        if (wrapped) {
          f -= first[width];
          g -= second[width] + (t - width) * first[width];
        }
      };
      // Integral over the band's z of L integrated in azimuth up to the
      // edge, which is straight: the map's u = 0.5 - tt / 4.
      const double dz = band->zTop - band->zBottom;
      auto integral = [&](const Edge& e, double shift) {
        const double tTop = (0.5 - 0.25 * (e.top + shift)) * width;
        const double tBottom = (0.5 - 0.25 * (e.bottom + shift)) * width;
        glm::dvec3 fTop, gTop, fBottom, gBottom;
        if (std::abs(tTop - tBottom) < 1e-3) {
          at(0.5 * (tTop + tBottom), fTop, gTop);
          return fTop * dz;
        }
        at(tTop, fTop, gTop);
        at(tBottom, fBottom, gBottom);
        return (gTop - gBottom) * (dz / (tTop - tBottom));
      };
      double zPixel;
      bandEdges(order, band->zTop, band->zBottom, edges, sc.up, sc.down, zPixel);
      glm::dvec3 previous = integral(edges[0], 0.0);
      for (size_t e = 1; e <= edges.size(); ++e) {
        const Edge& edge = edges[e % edges.size()];
        const double shift = e == edges.size() ? 4.0 : 0.0;
        const glm::dvec3 next = integral(edge, shift);
        const double phi = 0.25 * kPiD * (edges[e - 1].mean + edge.mean + shift);
        uint32_t ix, iy;
        int face;
        healpix::zphiToXYF(order, zPixel, phi, ix, iy, face);
        int64_t pieceRing, pos;
        healpix::xyfToRing(order, ix, iy, face, pieceRing, pos);
        if (pieceRing >= ringA && pieceRing <= ringB) {
          const size_t slot = sc.ringStart[size_t(pieceRing - ringA)] + size_t(pos);
          sc.energy[slot] += (previous - next) * dphi;
          sc.pixel[slot] = healpix::xyfToPix(order, ix, iy, face);
        }
        previous = next;
      }
    }
    for (size_t slot = 0; slot < sc.energy.size(); ++slot)
      if (sc.pixel[slot] != kNoPixel) env.radiance[sc.pixel[slot]] = glm::vec3(sc.energy[slot] * toRadiance);
  });
  setYaw(env, yawDegrees);
  finish(env);
  return env;
}

int64_t resampleRingsPerGroup(int order) {
  const int64_t n = int64_t(1) << order, rings = 4 * n - 1;
  return std::clamp<int64_t>((rings + 63) / 64, 1, std::max<int64_t>(1, (int64_t(1) << 18) / (4 * n)));
}

Environment environmentFromPixels(int order, std::vector<glm::vec3> radiance, float yawDegrees) {
  Environment env;
  env.order = order;
  env.radiance = std::move(radiance);
  setYaw(env, yawDegrees);
  finish(env);
  return env;
}

Environment constantEnvironment(int order, const glm::vec3& value) {
  return environmentFromPixels(order, std::vector<glm::vec3>(healpix::pixelCount(order), value));
}

}  // namespace ht
