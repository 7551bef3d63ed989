// The one list of the methods: each spec is defined in its family's file
// in this folder, and listed here in the order of the methods' numbers
// (shaders/common.h).
#include <array>

#include <fmt/format.h>

#include "error.h"
#include "method.h"

namespace ht {

extern const MethodSpec kUniform, kCosine, kEnv, kBrdf, kMis, kHt, kHtVis, kHtBiased, kHtVisBiased, kOracle, kWis,
    kWisBiased, kTsis, kRis, kHtFrontier, kMisCompensated, kRestir, kRestirBiased, kHtCut;

namespace {

const std::array kRegistry = {&kUniform, &kCosine, &kEnv, &kBrdf, &kMis, &kHt, &kHtVis, &kHtBiased, &kHtVisBiased,
                              &kOracle, &kWis, &kWisBiased, &kTsis, &kRis, &kHtFrontier, &kMisCompensated,
                              &kRestir, &kRestirBiased, &kHtCut};

constexpr const char* kSamplerChoices[] = {"stratified", "independent"};
const MethodOption kSampler{
    "--sampler", "sampler",
    "per-pixel sample points: Owen-scrambled Sobol' (0,2)-sequences per decision (stratified) or i.i.d. "
    "(independent); HT's candidates keep their own sequence",
    kSamplerChoices, 0, 0, [](const MethodOptions& o) { return o.sampler == SamplerKind::Stratified ? 0 : 1; },
    [](MethodOptions& o, int v) { o.sampler = v == 0 ? SamplerKind::Stratified : SamplerKind::Independent; }};

// The specs by value, checked against their numbers once.
const std::vector<MethodSpec>& registry() {
  static const std::vector<MethodSpec> specs = [] {
    std::vector<MethodSpec> v;
    for (const MethodSpec* s : kRegistry) {
      if (size_t(s->method) != v.size())
        throw Error(fmt::format("internal: method {} listed out of its number's order", s->name));
      v.push_back(*s);
    }
    return v;
  }();
  return specs;
}

}  // namespace

std::span<const MethodSpec> allMethods() { return registry(); }

const MethodSpec& methodSpec(Method m) {
  if (size_t(m) >= registry().size()) throw Error(fmt::format("internal: no method numbered {}", uint32_t(m)));
  return registry()[size_t(m)];
}

std::optional<Method> parseMethod(std::string_view name) {
  for (const MethodSpec& m : registry())
    if (name == m.name) return m.method;
  return std::nullopt;
}

const char* methodName(Method m) { return methodSpec(m).name; }

const char* familyName(Family f) {
  switch (f) {
    case Family::Baseline: return "baseline";
    case Family::Ht: return "ht (seed)";
    case Family::Oracle: return "oracle";
    case Family::Competitor: return "competitor";
    case Family::Product: return "product";
    case Family::Reuse: return "reuse";
  }
  return "?";
}

std::span<const MethodOption* const> allMethodOptions() {
  static const std::vector<const MethodOption*> options = [] {
    std::vector<const MethodOption*> v;
    for (const MethodSpec& m : registry())
      for (const MethodOption& o : m.options) {
        bool seen = false;
        for (const MethodOption* p : v) seen = seen || std::string_view(p->flag) == o.flag;
        if (!seen) v.push_back(&o);
      }
    v.push_back(&kSampler);
    return v;
  }();
  return options;
}

}  // namespace ht
