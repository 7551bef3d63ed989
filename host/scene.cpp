#include "scene.h"

#include <algorithm>
#include <array>
#include <numeric>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <vector>
#include <limits>
#include <sstream>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "common.h"  // shaders/common.h
#include "healpix.h"
#include "image_io.h"
#include "sampling.h"

namespace ht {
namespace {

using json = nlohmann::json;

// Validates one JSON object: known keys only, typed getters with ranges.
class Obj {
 public:
  Obj(const json& j, std::string where, const std::vector<std::string_view>& keys) : j_(j), where_(std::move(where)) {
    if (!j.is_object()) fail("must be an object");
    for (auto it = j.begin(); it != j.end(); ++it)
      if (std::find(keys.begin(), keys.end(), it.key()) == keys.end())
        fail(fmt::format("unknown key \"{}\"", it.key()));
  }

  bool has(const char* key) const { return j_.contains(key); }
  const json& at(const char* key) const {
    if (!has(key)) fail(fmt::format("missing key \"{}\"", key));
    return j_.at(key);
  }
  std::string path(const char* key) const { return where_ + "." + key; }

  float number(const char* key, float lo, float hi, bool openLo = false) const {
    const json& v = at(key);
    if (!v.is_number()) fail(fmt::format("\"{}\" must be a number", key));
    double x = v.get<double>();
    if (!std::isfinite(x) || x < lo || x > hi || (openLo && x == lo))
      fail(fmt::format("\"{}\" = {} is out of range {}{}, {}]", key, x, openLo ? "(" : "[", lo, hi));
    return float(x);
  }
  float number(const char* key, float lo, float hi, float fallback, bool openLo = false) const {
    return has(key) ? number(key, lo, hi, openLo) : fallback;
  }
  int integer(const char* key, int lo, int hi, int fallback) const {
    if (!has(key)) return fallback;
    const json& v = j_.at(key);
    if (!v.is_number_integer()) fail(fmt::format("\"{}\" must be an integer", key));
    if (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t(hi))
      fail(fmt::format("\"{}\" = {} is out of range [{}, {}]", key, v.get<uint64_t>(), lo, hi));
    auto x = v.get<int64_t>();
    if (x < lo || x > hi) fail(fmt::format("\"{}\" = {} is out of range [{}, {}]", key, x, lo, hi));
    return int(x);
  }
  std::string string(const char* key) const {
    const json& v = at(key);
    if (!v.is_string()) fail(fmt::format("\"{}\" must be a string", key));
    return v.get<std::string>();
  }
  glm::vec3 vec3(const char* key) const {
    const json& v = at(key);
    if (!v.is_array() || v.size() != 3 || !std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_number(); }))
      fail(fmt::format("\"{}\" must be an array of 3 numbers", key));
    glm::vec3 r(v[0].get<float>(), v[1].get<float>(), v[2].get<float>());
    if (!std::isfinite(r.x) || !std::isfinite(r.y) || !std::isfinite(r.z))
      fail(fmt::format("\"{}\" must be finite", key));
    return r;
  }
  // An RGB colour with components in [lo, hi]; a single number means grey.
  glm::vec3 colour(const char* key, float lo, float hi) const {
    const json& v = at(key);
    glm::vec3 c = v.is_number() ? glm::vec3(number(key, lo, hi)) : vec3(key);
    for (int i = 0; i < 3; ++i)
      if (c[i] < lo || c[i] > hi) fail(fmt::format("\"{}\" components must lie in [{}, {}]", key, lo, hi));
    return c;
  }
  glm::vec3 colour(const char* key, float lo, float hi, glm::vec3 fallback) const {
    return has(key) ? colour(key, lo, hi) : fallback;
  }

  [[noreturn]] void fail(const std::string& what) const { throw Error(fmt::format("{}: {}", where_, what)); }

 private:
  const json& j_;
  std::string where_;
};

constexpr float kMinGgxAlpha = 1e-3f;
// Brightest scaled radiance accepted: products with the largest BRDF values
// and pdfs of the renderer must stay finite in single precision.
constexpr double kMaxRadiance = 1e20;

