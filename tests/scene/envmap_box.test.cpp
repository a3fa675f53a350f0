// Box averages from the running sums: against the map integrated texel by
// texel (boxes across the seam, around the map more than once, past the
// poles), the bilinear lookup for boxes one texel wide, and a constant map.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include "difftrans/ad/params.hpp"
#include "difftrans/scene/envmap.hpp"
#include "difftrans/scene/envmap_box.hpp"

namespace sc = difftrans::scene;
using difftrans::Vec2f;
using difftrans::Vec3f;

namespace {

constexpr int W = 7, H = 5;

std::vector<float> random_map(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 3.0f);
  std::vector<float> t(std::size_t(W) * H * 3);
  for (float& v : t) v = u(rng);
  t[std::size_t(sc::texel_index(W, 2, 4, 0))] = 500.0f;  // a sun
  return t;
}

// The map's mean over [x0, x1] × [y0, y1] (texel coordinates, x wrapping,
// y inside [0, H]), summed texel by texel over the overlaps.
Vec3f brute_average(const std::vector<float>& t, double x0, double x1, double y0, double y1) {
  double sum[3] = {0, 0, 0};
  for (int row = 0; row < H; ++row) {
    const double oy = std::min(y1, double(row + 1)) - std::max(y0, double(row));
    if (oy <= 0) continue;
    for (long c = long(std::floor(x0)); double(c) < x1; ++c) {
      const double ox = std::min(x1, double(c + 1)) - std::max(x0, double(c));
      if (ox <= 0) continue;
      const int col = int(((c % W) + W) % W);
      for (int ch = 0; ch < 3; ++ch) sum[ch] += ox * oy * double(t[std::size_t(sc::texel_index(W, row, col, ch))]);
    }
  }
  const double area = (x1 - x0) * (y1 - y0);
  return Vec3f(float(sum[0] / area), float(sum[1] / area), float(sum[2] / area));
}

void check_close(const Vec3f& a, const Vec3f& b, double rel) {
  for (int c = 0; c < 3; ++c) CHECK(double(a[c]) == doctest::Approx(double(b[c])).epsilon(rel));
}

}  // namespace

TEST_CASE("a box's mean equals the map integrated texel by texel") {
  const std::vector<float> t = random_map(3);
  const std::vector<double> sums = sc::env_box_sums(t.data(), W, H);
  const sc::EnvBoxTable table{sums.data(), W, H};
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> ux(-20.0f, 20.0f), uy(0.0f, float(H)), uh(0.5f, 4.0f);
  for (int i = 0; i < 200; ++i) {
    const float x = ux(rng), y = uy(rng), hx = uh(rng), hy = 0.5f + 0.4f * uh(rng) / 4.0f;
    // the box as documented: y slid back inside the map
    double y0 = double(y) - hy, y1 = double(y) + hy;
    if (y0 < 0) y1 -= y0, y0 = 0;
    if (y1 > H) y0 -= y1 - H, y1 = H;
    check_close(sc::env_box_average(table, x, y, hx, hy), brute_average(t, double(x) - hx, double(x) + hx, y0, y1), 1e-5);
  }
  // around the map more than once in x: every whole turn weighs the same
  check_close(sc::env_box_average(table, 3.3f, 2.5f, 3.5f * W, 0.5f), brute_average(t, 0, W, 2, 3), 1e-5);
  // taller than the map: the whole map
  check_close(sc::env_box_average(table, 1.0f, 1.0f, 0.5f * W, 3.0f * H), brute_average(t, 0, W, 0, H), 1e-5);
}

TEST_CASE("a box one texel wide is the bilinear lookup, at the seam and the poles too") {
  const std::vector<float> t = random_map(7);
  const std::vector<double> sums = sc::env_box_sums(t.data(), W, H);
  const sc::EnvBoxTable table{sums.data(), W, H};
  const sc::EnvMap env = sc::equirect_environment(t.data(), W, H);
  const difftrans::ad::ParamSet none;
  difftrans::ad::ParamReader<float> reader(&none);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Vec2f> points;
  for (int i = 0; i < 100; ++i) points.emplace_back(u(rng), u(rng));
  for (float v : {0.0f, 0.05f, 0.5f, 0.97f, 1.0f}) points.emplace_back(0.999f, v);  // the seam, the poles
  points.emplace_back(0.0f, 0.5f);
  for (const Vec2f& p : points) {
    const Vec3f point = sc::lookup_uv(reader, env, difftrans::Vec2<float>(p.x, p.y));
    // half-extents below half a texel count as half a texel
    for (float h : {0.5f, 0.1f})
      check_close(sc::env_box_average(table, p.x * W, p.y * H, h, h), point, 2e-5);
  }
}

TEST_CASE("a constant map's box mean is the constant; bad input reads zero") {
  std::vector<float> t(std::size_t(W) * H * 3);
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = 0.25f * float(i % 3 + 1);
  const std::vector<double> sums = sc::env_box_sums(t.data(), W, H);
  const sc::EnvBoxTable table{sums.data(), W, H};
  for (float h : {0.5f, 2.0f, 30.0f})
    check_close(sc::env_box_average(table, -3.0f, 4.9f, h, h), Vec3f(0.25f, 0.5f, 0.75f), 1e-6);
  CHECK(sc::env_box_average(table, NAN, 1.0f, 1.0f, 1.0f) == Vec3f(0.0f));
  CHECK(sc::env_box_average(table, 1.0f, 1.0f, INFINITY, 1.0f) == Vec3f(0.0f));
  CHECK(sc::env_box_average(sc::EnvBoxTable{}, 1.0f, 1.0f, 1.0f, 1.0f) == Vec3f(0.0f));
}
