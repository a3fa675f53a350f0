// Ray footprints: the camera's ray differentials against differences of
// Camera::ray_through; the differentials of every escaping branch of a
// sphere's Fresnel tree against differences of traces from neighbouring
// pixel positions; the footprint image against the point image (equal on a
// constant map, closer to the converged image on a map with a small sun at
// few samples, and converging to it).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "difftrans/render/footprint.hpp"
#include "difftrans/render/passes.hpp"
#include "support/shapes.hpp"

namespace dr = difftrans::render;
namespace sc = difftrans::scene;
namespace ad = difftrans::ad;
using difftrans::Vec3;
using difftrans::Vec3f;

namespace {

dr::HostScene sphere_scene(std::vector<float> env, int w, int h) {
  const dt_test::Shape sphere = dt_test::make_icosphere(0.5f, 3);
  dr::HostScene s(sphere.positions, sphere.triangles, "sphere");
  s.ior = 1.5f;
  s.set_environment_map(std::move(env), w, h);
  return s;
}

// A smooth sky, and when `sun` > 0 one texel that bright.
std::vector<float> sky(int w, int h, float sun) {
  std::vector<float> t;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      t.insert(t.end(), {0.3f + 0.4f * float(r) / float(h), 0.5f, 0.2f + 0.5f * float(c) / float(w)});
  if (sun > 0)
    for (int c = 0; c < 3; ++c) t[std::size_t(sc::texel_index(w, h / 3, w / 2 + 3, c))] = sun;
  return t;
}

// Records the direction of every escaping branch, in the tracer's order:
// the value and, for Dual<double, 2>, both lanes.
struct RecordEscape {
  std::vector<std::vector<double>>* out;
  template <class S, class Reader>
  Vec3<S> operator()(Reader&, const dr::SceneView&, const Vec3<S>&, const Vec3<S>& d) const {
    std::vector<double> r;
    for (int c = 0; c < 3; ++c) r.push_back(double(ad::value_of(d[c])));
    if constexpr (dr::detail::IsPixelDual<S>::value)
      for (int lane = 0; lane < 2; ++lane)
        for (int c = 0; c < 3; ++c) r.push_back(double(d[c].grad[lane]));
    out->push_back(r);
    return Vec3<S>(S(0), S(0), S(0));
  }
};

// Linear RMSE over the image of values clamped to [0, 1] (what a
// tone-mapped picture keeps of a glint).
double clamped_rmse(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = std::min(1.0, double(a[i])) - std::min(1.0, double(b[i]));
    sum += d * d;
  }
  return std::sqrt(sum / double(a.size()));
}

}  // namespace

TEST_CASE("the camera ray's differentials are the derivatives of ray_through") {
  const sc::Camera cam = sc::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 40, 30);
  for (const float px : {0.5f, 17.3f, 39.9f})
    for (const float py : {0.2f, 15.0f, 29.5f}) {
      const float cell = 0.25f, h = 0.05f;
      const Vec3<ad::Dual<double, 2>> d = dr::ray_differential<double>(cam, px, py, cell);
      const Vec3f at = cam.ray_through(px, py).direction;
      const Vec3f dx = (cam.ray_through(px + h, py).direction - cam.ray_through(px - h, py).direction) / (2 * h);
      const Vec3f dy = (cam.ray_through(px, py + h).direction - cam.ray_through(px, py - h).direction) / (2 * h);
      for (int c = 0; c < 3; ++c) {
        CHECK(d[c].value == double(at[c]));
        CHECK(d[c].grad[0] == doctest::Approx(double(cell * dx[c])).epsilon(1e-3).scale(1e-3));
        CHECK(d[c].grad[1] == doctest::Approx(double(cell * dy[c])).epsilon(1e-3).scale(1e-3));
      }
    }
}