Material parseMaterial(const Obj& m, const std::string& type) {
  Material mat;
  if (type == "lambert") {
    mat.type = MaterialType::Lambert;
    mat.diffuse = m.colour("albedo", 0.0f, 1.0f);
  } else if (type == "phong") {
    mat.type = MaterialType::Phong;
    mat.specular = m.colour("specular", 0.0f, 1.0f);
    mat.exponent = m.number("exponent", 0.0f, 1e6f, true);
    mat.diffuse = m.colour("diffuse", 0.0f, 1.0f, glm::vec3(0.0f));
  } else {
    mat.type = MaterialType::Ggx;
    mat.alpha = m.number("alpha", 0.0f, 1.0f, true);
    // Below this, D(h) = alpha^2 / (pi (cos^2 (alpha^2 - 1) + 1)^2) cancels to
    // 0/0 or x/0 in single precision and poisons the image with NaN.
    if (mat.alpha < kMinGgxAlpha)
      m.fail(fmt::format("\"alpha\" = {} is below {}, the smallest roughness evaluated reliably in single precision",
                         mat.alpha, kMinGgxAlpha));
    if (m.has("f0") == m.has("conductor")) m.fail("ggx needs exactly one of \"f0\" and \"conductor\"");
    mat.specular = m.has("f0") ? m.colour("f0", 0.0f, 1.0f) : m.colour("conductor", 0.0f, 1.0f);
    mat.diffuse = m.colour("diffuse", 0.0f, 1.0f, glm::vec3(0.0f));
  }
  return mat;
}

std::string lineColumn(const std::string& text, size_t byte) {
  size_t line = 1, col = 1;
  for (size_t i = 0; i < std::min(byte, text.size()); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return fmt::format("line {}, column {}", line, col);
}

}  // namespace

