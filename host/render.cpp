#include "render.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "ht_cut.h"

namespace ht {

MethodOptions optionsForSpp(MethodOptions options, int spp) {
  options.cutNodes = cutNodesFor(options.cutNodes, spp);
  return options;
}

RenderResult renderCpu(const Scene& scene, const RenderSettings& s) {
  const auto start = std::chrono::steady_clock::now();
  const MethodTables tables = prepareTables(scene, s.method, optionsForSpp(s.options, s.spp));
  RenderResult result = renderCpu(scene, s, tables);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

RenderResult renderCpu(const Scene& scene, const RenderSettings& s, const MethodTables& tables) {
  auto start = std::chrono::steady_clock::now();
  RenderResult result;
  result.image.width = s.width;
  result.image.height = s.height;
  result.image.pixels.assign(size_t(s.width) * s.height, glm::vec3(0.0f));
  if (s.pixelCounts) result.pixelDirections.assign(size_t(s.width) * s.height, 0);
  if (const auto renderImage = methodSpec(s.method).renderImage) {
    renderImage(scene, s, result);
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  }

  struct Local {
    EstimateCounters counters;
    uint64_t shaded = 0;
  };
  tbb::combinable<Local> locals;
  std::atomic<int> rowsDone{0};
  std::mutex progressMutex;
  int lastReported = -1;

  tbb::parallel_for(tbb::blocked_range<int>(0, s.height), [&](const tbb::blocked_range<int>& rows) {
    Local& local = locals.local();
    for (int y = rows.begin(); y != rows.end(); ++y) {
      for (int x = 0; x < s.width; ++x) {
        Ray ray = cameraRay(scene.camera, s.width, s.height, x + 0.5f, y + 0.5f);
        Hit hit;
        glm::vec3& out = result.image.at(x, y);
        if (!intersectScene(scene, ray, 0.0f, INFINITY, hit)) {
          out = scene.environment.eval(ray.dir);
          continue;
        }
        ShadingPoint sp{hit.position, hit.normal, -ray.dir, &scene.materials[hit.material], hit.flat};
        Rng rng(s.seed, pixelStream(x, y, s.width));
        const uint64_t before = local.counters.directions;
        out = estimateDirect(scene, sp, s.method, s.spp, rng, local.counters, tables, s.options);
        if (s.pixelCounts) result.pixelDirections[size_t(y) * s.width + x] = uint32_t(local.counters.directions - before);
        ++local.shaded;
      }
      int done = ++rowsDone;
      if (s.progress) {
        int percent = int(100.0 * done / s.height);
        std::lock_guard lock(progressMutex);
        if (percent / 10 > lastReported / 10 || done == s.height) {
          lastReported = percent;
          std::fprintf(stderr, "\rrender: %3d%%%s", percent, done == s.height ? "\n" : "");
          std::fflush(stderr);
        }
      }
    }
  });

  locals.combine_each([&](const Local& l) {
    result.counters.directions += l.counters.directions;
    result.counters.shadowRays += l.counters.shadowRays;
    result.counters.htNodes += l.counters.htNodes;
    result.shadedPixels += l.shaded;
  });
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace ht
