// The benchmark scenes of docs/benchmark-scenes.md as data: presets (mesh, IoR, absorption,
// environment, views) and their variants, Fibonacci camera directions, and the
// heterogeneous "bands" absorption field of monkey-bands.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/core/constants.hpp"
#include "difftrans/core/vec.hpp"

namespace difftrans::io {

// ------------------------------------------------------------ camera directions

// Which part of the sphere the cameras sit on (docs/benchmark-scenes.md): the whole sphere,
// or the upper half above y = 0.05 (so no camera looks up from the floor).
enum class ViewSphere { sphere, upper_hemisphere };

inline constexpr double upper_hemisphere_min_y = 0.05;

inline const char* to_string(ViewSphere s) { return s == ViewSphere::sphere ? "sphere" : "hemisphere"; }

// Unit directions of n points of a spherical Fibonacci lattice. Point i sits
// at height y_i = y_max - (y_max - y_min) (i + 0.5) / n, which spreads the
// points evenly in area (the area of a zone of the sphere is proportional to
// its height), and at azimuth 2 pi frac(i / golden ratio + offset). The sphere
// spans y in [-1, 1]; the upper hemisphere y in [0.05, 1], every point
// strictly above 0.05. `offset` (any real; its fractional part counts) turns
// the lattice about +Y: the training and test views of a scene are the same
// construction with different offsets. No randomness: the same arguments
// give the same points, bit for bit.
inline std::vector<Vec3f> fibonacci_directions(int n, ViewSphere sphere, double offset = 0.0) {
  if (n < 0) throw std::invalid_argument("fibonacci_directions: negative count " + std::to_string(n));
  const double y_min = sphere == ViewSphere::sphere ? -1.0 : upper_hemisphere_min_y, y_max = 1.0;
  const double inv_golden = 0.6180339887498949;  // 1 / golden ratio
  std::vector<Vec3f> out;
  out.reserve(std::size_t(n));
  for (int i = 0; i < n; ++i) {
    const double y = y_max - (y_max - y_min) * (double(i) + 0.5) / double(n);
    const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    double turn = double(i) * inv_golden + offset;
    turn -= std::floor(turn);
    const double phi = 2.0 * pi_v<double> * turn;
    out.emplace_back(float(r * std::cos(phi)), float(y), float(r * std::sin(phi)));
  }
  return out;
}

// Lattice offsets derived from a seed: the training views turn by
// frac(seed / golden ratio), the test views by half a turn more, so the two
// sets never coincide. Seed 0 gives offsets 0 and 0.5.
struct ViewOffsets {
  double train = 0.0, test = 0.5;
};
inline ViewOffsets view_offsets(std::uint64_t seed) {
  double t = double(seed % 1000003u) * 0.6180339887498949;
  t -= std::floor(t);
  double u = t + 0.5;
  u -= std::floor(u);
  return {t, u};
}

// ------------------------------------------------------------ absorption "bands"

// monkey-bands (docs/benchmark-scenes.md): sigma_a = (0.5, 2, 5) above y = 0 and (5, 2, 0.5)
// below, joined by a smooth step of width 0.1 centred on y = 0: with
// t = clamp((y + 0.05) / 0.1, 0, 1), s = t² (3 − 2t),
// sigma(y) = below + (above − below) s. Coordinates in the normalized frame.
struct BandsField {
  Vec3f above{0.5f, 2.0f, 5.0f};
  Vec3f below{5.0f, 2.0f, 0.5f};
  double centre = 0.0;  // y of the middle of the step
  double width = 0.1;   // the step runs over [centre - width/2, centre + width/2]

  double step(double y) const {
    if (!(width > 0.0)) return y >= centre ? 1.0 : 0.0;
    const double t = std::clamp((y - centre) / width + 0.5, 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
  }
  Vec3f sigma(double y) const {
    const double s = step(y);
    return Vec3f(float(below.x + (above.x - below.x) * s), float(below.y + (above.y - below.y) * s),
                 float(below.z + (above.z - below.z) * s));
  }
};

// An absorption grid (sigma per vertex, RGB) over the box [lo, hi]; vertex
// (i, j, k) at lo + (i, j, k) (hi − lo) / (res − 1), flat index
// ((k res.y + j) res.x + i) 3 + channel — the layout of scene/absorption.hpp.
struct AbsorptionGrid {
  Vec3i res{2, 2, 2};
  Vec3f lo{-0.5f}, hi{0.5f};
  std::vector<float> sigma;  // res.x res.y res.z 3 values, >= 0

  std::size_t vertex_count() const { return std::size_t(res.x) * std::size_t(res.y) * std::size_t(res.z); }
  Vec3f vertex(int i, int j, int k) const {
    const Vec3i c = res - Vec3i(1);
    return Vec3f(lo.x + (hi.x - lo.x) * float(i) / float(c.x), lo.y + (hi.y - lo.y) * float(j) / float(c.y),
                 lo.z + (hi.z - lo.z) * float(k) / float(c.z));
  }
  std::size_t index(int i, int j, int k, int channel) const {
    return ((std::size_t(k) * std::size_t(res.y) + std::size_t(j)) * std::size_t(res.x) + std::size_t(i)) * 3 +
           std::size_t(channel);
  }
};

// Samples a field sigma(p) (a callable Vec3f -> Vec3f) at the grid's vertices.
template <class F>
AbsorptionGrid sample_absorption_grid(const Vec3i& res, const Vec3f& lo, const Vec3f& hi, F&& sigma_at) {
  if (res.x < 2 || res.y < 2 || res.z < 2)
    throw std::invalid_argument("sample_absorption_grid: every resolution must be at least 2");
  if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z))
    throw std::invalid_argument("sample_absorption_grid: the box's lower corner must lie below the upper one");
  AbsorptionGrid g;
  g.res = res;
  g.lo = lo;
  g.hi = hi;
  g.sigma.resize(g.vertex_count() * 3);
  for (int k = 0; k < res.z; ++k)
    for (int j = 0; j < res.y; ++j)
      for (int i = 0; i < res.x; ++i) {
        const Vec3f s = sigma_at(g.vertex(i, j, k));
        for (int c = 0; c < 3; ++c) g.sigma[g.index(i, j, k, c)] = s[c];
      }
  return g;
}

