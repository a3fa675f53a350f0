// Absorption error: the points inside a closed mesh, a grid's σ at a point,
// and the per-channel relative error inside the true object.
#include "difftrans/metrics/absorption.hpp"

#include <array>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <utility>
#include <vector>

#include <doctest/doctest.h>

namespace {

using difftrans::Vec3f;
using difftrans::Vec3i;

// An axis-aligned cube of half-size h around the origin, outward (or inward
// with flip) counter-clockwise triangles, appended to (p, t).
void add_cube(std::vector<Vec3f>& p, std::vector<Vec3i>& t, float h, bool flip) {
  const int base = int(p.size());
  for (int i = 0; i < 8; ++i) p.push_back(Vec3f(i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h));
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    Vec3i a(base + q[0], base + q[1], base + q[2]), b(base + q[0], base + q[2], base + q[3]);
    if (flip) {
      std::swap(a.y, a.z);
      std::swap(b.y, b.z);
    }
    t.push_back(a);
    t.push_back(b);
  }
}

}  // namespace

TEST_CASE("interior points: a hollow cube keeps the shell and leaves out the hole") {
  std::vector<Vec3f> p;
  std::vector<Vec3i> t;
  add_cube(p, t, 1.0f, false);
  CHECK(difftrans::metrics::interior_points(p, t, 40).size() == std::size_t(40 * 40 * 40));
  add_cube(p, t, 0.5f, true);  // a cavity of a quarter of the side: 20³ of the 40³ points
  const std::vector<Vec3f> inside = difftrans::metrics::interior_points(p, t, 40);
  CHECK(inside.size() == std::size_t(40 * 40 * 40 - 20 * 20 * 20));
  for (const Vec3f& x : inside)
    CHECK_FALSE((std::abs(x.x) < 0.5f && std::abs(x.y) < 0.5f && std::abs(x.z) < 0.5f));
  CHECK(difftrans::metrics::interior_points(p, {}, 8).empty());
  CHECK_THROWS_AS(difftrans::metrics::interior_points(p, t, 0), std::invalid_argument);
}

TEST_CASE("a grid's sigma at a point is trilinear between its vertices") {
  difftrans::io::AbsorptionGrid g;
  g.res = Vec3i(3, 4, 5);
  g.lo = Vec3f(-1.0f);
  g.hi = Vec3f(1.0f, 2.0f, 3.0f);
  g.sigma.resize(g.vertex_count() * 3);
  const auto field = [](const Vec3f& x) { return Vec3f(1.0f + x.x, 2.0f + 0.5f * x.y - x.z, 3.0f + x.z); };
  for (int k = 0; k < g.res.z; ++k)
    for (int j = 0; j < g.res.y; ++j)
      for (int i = 0; i < g.res.x; ++i)
        for (int c = 0; c < 3; ++c) g.sigma[g.index(i, j, k, c)] = field(g.vertex(i, j, k))[c];
  for (const Vec3f x : {Vec3f(0.3f, 0.7f, -0.2f), Vec3f(-1.0f, 2.0f, 3.0f), Vec3f(0.99f, -0.5f, 1.7f)}) {
    const Vec3f s = difftrans::metrics::grid_sigma_at(g, x);
    for (int c = 0; c < 3; ++c) CHECK(s[c] == doctest::Approx(field(x)[c]).epsilon(1e-5));
  }
  // outside the box: the nearest face's value
  CHECK(difftrans::metrics::grid_sigma_at(g, Vec3f(5.0f, 0.0f, 0.0f)).x == doctest::Approx(2.0f));
}

TEST_CASE("absorption error: per channel, the mean absolute error over the true mean") {
  const std::vector<Vec3f> points = {Vec3f(0.0f), Vec3f(0.1f, 0.0f, 0.0f), Vec3f(0.0f, 0.2f, 0.0f)};
  const auto truth = [](const Vec3f&) { return Vec3f(1.0f, 2.0f, 0.0f); };
  const auto fit = [](const Vec3f& x) { return Vec3f(x.x > 0.05f ? 1.3f : 1.0f, 1.8f, 0.3f); };
  const auto e = difftrans::metrics::absorption_error(points, fit, truth);
  CHECK(e.points == 3);
  CHECK(e.relative[0] == doctest::Approx(0.1));   // |0.3| / 3 points / 1
  CHECK(e.relative[1] == doctest::Approx(0.1));   // 0.2 / 2
  CHECK(e.relative[2] == 0.0);                    // clear channel: no relative error
  CHECK(e.mean_abs[2] == doctest::Approx(0.3));
  CHECK(e.mean_relative == doctest::Approx(0.1)); // the two absorbing channels
  CHECK(e.mean_fit[0] == doctest::Approx(1.1));
  CHECK(difftrans::metrics::absorption_error({}, fit, truth).points == 0);
}

TEST_CASE("absorption slabs: the error found in the slab that holds it") {
  // 100 points on a line along y from -0.495 to 0.495 (slabs 0.2475 high,
  // no point on a slab's edge); the fit is right except above y = 0.25
  std::vector<Vec3f> points;
  for (int i = 0; i < 100; ++i) points.push_back(Vec3f(0.1f, -0.495f + 0.01f * float(i), -0.2f));
  const auto truth = [](const Vec3f& p) { return p.y < 0.0f ? Vec3f(5.0f, 2.0f, 0.5f) : Vec3f(0.5f, 2.0f, 5.0f); };
  const auto fit = [&](const Vec3f& p) { return p.y > 0.25f ? truth(p) * 0.5f : truth(p); };
  const difftrans::metrics::AbsorptionSlabs s = difftrans::metrics::absorption_slabs(points, fit, truth, 1, 4);
  REQUIRE(s.points.size() == 4);
  CHECK(s.slabs.from == doctest::Approx(-0.495));
  CHECK(s.slabs.to == doctest::Approx(0.495));
  std::size_t total = 0;
  for (std::size_t n : s.points) total += n;
  CHECK(total == points.size());
  for (std::size_t b = 0; b < 4; ++b) {
    CAPTURE(b);
    const double lower_band = b < 2 ? 5.0 : 0.5;
    CHECK(s.mean_true[b][0] == doctest::Approx(lower_band));
    if (b < 3) {
      for (std::size_t c = 0; c < 3; ++c) CHECK(s.mean_fit[b][c] == doctest::Approx(s.mean_true[b][c]));
    } else {
      for (std::size_t c = 0; c < 3; ++c) CHECK(s.mean_fit[b][c] == doctest::Approx(0.5 * s.mean_true[b][c]));
    }
  }
  // the points-weighted means over the slabs are the whole field's
  const difftrans::metrics::AbsorptionError e = difftrans::metrics::absorption_error(points, fit, truth);
  for (std::size_t c = 0; c < 3; ++c) {
    double t = 0.0, f = 0.0;
    for (std::size_t b = 0; b < 4; ++b) {
      t += s.mean_true[b][c] * double(s.points[b]);
      f += s.mean_fit[b][c] * double(s.points[b]);
    }
    CHECK(t / double(total) == doctest::Approx(e.mean_true[c]));
    CHECK(f / double(total) == doctest::Approx(e.mean_fit[c]));
  }
}
