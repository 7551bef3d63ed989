#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "error.h"
#include "scene.h"

using namespace ht;

namespace {

const char* kMinimal = R"({
  "camera": {"position": [0, 1, 5], "look_at": [0, 0, 0]},
  "environment": {"file": "sky.exr"},
  "materials": {"m": {"type": "lambert", "albedo": 0.5}},
  "spheres": [{"center": [0, 0, 0], "radius": 1, "material": "m"}]
})";

// Replaces the first occurrence of `from` in the minimal scene.
std::string edit(const std::string& from, const std::string& to) {
  std::string s = kMinimal;
  auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

std::string errorOf(const std::string& text) {
  try {
    parseScene(text, "s.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Scene, ShippedScenesParse) {
  for (const char* name : {"spheres.json", "furnace.json"}) {
    Scene s = readSceneFile(std::string(HT_TEST_DATA) + "/scenes/" + name);
    EXPECT_FALSE(s.spheres.empty()) << name;
  }
  Scene s = readSceneFile(std::string(HT_TEST_DATA) + "/scenes/spheres.json");
  EXPECT_EQ(s.planes.size(), 1u);
  EXPECT_EQ(s.environmentDesc.nside, 256);
  bool mirrorLike = false;
  for (const Material& m : s.materials) mirrorLike |= m.type == MaterialType::Ggx && m.alpha <= 0.02f;
  EXPECT_TRUE(mirrorLike);
}

TEST(Scene, MinimalDefaults) {
  Scene s = parseScene(kMinimal, "s.json");
  EXPECT_EQ(s.environmentDesc.nside, 256);
  EXPECT_EQ(s.environmentDesc.scale, 1.0f);
  EXPECT_EQ(s.materials[0].diffuse, glm::vec3(0.5f));
}

TEST(Scene, ErrorsNameTheProblem) {
  struct Case {
    std::string text, expect;
  };
  const Case cases[] = {
      {edit("\"m\"}]", "\"m\"}"), "line 6, column 1"},
      {edit("\"radius\": 1", "\"radius\": -1"), "spheres[0]: \"radius\" = -1 is out of range"},
      {edit("\"radius\": 1", "\"radius\": \"big\""), "\"radius\" must be a number"},
      {edit("\"radius\": 1", "\"radius\": 1, \"colour\": 3"), "unknown key \"colour\""},
      {edit("\"albedo\": 0.5", "\"albedo\": 0.5, \"alpha\": 2"), "unknown key \"alpha\""},
      {edit("\"type\": \"lambert\", \"albedo\": 0.5", "\"type\": \"ggx\", \"alpha\": 0, \"f0\": 0.04"),
       "\"alpha\" = 0 is out of range (0, 1]"},
      {edit("\"type\": \"lambert\", \"albedo\": 0.5", "\"type\": \"ggx\", \"alpha\": 1.5, \"f0\": 0.04"),
       "\"alpha\" = 1.5 is out of range"},
      {edit("\"type\": \"lambert\", \"albedo\": 0.5", "\"type\": \"ggx\", \"alpha\": 0.5"),
       "exactly one of \"f0\" and \"conductor\""},
      {edit("\"type\": \"lambert\"", "\"type\": \"velvet\""), "unknown material type \"velvet\""},
      {edit("\"file\": \"sky.exr\"", "\"file\": \"sky.exr\", \"nside\": 100"), "not a power of two"},
      {edit("\"file\": \"sky.exr\"", "\"file\": \"sky.exr\", \"nside\": 16384"), "out of range"},
      {edit("\"look_at\": [0, 0, 0]", "\"look_at\": [0, 1, 5]"), "position and look_at coincide"},
      {edit("\"look_at\": [0, 0, 0]", "\"look_at\": [0, 0, 0], \"up\": [0, -1, -5]"), "not parallel"},
      {edit("\"environment\": {\"file\": \"sky.exr\"},", ""), "missing key \"environment\""},
      {edit("\"material\": \"m\"", "\"material\": \"n\""), "unknown material \"n\""},
      {edit("\"center\": [0, 0, 0]", "\"center\": [0, 0]"), "array of 3 numbers"},
      {edit("\"albedo\": 0.5", "\"albedo\": [0.5, 2, 0.5]"), "must lie in [0, 1]"},
      {edit("\"spheres\": [{\"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\"}]", "\"spheres\": []"),
       "no spheres and no planes"},
      {edit("\"spheres\"", "\"planes\": [{\"point\": [0, 0, 0], \"normal\": [0, 0, 0], \"material\": \"m\"}], \"spheres\""),
       "\"normal\" must be non-zero"},
  };
  for (const Case& c : cases) {
    std::string msg = errorOf(c.text);
    EXPECT_NE(msg.find(c.expect), std::string::npos) << "expected \"" << c.expect << "\" in \"" << msg << "\"";
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind("s.json", 0), 0u) << msg;
  }
}

// A normal is a direction whatever its length, even one whose squared length
// overflows or underflows single precision.
TEST(Scene, PlaneNormalsOfAnyLengthAreUnit) {
  for (const char* normal : {"[3e30, 4e30, 0]", "[3e-30, 4e-30, 0]", "[0, 3, 4]"}) {
    Scene s = parseScene(edit("\"spheres\"", std::string("\"planes\": [{\"point\": [0, 0, 0], \"normal\": ") +
                                                normal + ", \"material\": \"m\"}], \"spheres\""),
                         "s.json");
    ASSERT_EQ(s.planes.size(), 1u);
    glm::vec3 n = s.planes[0].normal;
    EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f) << normal;
    EXPECT_NEAR(std::max(n.x, std::max(n.y, n.z)), 0.8f, 1e-6f) << normal;
  }
}

TEST(Scene, IntersectionAndOcclusion) {
  Scene s = parseScene(kMinimal, "s.json");
  s.planes.push_back({glm::vec3(0, -1, 0), glm::vec3(0, 1, 0), 0});
  Hit hit;
  ASSERT_TRUE(intersectScene(s, {glm::vec3(0, 0, 5), glm::vec3(0, 0, -1)}, 0.0f, INFINITY, hit));
  EXPECT_NEAR(hit.t, 4.0f, 1e-5f);
  EXPECT_NEAR(glm::distance(hit.normal, glm::vec3(0, 0, 1)), 0.0f, 1e-6f);
  ASSERT_TRUE(intersectScene(s, {glm::vec3(3, 0, 0), glm::normalize(glm::vec3(0, -1, -1))}, 0.0f, INFINITY, hit));
  EXPECT_NEAR(hit.position.y, -1.0f, 1e-5f);
  EXPECT_EQ(hit.normal, glm::vec3(0, 1, 0));
  EXPECT_FALSE(intersectScene(s, {glm::vec3(3, 0, 0), glm::vec3(0, 1, 0)}, 0.0f, INFINITY, hit));
  // From the top of the sphere, upward is free, down is blocked by the sphere itself.
  glm::vec3 top = offsetRayOrigin(glm::vec3(0, 1, 0), glm::vec3(0, 1, 0));
  EXPECT_FALSE(occluded(s, top, glm::vec3(0, 1, 0)));
  EXPECT_TRUE(occluded(s, glm::vec3(0, 3, 0), glm::vec3(0, -1, 0)));
  // A point on the plane beside the sphere sees the sphere towards it.
  glm::vec3 ground = offsetRayOrigin(glm::vec3(2, -1, 0), glm::vec3(0, 1, 0));
  EXPECT_TRUE(occluded(s, ground, glm::normalize(glm::vec3(-2, 1, 0))));
  EXPECT_FALSE(occluded(s, ground, glm::normalize(glm::vec3(2, 1, 0))));
}

TEST(Scene, CameraRayThroughCentreLooksAtTarget) {
  Camera c;
  c.position = glm::vec3(1, 2, 3);
  c.lookAt = glm::vec3(0, 0, 0);
  Ray r = cameraRay(c, 64, 32, 32.0f, 16.0f);
  EXPECT_NEAR(glm::distance(r.dir, glm::normalize(-c.position)), 0.0f, 1e-6f);
  Ray corner = cameraRay(c, 64, 32, 0.0f, 0.0f);
  float halfDiag = std::atan(std::tan(0.5f * c.fovY * 3.14159265f / 180.0f) * std::sqrt(1.0f + 4.0f));
  EXPECT_NEAR(std::acos(glm::dot(corner.dir, r.dir)), halfDiag, 1e-5f);
}
