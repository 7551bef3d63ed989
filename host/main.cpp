// htrender command line.
#include <unistd.h>

#include <bit>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/info.h>

#include "gpu_render.h"
#include "ht_cut.h"
#include "image_io.h"
#include "memory.h"
#include "output_file.h"
#include "render.h"
#include "scene.h"
#include "system_memory.h"

namespace fs = std::filesystem;
using namespace ht;

namespace {

struct RenderOptions {
  std::string scene = "data/scenes/spheres.json";
  std::string method = "ht-frontier";
  std::string device = "auto";
  int gpuIndex = -1;
  std::string gpuPrecision = "auto";
  std::string out = "out/render.exr";
  std::string stats;
  int spp = 16;
  int width = 0, height = 0;
  uint32_t seed = 1;
  float exposure = 0.0f;
  bool quiet = false;
  bool repairNonFinite = false;
  std::string maxMemory;
  // The methods' options (allMethodOptions) by flag: integers, and choices by name.
  std::map<std::string, int> integers;
  std::map<std::string, std::string> choices;
};

// The methods' options as given (or by default).
MethodOptions methodOptions(const RenderOptions& o) {
  MethodOptions m;
  for (const MethodOption* option : allMethodOptions()) {
    if (option->choices.empty()) {
      option->set(m, o.integers.at(option->flag));
      continue;
    }
    const std::string& name = o.choices.at(option->flag);
    for (size_t i = 0; i < option->choices.size(); ++i)
      if (name == option->choices[i]) option->set(m, int(i));
  }
  return m;
}

double secondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

std::string cpuName() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

// A scene path that does not exist as given is looked up in the source tree,
// so the defaults work from any directory.
std::string resolveScene(const std::string& path) {
  if (fs::exists(path) || fs::path(path).is_absolute()) return path;
  fs::path alt = fs::path(HT_SOURCE_DIR) / path;
  return fs::exists(alt) ? alt.string() : path;
}

// --device gpu: the Vulkan path, or a one-line error. auto: the Vulkan path
// on the best device if it is a GPU; with no loader, no usable device, only
// a CPU Vulkan device (lavapipe), a method the GPU path lacks or a scene it cannot take, the CPU
// reference, and `why` says so.
std::unique_ptr<GpuRenderer> openGpu(const RenderOptions& o, const Scene& scene, Method method, std::string& why) {
  if (!gpuSupportsMethod(method)) {
    if (o.device == "gpu") {
      std::string gpuMethods;
      for (const MethodSpec& m : allMethods())
        if (gpuSupportsMethod(m.method)) gpuMethods += fmt::format("{}{}", gpuMethods.empty() ? "" : ", ", m.name);
      throw Error(fmt::format("--device gpu: method {} runs on the CPU reference only (the GPU path renders {}); "
                              "use --device cpu",
                              methodName(method), gpuMethods));
    }
    why = fmt::format("method {} has no GPU version", methodName(method));
    return nullptr;
  }
  if (const std::string limit = gpuSceneLimit(method, scene); !limit.empty()) {
    if (o.device == "gpu") throw Error(limit);
    why = limit.substr(0, limit.rfind(';'));
    return nullptr;
  }
  try {
    GpuOptions g;
    g.deviceIndex = o.gpuIndex;
    g.precision = o.gpuPrecision == "fp64"   ? GpuPrecision::Fp64
                  : o.gpuPrecision == "fp32" ? GpuPrecision::Fp32
                                             : GpuPrecision::Auto;
    if (o.device == "auto" && o.gpuIndex < 0) {
      std::vector<GpuDeviceInfo> devices = listGpuDevices();
      int best = defaultGpuDevice(devices);
      if (best < 0) {
        why = "no usable Vulkan device";
        return nullptr;
      }
      // A Vulkan device that runs on the CPU (lavapipe) is slower than the
      // CPU reference for every method: only --device gpu uses it.
      if (devices[best].type == "cpu") {
        why = fmt::format("the only Vulkan device, {}, runs on the CPU; --device gpu uses it", devices[best].name);
        return nullptr;
      }
      g.deviceIndex = best;
    }
    return std::make_unique<GpuRenderer>(g);
  } catch (const Error& e) {
    if (o.device == "gpu") throw Error(fmt::format("--device gpu: {}", e.what()));
    why = e.what();
    return nullptr;
  }
}

int runInfo() {
  std::vector<GpuDeviceInfo> devices = listGpuDevices();
  int best = defaultGpuDevice(devices);
  std::printf("Vulkan devices (--gpu-index N picks one; default: discrete > integrated > virtual > cpu):\n");
  for (const GpuDeviceInfo& d : devices) {
    std::printf("  [%u] %s\n", d.index, d.name.c_str());
    std::printf("      type %s, driver %s, Vulkan %s, %.1f GiB device-local\n", d.type.c_str(), d.driver.c_str(),
                d.apiVersion.c_str(), double(d.deviceLocalBytes) / double(1ull << 30));
    std::printf("      features used: scalarBlockLayout, bufferDeviceAddress (required); shaderFloat64 %s; "
                "timestamps %s\n",
                d.shaderFloat64 ? "yes (HEALPix lookups in double)" : "no (single-precision shader)",
                d.timestamps ? fmt::format("yes ({:g} ns)", d.timestampPeriodNs).c_str() : "no");
    std::printf("      limits: storage buffer range %.0f MiB, push constants %u B, subgroup %u\n",
                double(d.maxStorageBufferRange) / double(1 << 20), d.maxPushConstantsSize, d.subgroupSize);
    std::printf("      usable: %s\n", d.usable ? "yes" : ("no, " + d.unusableReason).c_str());
  }
  if (best < 0)
    std::printf("--device gpu: no usable device; --device auto: the CPU reference\n");
  else if (devices[best].type == "cpu")
    std::printf("--device gpu uses [%d] %s; --device auto: the CPU reference (faster than a CPU Vulkan device)\n",
                best, devices[best].name.c_str());
  else
    std::printf("--device gpu and --device auto use [%d] %s\n", best, devices[best].name.c_str());
  return 0;
}

// What the render's memory estimate needs, the map's size from its header.
MemoryInputs memoryInputs(const RenderOptions& o, const Scene& scene, Method method) {
  MemoryInputs mem;
  mem.envOrder = std::countr_zero(unsigned(scene.environmentDesc.nside));
  fs::path file = scene.environmentDesc.file;
  if (file.is_relative()) file = fs::path(scene.path).parent_path() / file;
  readImageSize(file.string(), mem.inputWidth, mem.inputHeight, &mem.inputDecodeBytes);
  mem.method = method;
  mem.options = methodOptions(o);
  mem.width = o.width > 0 ? o.width : scene.width;
  mem.height = o.height > 0 ? o.height : scene.height;
  mem.threads = tbb::info::default_concurrency();
  mem.gpu = o.device == "gpu";
  return mem;
}

struct Seconds {
  double parse, environment, prepare, write, device, upload, gpu;
};

RenderSettings renderSettings(const RenderOptions& o, const Scene& scene, Method method) {
  RenderSettings rs;
  rs.method = method;
  rs.spp = o.spp;
  rs.seed = o.seed;
  rs.width = o.width > 0 ? o.width : scene.width;
  rs.height = o.height > 0 ? o.height : scene.height;
  rs.progress = !o.quiet;
  rs.options = methodOptions(o);
  if (rs.options.cutNodes >= 0 && rs.options.cutNodes < 12)
    throw Error(fmt::format("--cut-nodes {}: -1 (by spp) or 12 to {}", rs.options.cutNodes, HT_CUT_MAX_NODES));
  rs.options = optionsForSpp(rs.options, rs.spp);
  return rs;
}

// The --stats JSON.
nlohmann::json renderStats(const RenderOptions& o, const Scene& scene, const RenderSettings& rs, const RenderResult& r,
                           const GpuRenderer* gpu, const Seconds& t, const MemoryEstimate& memory,
                           uint64_t memoryLimit) {
  double shaded = double(std::max<uint64_t>(r.shadedPixels, 1));
  nlohmann::json stats = {
      {"scene", scene.path},
      {"method", methodName(rs.method)},
      {"spp", rs.spp},
      {"width", rs.width},
      {"height", rs.height},
      {"seed", rs.seed},
      {"device", gpu ? nlohmann::json{{"type", "gpu"}, {"name", gpu->device().name}, {"vulkan_type", gpu->device().type},
                                        {"driver", gpu->device().driver}, {"vulkan", gpu->device().apiVersion},
                                        {"shader", gpu->shaderName()}, {"precision", o.gpuPrecision},
                                        {"texel_views", gpu->texelViews()}}
                     : nlohmann::json{{"type", "cpu"}, {"name", cpuName()}, {"threads", tbb::info::default_concurrency()}}},
      {"environment",
       {{"file", scene.environmentDesc.file},
        {"nside", scene.environment.nside()},
        {"clamped_negative_texels", scene.environmentStats.clampedNegativeTexels},
        {"repaired_nonfinite_texels", scene.environmentStats.repairedNonFiniteTexels}}},
      {"shaded_pixels", r.shadedPixels},
      {"mean_samples_per_pixel", double(r.counters.directions) / shaded},
      {"mean_shadow_rays_per_pixel", double(r.counters.shadowRays) / shaded},
      {"mean_ht_nodes_per_pixel", double(r.counters.htNodes) / shaded},
      {"seconds",
       {{"parse", t.parse}, {"environment", t.environment}, {"prepare", t.prepare}, {"render", r.seconds}, {"write", t.write}}},
      {"outputs", {o.out, fs::path(o.out).replace_extension(".png").string()}},
  };
  for (const MethodOption* option : allMethodOptions()) {
    const int value = option->get(rs.options);
    stats[option->key] = option->choices.empty() ? nlohmann::json(value) : nlohmann::json(option->choices[value]);
  }
  // The environment stage split: file read + checks, HEALPix resampling, max/avg tree.
  stats["seconds"]["scene_bvh"] = scene.sphereBvh.buildSeconds;  // part of "parse"
  stats["seconds"]["environment_load"] = scene.environmentStats.loadSeconds;
  stats["seconds"]["environment_trees"] = scene.environment.treeSeconds;
  stats["seconds"]["environment_resample"] =
      std::max(0.0, t.environment - scene.environmentStats.loadSeconds - scene.environment.treeSeconds);
  if (gpu) {
    stats["seconds"]["device"] = t.device;
    stats["seconds"]["upload"] = t.upload;
    stats["seconds"]["gpu"] = t.gpu >= 0.0 ? nlohmann::json(t.gpu) : nlohmann::json(nullptr);
  }
  nlohmann::json memoryParts = nlohmann::json::object();
  for (const auto& [what, bytes] : memory.parts) memoryParts[what] = bytes;
  stats["memory"] = {{"estimate_bytes", memory.peak()},
                     {"estimate_load_bytes", memory.loadPeak},
                     {"estimate_render_bytes", memory.renderPeak},
                     {"limit_bytes", memoryLimit},
                     {"peak_rss_bytes", peakRssBytes()},
                     {"parts", memoryParts}};
  return stats;
}

int runRender(const RenderOptions& o) {
  auto method = parseMethod(o.method);
  if (!method) {
    std::string names;
    for (const MethodSpec& m : allMethods()) names += std::string(names.empty() ? "" : ", ") + m.name;
    throw Error(fmt::format("unknown method \"{}\" (one of: {})", o.method, names));
  }
  if (o.device == "cpu" && o.gpuIndex >= 0)
    throw Error("--gpu-index picks a Vulkan device: it conflicts with --device cpu");
  if (fs::path(o.out).extension() != ".exr") throw Error(fmt::format("{}: --out must end in .exr", o.out));
  fs::path png = fs::path(o.out).replace_extension(".png");
  const uint64_t memoryLimit = o.maxMemory.empty() ? defaultMemoryLimit() : parseByteSize(o.maxMemory);
  const std::string limitSource =
      o.maxMemory.empty() ? "--max-memory, by default 80% of the available memory" : "--max-memory";
  std::vector<std::pair<std::string, std::string>> outputs = {{"--out", o.out}, {"the PNG preview", png.string()}};
  if (!o.stats.empty()) outputs.emplace_back("--stats", o.stats);
  checkOutputPaths(outputs);
  // Each output is written to a temporary next to it and renamed into place
  // only once all are complete; creating them now proves the directories
  // writable before anything is rendered.
  OutputFile exrFile(o.out), pngFile(png.string());
  std::optional<OutputFile> statsFile;
  if (!o.stats.empty()) statsFile.emplace(o.stats);

  // Bad input is refused before a device is opened (which may compile shaders).
  auto t0 = std::chrono::steady_clock::now();
  Scene scene = readSceneFile(resolveScene(o.scene));
  double tParse = secondsSince(t0);

  // The memory the render will need, before anything large is allocated;
  // the map's size comes from its header (an unreadable map is refused by
  // loadEnvironment with its own message).
  MemoryInputs mem = memoryInputs(o, scene, *method);
  checkMemory(estimateRenderMemory(mem), memoryLimit, limitSource);
  t0 = std::chrono::steady_clock::now();
  scene.environmentDesc.repairNonFinite = o.repairNonFinite;
  loadEnvironment(scene);
  double tEnv = secondsSince(t0);
  if (scene.environmentStats.repairedNonFiniteTexels > 0)
    std::fprintf(stderr, "warning: %s: set %llu NaN/Inf texel value(s) to 0\n", scene.environmentDesc.file.c_str(),
                 (unsigned long long)scene.environmentStats.repairedNonFiniteTexels);
  if (scene.environmentStats.clampedNegativeTexels > 0 && !o.quiet)
    std::fprintf(stderr, "warning: %s: clamped %llu tiny negative texel value(s) to 0\n",
                 scene.environmentDesc.file.c_str(), (unsigned long long)scene.environmentStats.clampedNegativeTexels);

  t0 = std::chrono::steady_clock::now();
  std::string cpuWhy;
  std::unique_ptr<GpuRenderer> gpu = o.device == "cpu" ? nullptr : openGpu(o, scene, *method, cpuWhy);
  double tDevice = secondsSince(t0);
  mem.gpu = gpu != nullptr;
  const MemoryEstimate memory = estimateRenderMemory(mem);
  checkMemory(memory, memoryLimit, limitSource);

  if (!o.quiet && gpu)
    std::fprintf(stderr, "device: gpu %s (%s, Vulkan %s)\n", gpu->device().name.c_str(), gpu->device().type.c_str(),
                 gpu->device().apiVersion.c_str());
  else if (!o.quiet && o.device == "auto")
    std::fprintf(stderr, "device: cpu reference (%s)\n", cpuWhy.c_str());
  const RenderSettings rs = renderSettings(o, scene, *method);
  // One-time tables (HEALPix geometry, BRDF tables) are built here, outside the render timing.
  t0 = std::chrono::steady_clock::now();
  const MethodTables tables = prepareTables(scene, rs.method, rs.options, gpu ? TablesFor::Gpu : TablesFor::Cpu);
  double tPrepare = secondsSince(t0);
  RenderResult r;
  double tUpload = 0.0, tGpu = -1.0;
  nlohmann::json gpuWork;
  if (gpu) {
    t0 = std::chrono::steady_clock::now();
    gpu->setScene(scene);
    gpu->uploadTables(rs, tables);
    tUpload = secondsSince(t0);
    GpuRenderResult g = gpu->render(rs, tables);
    r = std::move(g.result);
    tGpu = g.gpuSeconds;
    gpuWork = {{"readback_seconds", g.readbackSeconds >= 0.0 ? nlohmann::json(g.readbackSeconds) : nlohmann::json(nullptr)},
               {"tiles", g.tiles}, {"tile_width", g.tileWidth}, {"tile_height", g.tileHeight},
               {"submissions", g.submissions}, {"batch_limit", g.batchLimit}, {"restarts", g.restarts}};
  } else {
    r = renderCpu(scene, rs, tables);
  }

  t0 = std::chrono::steady_clock::now();
  writeExr(exrFile, r.image);
  writePng(pngFile, r.image, o.exposure);
  double tWrite = secondsSince(t0);

  const Seconds seconds{tParse, tEnv, tPrepare, tWrite, tDevice, tUpload, tGpu};
  nlohmann::json stats = renderStats(o, scene, rs, r, gpu.get(), seconds, memory, memoryLimit);
  if (gpu) stats["device"]["work"] = gpuWork;
  if (statsFile) {
    const std::string text = stats.dump(2) + "\n";
    writeBytes(*statsFile, text.data(), text.size());
  }
  // All or nothing as far as rename allows: every output is complete before
  // the first replaces its target.
  exrFile.commit();
  pngFile.commit();
  if (statsFile) statsFile->commit();
  if (!o.quiet)
    std::fprintf(stderr, "%s %d spp: %.3f s render, %.2f samples/pixel -> %s, %s\n", methodName(rs.method), rs.spp,
                 r.seconds, stats["mean_samples_per_pixel"].get<double>(), o.out.c_str(), png.string().c_str());
  return 0;
}

void addRenderOptions(CLI::App& r, RenderOptions& o) {
  r.add_option("--scene", o.scene, "scene JSON file")->capture_default_str();
  r.add_option("--method", o.method, "sampling method (see `htrender methods`)")->capture_default_str();
  r.add_option("--spp", o.spp, "samples per pixel")->check(CLI::Range(1, 1 << 20))->capture_default_str();
  r.add_option("--device", o.device, "cpu | gpu | auto")
      ->check(CLI::IsMember({"cpu", "gpu", "auto"}))
      ->capture_default_str();
  r.add_option("--gpu-index", o.gpuIndex, "Vulkan device for --device gpu/auto (see `htrender info`)")
      ->check(CLI::Range(0, 255));
  r.add_option("--gpu-precision", o.gpuPrecision,
               "GPU shader variant: fp32 (the production path), fp64 (bit for bit the CPU reference's samples; "
               "needs shaderFloat64) or auto (fp32; fp64 for wis and tsis, which need it)")
      ->check(CLI::IsMember({"auto", "fp32", "fp64"}))
      ->capture_default_str();
  r.add_option("--width", o.width, "image width (default: the scene's)")->check(CLI::Range(1, 16384));
  r.add_option("--height", o.height, "image height (default: the scene's)")->check(CLI::Range(1, 16384));
  r.add_option("--seed", o.seed, "random seed")->capture_default_str();
  r.add_option("--out", o.out, "output EXR; the PNG preview goes next to it")->capture_default_str();
  r.add_option("--stats", o.stats, "write timings and counts as JSON");
  r.add_option("--exposure", o.exposure, "PNG preview exposure in stops")->capture_default_str();
  // Each method's options (their specs), once per flag.
  const MethodOptions defaults;
  for (const MethodOption* option : allMethodOptions()) {
    if (option->choices.empty()) {
      int& value = o.integers[option->flag] = option->get(defaults);
      r.add_option(option->flag, value, option->help)->check(CLI::Range(option->min, option->max))->capture_default_str();
    } else {
      std::string& value = o.choices[option->flag] = option->choices[option->get(defaults)];
      r.add_option(option->flag, value, option->help)
          ->check(CLI::IsMember(std::vector<std::string>(option->choices.begin(), option->choices.end())))
          ->capture_default_str();
    }
  }
  r.add_flag("--repair-nonfinite", o.repairNonFinite,
                  "set NaN/Inf texels of the environment to 0 with a warning instead of refusing the map");
  r.add_option("--max-memory", o.maxMemory,
                     "refuse renders estimated to need more memory (bytes, or with K, M, G, T; "
                     "default: 80% of the available memory)");
  r.add_flag("--quiet,-q", o.quiet, "no progress or summary on stderr");
}

int runMethods() {
  std::printf("%-14s %-11s %-8s %-4s %s\n", "method", "family", "biased", "gpu", "samples");
  for (const MethodSpec& m : allMethods())
    std::printf("%-14s %-11s %-8s %-4s %s\n", m.name, familyName(m.family), m.biased ? "yes" : "no",
                m.gpu ? (m.gpu->float64 ? "fp64" : "yes") : "no", m.description);
  return 0;
}

int runAverage(const std::vector<std::string>& averageInputs, const std::string& averageOut) {
  checkOutputPaths({{"--out", averageOut}});
  ImageRGB sum;
  for (const std::string& path : averageInputs) {
    ImageRGB img = readImage(path);
    if (sum.pixels.empty()) {
      sum = img;
      continue;
    }
    if (img.width != sum.width || img.height != sum.height)
      throw Error(fmt::format("{}: size {}x{} differs from {}x{}", path, img.width, img.height, sum.width,
                              sum.height));
    for (size_t i = 0; i < sum.pixels.size(); ++i) sum.pixels[i] += img.pixels[i];
  }
  for (glm::vec3& p : sum.pixels) p /= float(averageInputs.size());
  writeExr(averageOut, sum);
  return 0;
}

int runExport(const std::string& exportIn, const std::string& exportOut) {
  checkOutputPaths({{"--out", exportOut}});
  OutputFile out(exportOut);
  ImageRGB img = readImage(exportIn);
  std::string pfm = fmt::format("PF\n{} {}\n-1.0\n", img.width, img.height);
  const size_t header = pfm.size(), row = sizeof(glm::vec3) * size_t(img.width);
  pfm.resize(header + row * size_t(img.height));
  for (int y = img.height - 1; y >= 0; --y)  // PFM rows run bottom to top
    std::memcpy(&pfm[header + row * size_t(img.height - 1 - y)], &img.at(0, y), row);
  writeBytes(out, pfm.data(), pfm.size());
  out.commit();
  return 0;
}

int runCompare(const std::string& refPath, const std::string& testPath) {
  ImageRGB ref = readImage(refPath), test = readImage(testPath);
  if (ref.width != test.width || ref.height != test.height)
    throw Error(fmt::format("{}: size {}x{} differs from the reference's {}x{}", testPath, test.width,
                            test.height, ref.width, ref.height));
  ImageError e = compareImages(ref, test);
  nlohmann::json j = {{"rmse", e.rmse}, {"relmse", e.relMse}, {"mean_abs_rel_error", e.meanAbsRelError},
                      {"luminance_relmse", e.luminanceRelMse}, {"pixels", e.pixels}};
  std::printf("%s\n", j.dump().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"htrender: product importance sampling of environment lighting by hierarchical thresholding"};
  app.require_subcommand(1);

  RenderOptions o;
  CLI::App* render = app.add_subcommand("render", "render a scene to EXR + PNG preview");
  addRenderOptions(*render, o);

  CLI::App* methods = app.add_subcommand("methods", "list the sampling methods");
  CLI::App* info = app.add_subcommand("info", "list the Vulkan devices and the features the GPU path uses");

  app.set_version_flag("--version", "htrender " HT_VERSION);

  std::vector<std::string> averageInputs;
  std::string averageOut;
  CLI::App* average = app.add_subcommand("average", "mean of several EXR (or .hdr) images of the same size");
  average->add_option("inputs", averageInputs, "EXR or .hdr files")->required();
  average->add_option("--out", averageOut, "output EXR")->required();

  std::string exportIn, exportOut;
  CLI::App* exportCmd = app.add_subcommand("export", "write an EXR (or .hdr) as PFM (little-endian float RGB), for scripts");
  exportCmd->add_option("input", exportIn, "EXR or .hdr file")->required();
  exportCmd->add_option("--out", exportOut, "PFM file")->required();

  std::string refPath, testPath;
  CLI::App* compare = app.add_subcommand("compare", "error of an image against a reference, as JSON");
  compare->add_option("--ref", refPath, "reference EXR or .hdr")->required();
  compare->add_option("--test", testPath, "EXR or .hdr to measure")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "htrender: error: %s (see --help)\n", e.what());
    return e.get_exit_code() != 0 ? e.get_exit_code() : 1;
  }
  removeOutputsOnSignals();
  try {
    if (*info) return runInfo();
    if (*methods) return runMethods();
    if (*average) return runAverage(averageInputs, averageOut);
    if (*exportCmd) return runExport(exportIn, exportOut);
    if (*compare) return runCompare(refPath, testPath);
    return runRender(o);
  } catch (const Error& e) {
    std::fprintf(stderr, "htrender: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "htrender: internal error: %s\n", e.what());
    return 2;
  }
}