// The bands field as a grid over [-0.51, 0.51]^3 (the unit box and a margin).
// It varies along y only, so 2 vertices suffice in x and z; in y the spacing
// is `spacing` (default 0.01: 10 vertices across the step), which the
// trilinear interpolation follows to within 0.2% of the field's range.
inline AbsorptionGrid bands_absorption_grid(const BandsField& field = {}, double spacing = 0.01) {
  const float half = 0.51f;
  const int cells = std::max(1, int(std::lround(2.0 * half / spacing)));
  return sample_absorption_grid(Vec3i(2, cells + 1, 2), Vec3f(-half), Vec3f(half),
                                [&](const Vec3f& p) { return field.sigma(double(p.y)); });
}

// ------------------------------------------------------------ presets

enum class AbsorptionModel { none, homogeneous, bands };

inline const char* to_string(AbsorptionModel a) {
  return a == AbsorptionModel::none ? "none" : a == AbsorptionModel::homogeneous ? "homogeneous" : "bands";
}

// One benchmark scene of docs/benchmark-scenes.md (files are names inside data/).
struct Preset {
  std::string id;
  std::string mesh;         // meshes/NAME
  double ior = 1.5;
  AbsorptionModel absorption = AbsorptionModel::none;
  Vec3f sigma{0.0f};        // homogeneous absorption (per unit length of the normalized frame)
  BandsField bands;         // AbsorptionModel::bands
  std::string environment;  // envmaps/NAME: the training environment
  ViewSphere views = ViewSphere::sphere;
};

inline const std::vector<Preset>& presets() {
  static const std::vector<Preset> list = [] {
    std::vector<Preset> p(4);
    p[0].id = "spot-clear";
    p[0].mesh = "spot.obj";
    p[0].ior = 1.472;
    p[0].environment = "venice_sunset_1k.hdr";
    p[0].views = ViewSphere::sphere;
    p[1].id = "bunny-clear";
    p[1].mesh = "bunny.obj";
    p[1].ior = 1.485;
    p[1].environment = "royal_esplanade_1k.hdr";
    p[1].views = ViewSphere::sphere;
    p[2].id = "horse-green";
    p[2].mesh = "horse.obj";
    p[2].ior = 1.45;
    p[2].absorption = AbsorptionModel::homogeneous;
    p[2].sigma = Vec3f(4.0f, 0.4f, 4.0f);
    p[2].environment = "pedestrian_overpass_1k.hdr";
    p[2].views = ViewSphere::upper_hemisphere;
    p[3].id = "monkey-bands";
    p[3].mesh = "monkey.obj";
    p[3].ior = 1.60;
    p[3].absorption = AbsorptionModel::bands;
    p[3].environment = "blouberg_sunrise_2_1k.hdr";
    p[3].views = ViewSphere::upper_hemisphere;
    return p;
  }();
  return list;
}

// The preset of that id; std::invalid_argument listing the ids otherwise.
inline const Preset& find_preset(const std::string& id) {
  std::string ids;
  for (const auto& p : presets()) {
    if (p.id == id) return p;
    ids += (ids.empty() ? "" : ", ") + p.id;
  }
  throw std::invalid_argument("unknown preset '" + id + "' (known: " + ids + ")");
}

// The four environment maps of data/envmaps (envmaps/NAME), in a fixed order.
inline std::vector<std::string> shared_environments() {
  std::vector<std::string> names;
  for (const auto& p : presets()) names.push_back(p.environment);
  return names;
}

// The environment maps other than `training` (docs/benchmark-scenes.md: relighting).
inline std::vector<std::string> relighting_environments(const std::string& training) {
  std::vector<std::string> names;
  for (const auto& n : shared_environments())
    if (n != training) names.push_back(n);
  return names;
}

// Views per relighting environment (docs/benchmark-scenes.md).
inline constexpr int relighting_views = 10;

// Resolution and view counts of a variant, and the reference render settings.
struct Variant {
  std::string name;
  int resolution = 256;  // square images
  int train_views = 100;
  int test_views = 20;
  int samples_per_axis = 4;  // 16 stratified samples per pixel
  int max_depth = 16;        // reference: depth 16, no pruning, exact absorption
};

// docs/benchmark-scenes.md: full 256² and 100 views, quick 128² and 50, test 64² and 24.
// The protocol gives 20 test views and leaves the test-suite variant's count
// open; it takes 8, so the suite stays fast.
inline Variant find_variant(const std::string& name) {
  Variant v;
  v.name = name;
  if (name == "full") return v;
  if (name == "quick") {
    v.resolution = 128;
    v.train_views = 50;
    return v;
  }
  if (name == "test") {
    v.resolution = 64;
    v.train_views = 24;
    v.test_views = 8;
    return v;
  }
  throw std::invalid_argument("unknown variant '" + name + "' (known: full, quick, test)");
}

}  // namespace difftrans::io