namespace {

Scene parseSceneText(const std::string& text, const std::string& path) {
  json root;
  try {
    root = json::parse(text);
  } catch (const json::parse_error& e) {
    std::string msg = e.what();
    auto colon = msg.rfind(": ");
    throw Error(fmt::format("{}: JSON syntax error at {}: {}", path, lineColumn(text, e.byte ? e.byte - 1 : 0),
                            colon == std::string::npos ? msg : msg.substr(colon + 2)));
  } catch (const json::out_of_range& e) {
    // A number literal beyond double (1e400): the message quotes the literal,
    // whose first occurrence gives the position.
    std::string msg = e.what();
    auto open = msg.find('\''), close = msg.rfind('\'');
    std::string where = "a number";
    if (open != std::string::npos && close > open + 1) {
      auto at = text.find(msg.substr(open + 1, close - open - 1));
      if (at != std::string::npos) where = lineColumn(text, at);
    }
    auto bracket = msg.find("] ");
    throw Error(fmt::format("{}: JSON number out of range at {}: {}", path, where,
                            oneLine(bracket == std::string::npos ? msg : msg.substr(bracket + 2))));
  } catch (const json::exception& e) {
    throw Error(fmt::format("{}: JSON error: {}", path, oneLine(e.what())));
  }
  Scene scene;
  scene.path = path;
  Obj top(root, path, {"camera", "image", "environment", "materials", "spheres", "planes"});

  Obj cam(top.at("camera"), path + ": camera", {"position", "look_at", "up", "fov"});
  scene.camera.position = cam.vec3("position");
  scene.camera.lookAt = cam.vec3("look_at");
  scene.camera.up = cam.has("up") ? cam.vec3("up") : glm::vec3(0, 1, 0);
  scene.camera.fovY = cam.number("fov", 0.0f, 179.0f, 40.0f, true);
  glm::vec3 forward = scene.camera.lookAt - scene.camera.position;
  if (!std::isfinite(glm::length(forward)) || !std::isfinite(glm::length(scene.camera.up)))
    cam.fail("position and look_at too far apart, or up too long, for single precision");
  if (glm::length(forward) < 1e-6f) cam.fail("position and look_at coincide");
  if (glm::length(scene.camera.up) < 1e-6f ||
      glm::length(glm::cross(glm::normalize(forward), glm::normalize(scene.camera.up))) < 1e-4f)
    cam.fail("up must be non-zero and not parallel to the view direction");

  if (top.has("image")) {
    Obj img(top.at("image"), path + ": image", {"width", "height"});
    scene.width = img.integer("width", 1, 16384, scene.width);
    scene.height = img.integer("height", 1, 16384, scene.height);
  }

  Obj env(top.at("environment"), path + ": environment", {"file", "nside", "yaw", "scale"});
  scene.environmentDesc.file = env.string("file");
  if (scene.environmentDesc.file.empty()) env.fail("\"file\" is empty");
  int nside = env.integer("nside", 1, 1 << healpix::kMaxOrder, 256);
  if ((nside & (nside - 1)) != 0) env.fail(fmt::format("\"nside\" = {} is not a power of two", nside));
  scene.environmentDesc.nside = nside;
  scene.environmentDesc.yaw = env.number("yaw", -360.0f, 360.0f, 0.0f);
  scene.environmentDesc.scale = env.number("scale", 0.0f, 1e9f, 1.0f);

  const json& mats = top.at("materials");
  if (!mats.is_object() || mats.empty()) top.fail("\"materials\" must be a non-empty object of named materials");
  for (auto it = mats.begin(); it != mats.end(); ++it) {
    std::string where = fmt::format("{}: materials.{}", path, it.key());
    if (!it->is_object() || !it->contains("type") || !(*it)["type"].is_string())
      throw Error(where + ": must be an object with a string \"type\"");
    std::string type = (*it)["type"].get<std::string>();
    std::vector<std::string_view> keys;
    if (type == "lambert") keys = {"type", "albedo"};
    else if (type == "phong") keys = {"type", "specular", "exponent", "diffuse"};
    else if (type == "ggx") keys = {"type", "alpha", "f0", "conductor", "diffuse"};
    else throw Error(fmt::format("{}: unknown material type \"{}\" (lambert, phong, ggx)", where, type));
    scene.materials.push_back(parseMaterial(Obj(*it, where, keys), type));
    scene.materialNames.push_back(it.key());
  }
  auto materialIndex = [&](const Obj& o) {
    std::string name = o.string("material");
    auto it = std::find(scene.materialNames.begin(), scene.materialNames.end(), name);
    if (it == scene.materialNames.end()) o.fail(fmt::format("unknown material \"{}\"", name));
    return int(it - scene.materialNames.begin());
  };

  auto list = [&](const char* key) -> const json& {
    static const json empty = json::array();
    if (!top.has(key)) return empty;
    const json& a = top.at(key);
    if (!a.is_array()) top.fail(fmt::format("\"{}\" must be an array", key));
    return a;
  };
  const json& spheres = list("spheres");
  for (size_t i = 0; i < spheres.size(); ++i) {
    Obj s(spheres[i], fmt::format("{}: spheres[{}]", path, i), {"center", "radius", "material"});
    scene.spheres.push_back({s.vec3("center"), s.number("radius", 0.0f, 1e6f, true), materialIndex(s)});
  }
  const json& planes = list("planes");
  for (size_t i = 0; i < planes.size(); ++i) {
    Obj p(planes[i], fmt::format("{}: planes[{}]", path, i), {"point", "normal", "material"});
    glm::vec3 n = p.vec3("normal");
    // Divided by its largest component first, so that neither a long normal's
    // squared length overflows nor a short one's underflows.
    float largest = std::max({std::abs(n.x), std::abs(n.y), std::abs(n.z)});
    if (largest == 0.0f) p.fail("\"normal\" must be non-zero");
    scene.planes.push_back({p.vec3("point"), glm::normalize(n / largest), materialIndex(p)});
  }
  if (scene.spheres.empty() && scene.planes.empty()) top.fail("the scene has no spheres and no planes");
  scene.sphereBvh = buildBvh(scene.spheres);
  return scene;
}

}  // namespace

Scene parseScene(const std::string& text, const std::string& path) {
  try {
    return parseSceneText(text, path);
  } catch (const Error& e) {
    // Keys, names and the path come from the user and may hold newlines.
    throw Error(oneLine(e.what()));
  }
}

Scene readSceneFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(oneLine(fmt::format("{}: cannot open scene file ({})", path, std::strerror(errno))));
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error(oneLine(fmt::format("{}: cannot open scene file (is a directory)", path)));
  std::stringstream ss;
  ss << in.rdbuf();
  return parseScene(ss.str(), path);
}

