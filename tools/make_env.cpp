// make_env: writes synthetic equirectangular environment maps (float RGB EXR)
// with known integrals, for tests and stress scenes.
//
// Equirectangular convention, shared with the renderer:
//   world is y-up; pixel (x, y) with x in [0, W), y in [0, H), row 0 on top;
//   u = (x + 0.5) / W, v = (y + 0.5) / H;
//   theta = v * pi      angle from +y (the zenith);
//   phi   = u * 2 * pi  azimuth;
//   direction = (sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi)),
//   so phi = 0 looks along -z and phi = 90 degrees along +x.
// Row y covers theta in [y pi / H, (y + 1) pi / H], so each of its texels
// subtends exactly (2 pi / W) * (cos(theta0) - cos(theta1)) steradians.
// Command-line angles (--theta, --phi, --sun-radius-deg) are in degrees.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "image_io.h"

namespace {

constexpr double kPi = 3.14159265358979323846;

using Vec3d = glm::dvec3;

Vec3d direction(double theta, double phi) {
  return {std::sin(theta) * std::sin(phi), std::cos(theta), -std::sin(theta) * std::cos(phi)};
}

double texelSolidAngle(int y, int width, int height) {
  return 2.0 * kPi / width * (std::cos(kPi * y / height) - std::cos(kPi * (y + 1) / height));
}

// Fraction of row y's solid angle above the horizon. Whole rows are decided
// in integers (cos(pi/2) is not 0 in floating point); only the middle row of
// an odd height straddles the horizon and is split by solid angle.
double upperFraction(int y, int height) {
  if (2 * (y + 1) <= height) return 1.0;
  if (2 * y >= height) return 0.0;
  const double c0 = std::cos(kPi * y / height), c1 = std::cos(kPi * (y + 1) / height);
  return c0 / (c0 - c1);
}

// Options shared by every kind of map.
struct Common {
  int width = 256;
  int height = 128;
  std::string out;
};

void addCommon(CLI::App* cmd, Common& c) {
  cmd->add_option("--width", c.width, "image width in pixels (1.." + std::to_string(ht::kMaxImageDimension) + ")")
      ->capture_default_str();
  cmd->add_option("--height", c.height, "image height in pixels (1.." + std::to_string(ht::kMaxImageDimension) + ")")
      ->capture_default_str();
  cmd->add_option("--out", c.out, "output EXR file")->required();
}

void checkCommon(const Common& c) {
  const int maxDim = ht::kMaxImageDimension;
  if (c.width < 1 || c.width > maxDim || c.height < 1 || c.height > maxDim)
    throw ht::Error("--width and --height must be in 1.." + std::to_string(maxDim) + ", got " +
                    std::to_string(c.width) + "x" + std::to_string(c.height));
  if ((long long)c.width * c.height > (1ll << 28))
    throw ht::Error("image of " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                    " pixels exceeds 2^28 pixels, which readers refuse");
}

// A colour option given as one grey value or three RGB values.
CLI::Option* addColour(CLI::App* cmd, const std::string& name, std::vector<double>& v, const std::string& help) {
  CLI::Option* opt = cmd->add_option(name, v, help + " (one value or R G B)")->expected(1, 3);
  return v.empty() ? opt : opt->capture_default_str();
}

Vec3d toColour(const std::string& name, const std::vector<double>& v) {
  if (v.size() != 1 && v.size() != 3) throw ht::Error(name + " takes one value or three (R G B)");
  const Vec3d c = v.size() == 1 ? Vec3d(v[0]) : Vec3d(v[0], v[1], v[2]);
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(c[i]) || c[i] < 0.0) throw ht::Error(name + " must be finite and non-negative");
  return c;
}

double checkNonNegative(const std::string& name, double v) {
  if (!std::isfinite(v) || v < 0.0) throw ht::Error(name + " must be finite and non-negative");
  return v;
}

double checkTheta(double thetaDeg) {
  if (!(thetaDeg >= 0.0 && thetaDeg <= 180.0)) throw ht::Error("--theta must be in [0, 180] degrees");
  return thetaDeg * kPi / 180.0;
}

