// Benchmark presets: Fibonacci camera directions (count, unit length, the
// hemisphere constraint, even spread, determinism, offsets), the bands field
// and its grid, the preset and variant tables against docs/benchmark-scenes.md.
#include <doctest/doctest.h>

#include <cmath>
#include <set>

#include "difftrans/io/presets.hpp"

namespace io = difftrans::io;
using difftrans::Vec3f;
using difftrans::Vec3i;

TEST_CASE("fibonacci_directions: count, unit length, sphere and hemisphere") {
  for (int n : {0, 1, 7, 24, 100}) {
    const auto s = io::fibonacci_directions(n, io::ViewSphere::sphere);
    const auto h = io::fibonacci_directions(n, io::ViewSphere::upper_hemisphere, 0.3);
    CHECK(int(s.size()) == n);
    CHECK(int(h.size()) == n);
    for (const auto& d : s) CHECK(std::abs(glm::length(d) - 1.0f) < 1e-5f);
    for (const auto& d : h) {
      CHECK(std::abs(glm::length(d) - 1.0f) < 1e-5f);
      CHECK(d.y > 0.05f);
    }
  }
  // the sphere reaches both halves, in equal numbers for an even count
  const auto s = io::fibonacci_directions(100, io::ViewSphere::sphere);
  int upper = 0;
  for (const auto& d : s) upper += d.y > 0.0f;
  CHECK(upper == 50);
  CHECK_THROWS(io::fibonacci_directions(-1, io::ViewSphere::sphere));
}

TEST_CASE("fibonacci_directions: even spread (no two points close, balanced centroid)") {
  const int n = 100;
  const auto s = io::fibonacci_directions(n, io::ViewSphere::sphere);
  // for n evenly spread points the nearest neighbour is about sqrt(4 pi / n) away
  double min_dist = 1e9;
  Vec3f centroid(0.0f);
  for (int i = 0; i < n; ++i) {
    centroid += s[size_t(i)];
    for (int j = i + 1; j < n; ++j) min_dist = std::min(min_dist, double(glm::length(s[size_t(i)] - s[size_t(j)])));
  }
  const double spacing = std::sqrt(4.0 * M_PI / n);
  CHECK(min_dist > 0.5 * spacing);
  CHECK(glm::length(centroid / float(n)) < 0.05f);
  // the hemisphere's points sit evenly in y (equal-area zones)
  const auto h = io::fibonacci_directions(n, io::ViewSphere::upper_hemisphere);
  int low = 0;
  for (const auto& d : h) low += d.y < 0.525f;  // the middle of [0.05, 1]
  CHECK(low == n / 2);
}

TEST_CASE("fibonacci_directions: deterministic; the offset turns the lattice about +Y") {
  const auto a = io::fibonacci_directions(24, io::ViewSphere::upper_hemisphere, 0.25);
  const auto b = io::fibonacci_directions(24, io::ViewSphere::upper_hemisphere, 0.25);
  for (size_t i = 0; i < a.size(); ++i) CHECK(a[i] == b[i]);
  const auto c = io::fibonacci_directions(24, io::ViewSphere::upper_hemisphere, 0.5);
  for (size_t i = 0; i < a.size(); ++i) {
    CHECK(a[i].y == c[i].y);  // same heights
    // turned by a quarter turn: (x, z) rotated by pi/2
    const double angle_a = std::atan2(a[i].z, a[i].x), angle_c = std::atan2(c[i].z, c[i].x);
    double diff = angle_c - angle_a;
    diff -= 2.0 * M_PI * std::floor(diff / (2.0 * M_PI));
    CHECK(diff == doctest::Approx(M_PI / 2).epsilon(1e-4));
  }
  // offsets from seeds: train and test differ by half a turn, seeds differ
  const auto o0 = io::view_offsets(0), o1 = io::view_offsets(1), o1b = io::view_offsets(1);
  CHECK(o0.train == 0.0);
  CHECK(o0.test == 0.5);
  CHECK(o1.train == o1b.train);
  CHECK(o1.train != o0.train);
  CHECK(std::abs(std::fmod(o1.test - o1.train + 1.0, 1.0) - 0.5) < 1e-12);
}