namespace {

void loadEnvironmentFile(Scene& scene) {
  namespace fs = std::filesystem;
  fs::path file = scene.environmentDesc.file;
  if (file.is_relative()) file = fs::path(scene.path).parent_path() / file;
  scene.environmentDesc.file = file.lexically_normal().string();
  const auto t0 = std::chrono::steady_clock::now();
  ImageRGB image = readImage(scene.environmentDesc.file);
  scene.environmentStats =
      sanitizeEnvironmentImage(image, scene.environmentDesc.file, scene.environmentDesc.repairNonFinite);
  scene.environmentStats.loadSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double peak = double(scene.environmentStats.maxTexel) * double(scene.environmentDesc.scale);
  if (peak > kMaxRadiance)
    throw Error(fmt::format("{}: brightest texel {:g} times environment.scale {:g} = {:g} exceeds {:g}",
                            scene.environmentDesc.file, scene.environmentStats.maxTexel,
                            scene.environmentDesc.scale, peak, kMaxRadiance));
  int order = std::countr_zero(unsigned(scene.environmentDesc.nside));
  scene.environment =
      environmentFromEquirect(image, order, scene.environmentDesc.yaw, scene.environmentDesc.scale);
}

}  // namespace

void loadEnvironment(Scene& scene) {
  try {
    loadEnvironmentFile(scene);
  } catch (const Error& e) {
    // The map's path comes from the user and may hold newlines.
    throw Error(oneLine(e.what()));
  }
}

Ray cameraRay(const Camera& c, int width, int height, float px, float py) {
  glm::vec3 w = glm::normalize(c.lookAt - c.position);
  glm::vec3 u = glm::normalize(glm::cross(w, c.up));
  glm::vec3 v = glm::cross(u, w);
  float tanHalf = std::tan(0.5f * c.fovY * kPi / 180.0f);
  float aspect = float(width) / float(height);
  float sx = (2.0f * px / float(width) - 1.0f) * tanHalf * aspect;
  float sy = (1.0f - 2.0f * py / float(height)) * tanHalf;
  return {c.position, glm::normalize(w + sx * u + sy * v)};
}

namespace {

// Ray/sphere with the numerically careful discriminant of Haines et al.
// (Ray Tracing Gems, ch. 7): distances measured from the sphere's centre.
bool hitSphere(const Sphere& s, const Ray& ray, float tMin, float tMax, float& t) {
  glm::vec3 f = ray.origin - s.center;
  float b = -glm::dot(f, ray.dir);
  glm::vec3 l = f + b * ray.dir;
  float disc = s.radius * s.radius - glm::dot(l, l);
  if (disc < 0.0f) return false;
  float c = glm::dot(f, f) - s.radius * s.radius;
  float q = b + std::copysign(std::sqrt(disc), b);
  float t0 = q != 0.0f ? c / q : 0.0f;
  float t1 = q;
  if (t0 > t1) std::swap(t0, t1);
  if (t0 > tMin && t0 < tMax) {
    t = t0;
    return true;
  }
  if (t1 > tMin && t1 < tMax) {
    t = t1;
    return true;
  }
  return false;
}

bool hitPlane(const Plane& p, const Ray& ray, float tMin, float tMax, float& t) {
  float denom = glm::dot(p.normal, ray.dir);
  if (denom == 0.0f) return false;
  float tt = glm::dot(p.point - ray.origin, p.normal) / denom;
  if (!(tt > tMin && tt < tMax)) return false;
  t = tt;
  return true;
}

}  // namespace