ht::ImageRGB blank(const Common& c) {
  ht::ImageRGB img;
  img.width = c.width;
  img.height = c.height;
  img.pixels.assign(size_t(c.width) * c.height, glm::vec3(0.0f));
  return img;
}

// Sky above the horizon, ground below, blended exactly on a straddling row.
ht::ImageRGB hemispheres(const Common& c, Vec3d upper, Vec3d lower) {
  ht::ImageRGB img = blank(c);
  for (int y = 0; y < c.height; ++y) {
    const double f = upperFraction(y, c.height);
    const glm::vec3 v(f * upper + (1.0 - f) * lower);
    for (int x = 0; x < c.width; ++x) img.at(x, y) = v;
  }
  return img;
}

// Paints a disc of angular radius `radius` around `centre` with `radiance`,
// weighting each texel by the fraction of its solid angle inside the disc, so
// the disc's integral is right even when it spans only a few texels.
// Returns the disc power that landed in the image.
double paintDisc(ht::ImageRGB& img, Vec3d centre, double radius, Vec3d radiance) {
  const int w = img.width, h = img.height;
  const double cosRadius = std::cos(radius);
  // Every point of a texel is within half its theta extent plus its full phi
  // extent of the texel centre; anything farther cannot touch the disc.
  const double reach = radius + kPi / h + 2.0 * kPi / w;
  constexpr int n = 64;  // n x n stratified samples, uniform in solid angle
  double power = 0.0;
  for (int y = 0; y < h; ++y) {
    const double c0 = std::cos(kPi * y / h), c1 = std::cos(kPi * (y + 1) / h);
    for (int x = 0; x < w; ++x) {
      const Vec3d mid = direction(kPi * (y + 0.5) / h, 2.0 * kPi * (x + 0.5) / w);
      if (std::acos(std::clamp(glm::dot(mid, centre), -1.0, 1.0)) > reach) continue;
      int inside = 0;
      for (int i = 0; i < n; ++i) {
        const double z = c0 + (c1 - c0) * (i + 0.5) / n;
        const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
        for (int j = 0; j < n; ++j) {
          const double phi = 2.0 * kPi * (x + (j + 0.5) / n) / w;
          inside += glm::dot(Vec3d(s * std::sin(phi), z, -s * std::cos(phi)), centre) >= cosRadius;
        }
      }
      if (inside == 0) continue;
      const double f = double(inside) / (n * n);
      const Vec3d before(img.at(x, y));
      img.at(x, y) = glm::vec3((1.0 - f) * before + f * radiance);
      power += f * radiance.x * texelSolidAngle(y, w, h);
    }
  }
  return power;
}