TEST_CASE("bands field: the two colours away from y = 0, a smooth step across") {
  const io::BandsField f;
  CHECK(f.sigma(0.3) == Vec3f(0.5f, 2.0f, 5.0f));
  CHECK(f.sigma(0.05) == Vec3f(0.5f, 2.0f, 5.0f));
  CHECK(f.sigma(-0.05) == Vec3f(5.0f, 2.0f, 0.5f));
  CHECK(f.sigma(-0.4) == Vec3f(5.0f, 2.0f, 0.5f));
  // halfway at the centre, symmetric around it, monotone across the step
  const Vec3f mid = f.sigma(0.0);
  CHECK(mid.x == doctest::Approx(2.75));
  CHECK(mid.z == doctest::Approx(2.75));
  CHECK(mid.y == doctest::Approx(2.0));
  CHECK(f.step(0.02) == doctest::Approx(1.0 - f.step(-0.02)));
  double previous = -1.0;
  for (int i = 0; i <= 100; ++i) {
    const double s = f.step(-0.06 + 0.12 * i / 100.0);
    CHECK(s >= previous);
    previous = s;
  }
  // smooth: the slope at both ends of the step is zero (finite differences)
  const double h = 1e-5;
  CHECK(std::abs(f.step(-0.05 + h) - f.step(-0.05)) / h < 1e-2);
  CHECK(std::abs(f.step(0.05) - f.step(0.05 - h)) / h < 1e-2);
}

TEST_CASE("bands grid: samples the field at its vertices, spans the unit box") {
  const io::BandsField f;
  const io::AbsorptionGrid g = io::bands_absorption_grid(f);
  CHECK(g.res.x == 2);
  CHECK(g.res.z == 2);
  CHECK(g.res.y == 103);
  CHECK(g.sigma.size() == g.vertex_count() * 3);
  for (int a = 0; a < 3; ++a) {
    CHECK(g.lo[a] <= -0.5f);
    CHECK(g.hi[a] >= 0.5f);
  }
  for (int k = 0; k < g.res.z; ++k)
    for (int j = 0; j < g.res.y; ++j)
      for (int i = 0; i < g.res.x; ++i) {
        const Vec3f expected = f.sigma(double(g.vertex(i, j, k).y));
        for (int c = 0; c < 3; ++c) CHECK(g.sigma[g.index(i, j, k, c)] == expected[c]);
      }
  // linear interpolation between vertices follows the field closely
  double worst = 0.0;
  for (int j = 0; j + 1 < g.res.y; ++j) {
    const float y0 = g.vertex(0, j, 0).y, y1 = g.vertex(0, j + 1, 0).y;
    const float ym = 0.5f * (y0 + y1);
    const double interp = 0.5 * (g.sigma[g.index(0, j, 0, 0)] + g.sigma[g.index(0, j + 1, 0, 0)]);
    worst = std::max(worst, std::abs(interp - f.sigma(ym).x));
  }
  CHECK(worst < 0.01 * 4.5);
  CHECK_THROWS(io::sample_absorption_grid(Vec3i(1, 2, 2), Vec3f(0.0f), Vec3f(1.0f), [](Vec3f) { return Vec3f(0.0f); }));
}

TEST_CASE("presets and variants follow docs/benchmark-scenes.md") {
  CHECK(io::presets().size() == 4);
  const auto& horse = io::find_preset("horse-green");
  CHECK(horse.mesh == "horse.obj");
  CHECK(horse.ior == 1.45);
  CHECK(horse.absorption == io::AbsorptionModel::homogeneous);
  CHECK(horse.sigma == Vec3f(4.0f, 0.4f, 4.0f));
  CHECK(horse.views == io::ViewSphere::upper_hemisphere);
  CHECK(io::find_preset("spot-clear").views == io::ViewSphere::sphere);
  CHECK(io::find_preset("monkey-bands").absorption == io::AbsorptionModel::bands);
  CHECK(io::find_preset("bunny-clear").ior == 1.485);
  CHECK_THROWS_WITH(io::find_preset("teapot"), doctest::Contains("spot-clear"));
  // the four environments are distinct; relighting uses the other three
  const auto envs = io::shared_environments();
  CHECK(std::set<std::string>(envs.begin(), envs.end()).size() == 4);
  const auto others = io::relighting_environments(horse.environment);
  CHECK(others.size() == 3);
  for (const auto& e : others) CHECK(e != horse.environment);

  const auto full = io::find_variant("full"), quick = io::find_variant("quick"), test = io::find_variant("test");
  CHECK(full.resolution == 256);
  CHECK(full.train_views == 100);
  CHECK(full.test_views == 20);
  CHECK(quick.resolution == 128);
  CHECK(quick.train_views == 50);
  CHECK(test.resolution == 64);
  CHECK(test.train_views == 24);
  for (const auto& v : {full, quick, test}) {
    CHECK(v.samples_per_axis * v.samples_per_axis >= 16);
    CHECK(v.max_depth == 16);
  }
  CHECK_THROWS(io::find_variant("huge"));
}