namespace {

bool usesBvh(const Scene& scene) {
  return !scene.sphereBvh.nodes.empty() && scene.sphereBvh.spheres == scene.spheres.size();
}

// capSpheres' floors on the sines, pass by pass, a quarter of the one
// before from HT_CAP_FIRST_FLOOR (shaders/common.h); the last, 0, visits
// every box that may rank. A high first floor finds the near spheres first,
// whose k-th sine then prunes the far boxes; halving instead took more
// passes, whose walks over the inner nodes ran past llvmpipe's loop limit
// with 16 caps among 8192 spheres.
constexpr auto kCapFloors = [] {
  std::array<float, HT_CAP_PASSES> floors{};
  for (int p = 0; p + 1 < HT_CAP_PASSES; ++p) floors[size_t(p)] = float(HT_CAP_FIRST_FLOOR) / float(1 << (2 * p));
  return floors;
}();

// An upper bound of capRank's sine for any sphere inside the node's box:
// such a sphere has r <= R, half the box's least extent, and its nearest
// point lies in the box, at least the box's distance D from `origin`, so
// r / d <= R / (R + D); enlarged for rounding.
float capBound(const BvhNode& node, const glm::vec3& origin) {
  const glm::vec3 extent = node.hi - node.lo;
  const float r = 0.5f * std::min({extent.x, extent.y, extent.z});
  const glm::vec3 gap = glm::max(glm::max(node.lo - origin, origin - node.hi), glm::vec3(0.0f));
  const float dist = glm::length(gap);
  if (!(dist > 0.0f)) return 1.0f;
  return std::min(1.0f, r / (r + dist) * 1.001f + 1e-6f);
}

// Visits the BVH's leaves whose boxes the ray enters before `limit()`, in
// depth-first order, the nearer child first; `leaf` returns true to stop.
// A child is tested once when its parent is visited, a pending one again
// when it is taken up (the limit may have shrunk meanwhile).
template <class Limit, class Leaf>
void traverseBvh(const Bvh& bvh, const Ray& ray, Limit limit, Leaf leaf) {
  const glm::vec3 inv = 1.0f / ray.dir;
  uint32_t stack[kBvhMaxDepth];
  int size = 0;
  uint32_t node = 0;
  float enter;
  if (!rayBox(bvh.nodes[0], ray.origin, inv, limit(), enter)) return;
  for (;;) {
    const BvhNode& n = bvh.nodes[node];
    if (n.count > 0) {
      if (leaf(n)) return;
    } else {
      const uint32_t left = node + 1, right = n.first;
      float tl, tr;
      const bool hl = rayBox(bvh.nodes[left], ray.origin, inv, limit(), tl);
      const bool hr = rayBox(bvh.nodes[right], ray.origin, inv, limit(), tr);
      if (hl && hr) {
        node = tl <= tr ? left : right;
        stack[size++] = tl <= tr ? right : left;
        continue;
      }
      if (hl || hr) {
        node = hl ? left : right;
        continue;
      }
    }
    do {
      if (size == 0) return;
      node = stack[--size];
    } while (!rayBox(bvh.nodes[node], ray.origin, inv, limit(), enter));
  }
}

// The linear scan's closest sphere: the least valid root in (tMin, tMax),
// ties to the lower index. `best` is the sphere, or -1.
float closestSphere(const Scene& scene, const Ray& ray, float tMin, float tMax, int& best) {
  float bestT = tMax;
  best = -1;
  float t;
  if (usesBvh(scene)) {
    const Bvh& bvh = scene.sphereBvh;
    traverseBvh(bvh, ray, [&] { return bestT; }, [&](const BvhNode& n) {
      for (uint32_t k = n.first; k < n.first + n.count; ++k) {
        const int i = int(bvh.order[k]);
        if (hitSphere(scene.spheres[size_t(i)], ray, tMin, tMax, t) && (t < bestT || (t == bestT && i < best))) {
          bestT = t;
          best = i;
        }
      }
      return false;
    });
    return bestT;
  }
  for (size_t i = 0; i < scene.spheres.size(); ++i)
    if (hitSphere(scene.spheres[i], ray, tMin, bestT, t)) {
      bestT = t;
      best = int(i);
    }
  return bestT;
}

}  // namespace

bool intersectScene(const Scene& scene, const Ray& ray, float tMin, float tMax, Hit& hit) {
  bool any = false;
  int sphere;
  tMax = closestSphere(scene, ray, tMin, tMax, sphere);
  if (sphere >= 0) {
    const Sphere& s = scene.spheres[size_t(sphere)];
    any = true;
    hit.t = tMax;
    hit.position = ray.origin + tMax * ray.dir;
    hit.normal = glm::normalize(hit.position - s.center);
    hit.material = s.material;
    hit.flat = false;
  }
  float t;
  for (const Plane& p : scene.planes)
    if (hitPlane(p, ray, tMin, tMax, t)) {
      tMax = t;
      any = true;
      hit.t = t;
      hit.position = ray.origin + t * ray.dir;
      hit.normal = p.normal;
      hit.material = p.material;
      hit.flat = true;
    }
  if (any && glm::dot(hit.normal, ray.dir) > 0.0f) hit.normal = -hit.normal;
  return any;
}