void save(const std::string& path, const ht::ImageRGB& img) {
  ht::writeExr(path, img);
  std::printf("wrote %s (%dx%d)\n", path.c_str(), img.width, img.height);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Writes synthetic equirectangular environment maps as float RGB OpenEXR.\n"
      "Convention: y-up; pixel (x,y) -> u=(x+0.5)/W, v=(y+0.5)/H, theta=v*180 deg from +y (zenith),\n"
      "phi=u*360 deg; direction = (sin(theta)sin(phi), cos(theta), -sin(theta)cos(phi)).",
      "make_env"};
  app.require_subcommand(1);
  app.footer(
      "Examples:\n"
      "  make_env constant --value 1 --width 64 --height 32 --out constant.exr\n"
      "  make_env sun --power 10 --theta 40 --phi 30 --background 0.05 --out sun.exr\n"
      "  make_env sky-sun --sky 0.4 0.6 1.0 --ground 0.1 --sun-radiance 20000 --sun-radius-deg 1 \\\n"
      "      --theta 50 --phi 120 --out sky-sun.exr\n"
      "  make_env black-hemisphere --value 1 --width 64 --height 32 --out hemisphere.exr\n"
      "Run 'make_env SUBCOMMAND --help' for the options of each map.");

  Common common;
  std::vector<double> value{1.0}, color{1.0}, background{0.0}, sky, ground{0.0};
  double power = 1.0, thetaDeg = 0.0, phiDeg = 0.0, sunRadiance = 0.0, sunRadiusDeg = 0.5;

  CLI::App* constant = app.add_subcommand("constant", "uniform radiance everywhere");
  addColour(constant, "--value", value, "radiance");
  addCommon(constant, common);

  CLI::App* sun = app.add_subcommand(
      "sun", "one texel holds a sun of the given power (radiance x texel solid angle); all else background");
  sun->add_option("--power", power, "radiance x solid angle of the sun texel")->required();
  sun->add_option("--theta", thetaDeg, "sun angle from the zenith, degrees [0, 180]")->required();
  sun->add_option("--phi", phiDeg, "sun azimuth, degrees")->required();
  addColour(sun, "--color", color, "sun colour, multiplies --power");
  addColour(sun, "--background", background, "radiance of every other texel");
  addCommon(sun, common);

  CLI::App* skySun = app.add_subcommand(
      "sky-sun", "constant sky over constant ground, plus a sun disc (texels weighted by disc coverage)");
  addColour(skySun, "--sky", sky, "radiance of the upper hemisphere")->required();
  addColour(skySun, "--ground", ground, "radiance of the lower hemisphere");
  skySun->add_option("--sun-radiance", sunRadiance, "radiance inside the sun disc")->required();
  skySun->add_option("--sun-radius-deg", sunRadiusDeg, "angular radius of the disc, degrees (0, 90]")
      ->capture_default_str();
  skySun->add_option("--theta", thetaDeg, "disc centre angle from the zenith, degrees [0, 180]")->required();
  skySun->add_option("--phi", phiDeg, "disc centre azimuth, degrees")->required();
  addColour(skySun, "--color", color, "sun colour, multiplies --sun-radiance");
  addCommon(skySun, common);

  CLI::App* blackHemi = app.add_subcommand("black-hemisphere", "upper hemisphere constant, lower hemisphere black");
  addColour(blackHemi, "--value", value, "radiance of the upper hemisphere");
  addCommon(blackHemi, common);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    std::fprintf(stderr, "make_env: error: %s (see --help)\n", e.what());
    return 2;
  }

  try {
    checkCommon(common);
    if (constant->parsed()) {
      const Vec3d v = toColour("--value", value);
      save(common.out, hemispheres(common, v, v));
    } else if (blackHemi->parsed()) {
      save(common.out, hemispheres(common, toColour("--value", value), Vec3d(0.0)));
    } else if (sun->parsed()) {
      const double theta = checkTheta(thetaDeg);
      checkNonNegative("--power", power);
      if (!std::isfinite(phiDeg)) throw ht::Error("--phi must be finite");
      const Vec3d bg = toColour("--background", background), col = toColour("--color", color);
      ht::ImageRGB img = hemispheres(common, bg, bg);
      // The texel containing the direction; phi wraps, theta = 180 is the last row.
      const double u = phiDeg / 360.0 - std::floor(phiDeg / 360.0);
      const int x = std::min(int(u * common.width), common.width - 1);
      const int y = std::min(int(theta / kPi * common.height), common.height - 1);
      const double omega = texelSolidAngle(y, common.width, common.height);
      img.at(x, y) = glm::vec3(col * (power / omega));
      std::printf("sun texel (%d, %d), solid angle %.6g sr, radiance %.6g\n", x, y, omega, power / omega);
      save(common.out, img);
    } else if (skySun->parsed()) {
      const double theta = checkTheta(thetaDeg);
      checkNonNegative("--sun-radiance", sunRadiance);
      if (!(sunRadiusDeg > 0.0 && sunRadiusDeg <= 90.0)) throw ht::Error("--sun-radius-deg must be in (0, 90]");
      if (!std::isfinite(phiDeg)) throw ht::Error("--phi must be finite");
      ht::ImageRGB img = hemispheres(common, toColour("--sky", sky), toColour("--ground", ground));
      const double radius = sunRadiusDeg * kPi / 180.0;
      const double got = paintDisc(img, direction(theta, phiDeg * kPi / 180.0), radius,
                                   toColour("--color", color) * sunRadiance);
      const double exact = toColour("--color", color).x * sunRadiance * 2.0 * kPi * (1.0 - std::cos(radius));
      std::printf("sun disc power (red): %.6g in image, %.6g exact\n", got, exact);
      save(common.out, img);
    }
  } catch (const ht::Error& e) {
    std::fprintf(stderr, "make_env: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