TEST_CASE("every escaping branch's differentials match differences of neighbouring traces") {
  const std::vector<float> env = sky(16, 8, 0.0f);
  dr::HostScene s = sphere_scene(env, 16, 8);
  s.set_homogeneous_absorption(Vec3f(0.3f, 0.6f, 0.9f));
  const sc::Camera cam = sc::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 64, 64);
  const dr::SceneView view = s.view(false);
  const ad::ParamSet params = s.params();
  dr::TraceSettings settings;
  settings.max_depth = 5;
  const double h = 0.005;
  int branches = 0;
  double worst = 0;
  for (const float px : {24.5f, 32.5f, 37.2f})
    for (const float py : {27.5f, 32.5f, 38.1f}) {
      std::vector<std::vector<double>> dual, left, right, up, down;
      ad::ParamReader<ad::Dual<double, 2>> dual_reader(&params);
      dr::trace_footprint<double>(view, s.accel(), dual_reader, cam, px, py, 1.0f, settings, RecordEscape{&dual});
      ad::ParamReader<double> reader(&params);
      const auto trace_at = [&](double x, double y, std::vector<std::vector<double>>* out) {
        const sc::Ray r = cam.ray_through(float(x), float(y));
        dr::trace<double>(view, s.accel(), reader, r.origin, r.direction, settings, nullptr, RecordEscape{out});
      };
      trace_at(px + h, py, &right);
      trace_at(px - h, py, &left);
      trace_at(px, py + h, &down);
      trace_at(px, py - h, &up);
      REQUIRE(dual.size() > 4);  // the sphere was hit: a tree, not one escape
      REQUIRE(right.size() == dual.size());
      REQUIRE(left.size() == dual.size());
      REQUIRE(up.size() == dual.size());
      REQUIRE(down.size() == dual.size());
      for (std::size_t i = 0; i < dual.size(); ++i) {
        double scale = 0;
        for (int k = 3; k < 9; ++k) scale = std::max(scale, std::abs(dual[i][std::size_t(k)]));
        for (int c = 0; c < 3; ++c) {
          const double fx = (right[i][std::size_t(c)] - left[i][std::size_t(c)]) / (2 * h);
          const double fy = (down[i][std::size_t(c)] - up[i][std::size_t(c)]) / (2 * h);
          worst = std::max(worst, std::abs(fx - dual[i][std::size_t(3 + c)]) / std::max(scale, 1e-3));
          worst = std::max(worst, std::abs(fy - dual[i][std::size_t(6 + c)]) / std::max(scale, 1e-3));
        }
        ++branches;
      }
    }
  MESSAGE("branches ", branches, ", largest difference relative to the branch's largest lane ", worst);
  CHECK(branches > 40);
  CHECK(worst < 5e-3);
}

TEST_CASE("on a map of one colour the footprint image is the point image") {
  std::vector<float> env;
  for (int i = 0; i < 32 * 16; ++i) env.insert(env.end(), {0.4f, 0.7f, 1.1f});
  dr::HostScene s = sphere_scene(env, 32, 16);
  const sc::Camera cam = sc::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 24, 24);
  dr::PassOptions opt;
  opt.samples_per_axis = 2;
  opt.trace.max_depth = 6;
  dr::PassStats st;
  const std::vector<float> point = dr::render_image(s, cam, opt);
  const std::vector<float> foot = dr::render_image_footprints(s, cam, opt, {}, &st);
  CHECK(st.rays == 24 * 24 * 4);
  REQUIRE(foot.size() == point.size());
  double worst = 0;
  for (std::size_t i = 0; i < point.size(); ++i) worst = std::max(worst, double(std::abs(foot[i] - point[i])));
  CHECK(worst < 1e-5);
  // a constant environment has nothing to filter: the point pass itself
  s.set_constant_environment(Vec3f(0.4f, 0.7f, 1.1f));
  CHECK(dr::render_image_footprints(s, cam, opt) == dr::render_image(s, cam, opt));
}

TEST_CASE("with a small sun, footprints at few samples are closer to the converged image, and converge to it") {
  const int w = 256, h = 128;  // the sun: one texel of 1.4 degrees
  dr::HostScene s = sphere_scene(sky(w, h, 3000.0f), w, h);
  const sc::Camera cam = sc::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 40, 40);
  dr::PassOptions opt;
  opt.trace.max_depth = 6;
  opt.samples_per_axis = 24;
  const std::vector<float> converged = dr::render_image(s, cam, opt);
  const auto error = [&](int n, bool footprints) {
    dr::PassOptions o = opt;
    o.samples_per_axis = n;
    return clamped_rmse(footprints ? dr::render_image_footprints(s, cam, o) : dr::render_image(s, cam, o), converged);
  };
  const double point2 = error(2, false), foot2 = error(2, true), point4 = error(4, false), foot4 = error(4, true),
               point8 = error(8, false), foot8 = error(8, true);
  MESSAGE("clamped RMSE against 24 x 24 point samples, points / footprints: 2x2 ", point2, " / ", foot2, ", 4x4 ",
          point4, " / ", foot4, ", 8x8 ", point8, " / ", foot8);
  CHECK(point4 > 0.01);          // the sun is seen: there is aliasing to remove
  CHECK(foot2 < point2);         // footprints beat points at equal samples
  CHECK(foot4 < 0.5 * point4);
  CHECK(foot4 < 0.5 * foot2);    // and converge as the strata shrink
  CHECK(foot8 < 0.5 * foot4);
}