bool occluded(const Scene& scene, const glm::vec3& origin, const glm::vec3& dir) {
  Ray ray{origin, dir};
  const float tMax = std::numeric_limits<float>::infinity();
  float t;
  if (usesBvh(scene)) {
    bool blocked = false;
    const Bvh& bvh = scene.sphereBvh;
    traverseBvh(bvh, ray, [&] { return tMax; }, [&](const BvhNode& n) {
      for (uint32_t k = n.first; k < n.first + n.count && !blocked; ++k)
        blocked = hitSphere(scene.spheres[bvh.order[k]], ray, 0.0f, tMax, t);
      return blocked;
    });
    if (blocked) return true;
  } else {
    for (const Sphere& s : scene.spheres)
      if (hitSphere(s, ray, 0.0f, tMax, t)) return true;
  }
  for (const Plane& p : scene.planes)
    if (hitPlane(p, ray, 0.0f, tMax, t)) return true;
  return false;
}

glm::vec3 offsetRayOrigin(const glm::vec3& p, const glm::vec3& n) {
  float scale = 1.0f + std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  return p + n * (1e-4f * scale);
}

bool capRank(const Sphere& s, const glm::vec3& origin, const glm::vec3& normal, float& sine) {
  const glm::vec3 d = s.center - origin;
  const float dist = glm::length(d);
  if (!(dist > 0.0f) || !(glm::dot(d, normal) > -s.radius)) return false;
  sine = std::min(1.0f, s.radius / dist);
  return true;
}

std::vector<uint32_t> capSpheres(const Scene& scene, const glm::vec3& origin, const glm::vec3& normal, size_t k) {
  std::vector<uint32_t> chosen;
  const size_t n = scene.spheres.size();
  if (n <= k) {
    chosen.resize(n);
    std::iota(chosen.begin(), chosen.end(), 0u);
    return chosen;
  }
  if (k == 0) return chosen;
  // The best k so far, best first: a larger sine, then a lower index.
  std::vector<std::pair<float, uint32_t>> best;
  best.reserve(k + 1);
  auto consider = [&](uint32_t i) {
    float sine;
    if (!capRank(scene.spheres[i], origin, normal, sine)) return;
    const std::pair<float, uint32_t> c{sine, i};
    auto before = [](const std::pair<float, uint32_t>& a, const std::pair<float, uint32_t>& b) {
      return a.first > b.first || (a.first == b.first && a.second < b.second);
    };
    if (best.size() == k && !before(c, best.back())) return;
    best.insert(std::upper_bound(best.begin(), best.end(), c, before), c);
    if (best.size() > k) best.pop_back();
  };
  if (usesBvh(scene)) {
    // Passes with a decreasing floor on the sines: a pass visits only boxes
    // that may hold a sphere at or above its floor, so when its k-th best
    // reaches the floor no sphere it skipped could rank (kCapFloors). A
    // leaf whose bound reaches the previous pass's floor was visited then
    // (a box's bound is at most its parent's), or the k-th best passed it.
    const Bvh& bvh = scene.sphereBvh;
    float above = 2.0f;
    for (const float floor : kCapFloors) {
      uint32_t stack[kBvhMaxDepth + 1];
      int size = 0;
      stack[size++] = 0;
      while (size > 0) {
        const BvhNode& node = bvh.nodes[stack[--size]];
        const float least = best.size() == k ? std::max(floor, best.back().first) : floor;
        const float bound = capBound(node, origin);
        if (bound < least) continue;
        if (node.count > 0) {
          if (bound < above)
            for (uint32_t j = node.first; j < node.first + node.count; ++j) consider(bvh.order[j]);
        } else {
          stack[size++] = node.first;
          stack[size++] = uint32_t(&node - bvh.nodes.data()) + 1;
        }
      }
      if (best.size() == k && best.back().first >= floor) break;
      above = floor;
    }
  } else {
    for (uint32_t i = 0; i < uint32_t(n); ++i) consider(i);
  }
  for (const auto& [sine, i] : best) chosen.push_back(i);
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

}  // namespace ht
