// The method registry: every spec in its number's place, complete, with
// options whose defaults the command line can show and set.
#include <filesystem>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "memory.h"
#include "method.h"

namespace ht {
namespace {

TEST(Methods, RegistryHoldsEveryNumberOnceInOrder) {
  std::set<std::string> names;
  for (size_t i = 0; i < allMethods().size(); ++i) {
    const MethodSpec& m = allMethods()[i];
    EXPECT_EQ(size_t(m.method), i) << m.name;
    EXPECT_TRUE(names.insert(m.name).second) << "two methods named " << m.name;
    EXPECT_EQ(parseMethod(m.name), m.method);
    EXPECT_EQ(&methodSpec(m.method), &m);
    EXPECT_TRUE((m.estimate != nullptr) != (m.renderImage != nullptr)) << m.name;
    EXPECT_GE(m.directionsPerSample, 1) << m.name;
  }
  // The shaders' numbers: the last one names the registry's size.
  EXPECT_EQ(allMethods().size(), size_t(HT_METHOD_HT_CUT) + 1);
  EXPECT_FALSE(parseMethod("no-such-method"));
}

TEST(Methods, GpuMethodsNameTheirFamilyShader) {
  for (const MethodSpec& m : allMethods()) {
    if (!m.gpu) continue;
    const std::filesystem::path shader =
        std::filesystem::path(HT_SOURCE_DIR) / "shaders" / (std::string(m.gpu->shader) + ".comp.glsl");
    EXPECT_TRUE(std::filesystem::exists(shader)) << m.name << ": " << shader;
    EXPECT_GE(m.gpu->stepsPerSample, 1u) << m.name;
  }
}

TEST(Methods, OptionsHaveOneFlagAndDefaultsTheyCanSet) {
  std::set<std::string> flags, keys;
  const MethodOptions defaults;
  for (const MethodOption* o : allMethodOptions()) {
    EXPECT_TRUE(flags.insert(o->flag).second) << o->flag;
    EXPECT_TRUE(keys.insert(o->key).second) << o->key;
    const int value = o->get(defaults);
    if (o->choices.empty()) {
      EXPECT_LE(o->min, value) << o->flag;
      EXPECT_LE(value, o->max) << o->flag;
      for (int v : {o->min, o->max}) {
        MethodOptions m;
        o->set(m, v);
        EXPECT_EQ(o->get(m), v) << o->flag;
      }
    } else {
      EXPECT_GE(value, 0) << o->flag;
      EXPECT_LT(size_t(value), o->choices.size()) << o->flag;
      for (int v = 0; v < int(o->choices.size()); ++v) {
        MethodOptions m;
        o->set(m, v);
        EXPECT_EQ(o->get(m), v) << o->flag << " " << o->choices[size_t(v)];
      }
    }
  }
  // Every method's options are among them.
  for (const MethodSpec& m : allMethods())
    for (const MethodOption& o : m.options) EXPECT_TRUE(flags.count(o.flag)) << m.name << " " << o.flag;
  EXPECT_TRUE(flags.count("--sampler"));
}

// A method's tables and buffers are in the render's estimate: on the GPU
// path it counts the method's part of the buffers, which only a method with
// its own tables adds.
TEST(Methods, MemoryEstimateCountsTheMethodsTables) {
  MemoryInputs in;
  in.envOrder = 8;
  in.width = 64;
  in.height = 32;
  in.method = Method::Mis;
  const uint64_t mis = estimateRenderMemory(in).renderPeak;
  for (const MethodSpec& m : allMethods()) {
    in.method = m.method;
    const uint64_t peak = estimateRenderMemory(in).renderPeak;
    if (m.memory)
      EXPECT_GT(peak, mis) << m.name;
    else
      EXPECT_EQ(peak, mis) << m.name;
  }
}

}  // namespace
}  // namespace ht
