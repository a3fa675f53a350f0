// Adaptive sampling: a pixel's value is the mean of its rounds (traced by
// hand here), a plain background stops after the first rounds with its exact
// value, the uncertain pixels (the object, the sun's glints) get the rounds,
// and a tolerance of zero gives every uncertain pixel all of them.
#include <doctest/doctest.h>

#include "support/shapes.hpp"

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "difftrans/render/adaptive.hpp"

using namespace dt_test;
namespace dr = difftrans::render;
using difftrans::Vec3f;
namespace ad = difftrans::ad;

namespace {
// A glass sphere before a plain grey map (or a checkerboard of 8 x 4 cells)
// with one bright texel (a sun).
dr::HostScene sun_scene(float sun, bool checker = false) {
  const Shape sphere = make_icosphere(0.5f, 3);
  dr::HostScene s(sphere.positions, sphere.triangles, "sphere");
  s.ior = 1.5f;
  const int w = 64, h = 32;
  std::vector<float> env(std::size_t(w * h * 3), 0.3f);
  if (checker)
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c)
        for (int k = 0; k < 3; ++k) env[std::size_t((r * w + c) * 3 + k)] = ((r / 8 + c / 8) % 2) ? 0.8f : 0.1f;
  for (int c = 0; c < 3; ++c) env[std::size_t((12 * w + 40) * 3 + c)] = sun;
  s.set_environment_map(env, w, h);
  return s;
}

std::int64_t total(const std::vector<std::int64_t>& v) {
  std::int64_t t = 0;
  for (auto x : v) t += x;
  return t;
}
}  // namespace

TEST_CASE("adaptive_rounds doubles from the least to the most") {
  dr::AdaptiveOptions a;
  a.min_rounds = 2;
  a.max_rounds = 64;
  CHECK(dr::adaptive_rounds(a) == std::vector<int>{2, 4, 8, 16, 32, 64});
  a.max_rounds = 40;
  CHECK(dr::adaptive_rounds(a) == std::vector<int>{2, 4, 8, 16, 32});
  a.min_rounds = 1;  // one round cannot show its own spread
  a.max_rounds = 8;
  CHECK(dr::adaptive_rounds(a) == std::vector<int>{2, 4, 8});
}

TEST_CASE("a pixel is the mean of its rounds; the plain background stops first, the object goes on") {
  const dr::HostScene s = sun_scene(50.0f);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 24, 20);
  dr::PassOptions opt;
  opt.trace.max_depth = 8;
  dr::AdaptiveOptions a;
  a.per_axis = 2;
  a.min_rounds = 2;
  a.max_rounds = 16;
  a.tolerance = 1.0f;
  dr::AdaptiveStats st;
  const std::vector<float> img = dr::render_image_adaptive(s, cam, opt, a, &st);
  REQUIRE(st.rounds == std::vector<int>{2, 4, 8, 16});
  CHECK(total(st.pixels_at) == 24 * 20);
  std::int64_t samples = 0;
  for (std::size_t k = 0; k < st.rounds.size(); ++k) samples += st.pixels_at[k] * st.rounds[k] * 4;
  CHECK(st.pass.rays == samples);
  // a corner sees the plain map: stops at the first stop with the map's value
  CHECK(st.pixels_at[0] > 0);
  for (int c = 0; c < 3; ++c) CHECK(img[std::size_t(c)] == doctest::Approx(0.3f).epsilon(1e-6));
  CHECK(st.pixels_at.back() > 0);  // some pixels of the object use every round
  // the centre pixel (on the object) by hand: the mean over its rounds of the
  // mean of 2 x 2 samples at the round's offsets, for each stop until it matches
  const ad::ParamSet params = s.params();
  ad::ParamReader<float> reader(&params);
  const int x = 12, y = 10;
  const std::size_t pix = std::size_t(y * 24 + x) * 3;
  bool matched = false;
  Vec3f sum(0.0f);
  int done = 0;
  for (int stop : st.rounds) {
    for (int r = done; r < stop; ++r) {
      const auto o = dr::detail::round_offset(r);
      Vec3f round(0.0f);
      for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
          const auto ray = cam.generate_ray(x, y, (float(i) + o.x) * 0.5f, (float(j) + o.y) * 0.5f);
          round += dr::trace<float>(s.view(false), s.accel(), reader, ray.origin, ray.direction, opt.trace) * 0.25f;
        }
      sum += round;
    }
    done = stop;
    bool same = true;
    for (int c = 0; c < 3; ++c) same = same && std::abs(sum[c] / float(stop) - img[pix + std::size_t(c)]) < 1e-5f;
    matched = matched || same;
  }
  CHECK(matched);
}

TEST_CASE("tolerance zero: every pixel whose rounds differ uses all of them") {
  const dr::HostScene s = sun_scene(50.0f, true);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 16, 16);
  dr::PassOptions opt;
  opt.trace.max_depth = 8;
  dr::AdaptiveOptions a;
  a.per_axis = 1;
  a.min_rounds = 2;
  a.max_rounds = 8;
  a.tolerance = 0.0f;
  dr::AdaptiveStats tight, loose;
  dr::render_image_adaptive(s, cam, opt, a, &tight);
  a.tolerance = 255.0f;
  dr::render_image_adaptive(s, cam, opt, a, &loose);
  CHECK(loose.pixels_at[0] == 16 * 16);  // nothing is uncertain by 255 levels
  CHECK(tight.pixels_at.back() > 16 * 16 / 4);  // the checker edges, the sphere (inside a cell, the rounds agree and stop)
  CHECK(tight.mean_samples > 2.0 * loose.mean_samples);
}

TEST_CASE("levels: one level is the uniform render") {
  const dr::HostScene s = sun_scene(50.0f, true);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 20, 16);
  dr::PassOptions opt;
  opt.trace.max_depth = 8;
  opt.samples_per_axis = 3;
  const std::vector<float> uniform = dr::render_image<float>(s, cam, opt);
  dr::LevelOptions l;
  l.per_axis = {3};
  dr::LevelStats st;
  const std::vector<float> levels = dr::render_image_levels(s, cam, opt, l, &st);
  REQUIRE(levels.size() == uniform.size());
  for (std::size_t i = 0; i < uniform.size(); ++i) CHECK(levels[i] == doctest::Approx(uniform[i]).epsilon(1e-5));
  CHECK(st.traced == std::vector<std::int64_t>{20 * 16});
  CHECK(st.spread.empty());
  CHECK(st.pass.rays == 20 * 16 * 9);
}

TEST_CASE("levels: the spread pixels and their neighbours go on; a pixel is the mean of all its samples") {
  const dr::HostScene s = sun_scene(50.0f);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 24, 20);
  dr::PassOptions opt;
  opt.trace.max_depth = 8;
  dr::LevelOptions l;
  l.per_axis = {2, 4};
  l.tolerance = 1.0f;
  l.dilate = 0;
  dr::LevelStats alone, around;
  const std::vector<float> img = dr::render_image_levels(s, cam, opt, l, &alone);
  l.dilate = 1;
  dr::render_image_levels(s, cam, opt, l, &around);
  REQUIRE(alone.traced.size() == 2);
  CHECK(alone.traced[0] == 24 * 20);
  CHECK(alone.pass.rays == alone.traced[0] * 4 + alone.traced[1] * 16);
  // the object spreads, the plain map does not; without dilation exactly the
  // spread pixels go on, with it their neighbours too
  CHECK(alone.spread[0] > 0);
  CHECK(alone.spread[0] < 24 * 20 / 2);
  CHECK(alone.traced[1] == alone.spread[0]);
  CHECK(around.spread[0] == alone.spread[0]);
  CHECK(around.traced[1] > alone.traced[1]);
  // a corner sees the plain map: the first level's value, the map's
  for (int c = 0; c < 3; ++c) CHECK(img[std::size_t(c)] == doctest::Approx(0.3f).epsilon(1e-6));
  // the centre pixel (on the object, spread) by hand: the mean of its 2 x 2
  // and 4 x 4 samples
  const ad::ParamSet params = s.params();
  ad::ParamReader<float> reader(&params);
  const std::int64_t pix = 10 * 24 + 12;
  Vec3f sum(0.0f);
  for (int n : {2, 4})
    for (int k = 0; k < n * n; ++k) {
      const auto ray = dr::pixel_sample(cam, n, pix, k);
      sum += dr::trace<float>(s.view(false), s.accel(), reader, ray.origin, ray.direction, opt.trace);
    }
  for (int c = 0; c < 3; ++c)
    CHECK(img[std::size_t(pix) * 3 + std::size_t(c)] == doctest::Approx(sum[c] / 20.0f).epsilon(1e-5));
  // 2 then 6: the 6 x 6 grid holds the 2 x 2 grid's four centres, which are
  // not traced twice: 32 new samples, the pixel the mean of 36
  l.per_axis = {2, 6};
  dr::LevelStats odd;
  const std::vector<float> img6 = dr::render_image_levels(s, cam, opt, l, &odd);
  CHECK(odd.pass.rays == odd.traced[0] * 4 + odd.traced[1] * 32);
  Vec3f sum6(0.0f);
  for (int k = 0; k < 36; ++k) {
    const auto ray = dr::pixel_sample(cam, 6, pix, k);
    sum6 += dr::trace<float>(s.view(false), s.accel(), reader, ray.origin, ray.direction, opt.trace);
  }
  for (int c = 0; c < 3; ++c)
    CHECK(img6[std::size_t(pix) * 3 + std::size_t(c)] == doctest::Approx(sum6[c] / 36.0f).epsilon(1e-5));
  l.per_axis.clear();
  CHECK_THROWS_AS(dr::render_image_levels(s, cam, opt, l), std::invalid_argument);
}

TEST_CASE("levels: the refined image is nearer a converged render than its first level, for fewer samples than uniform") {
  const dr::HostScene s = sun_scene(50.0f);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 32, 32);
  dr::PassOptions opt;
  opt.trace.max_depth = 8;
  opt.samples_per_axis = 24;
  const std::vector<float> converged = dr::render_image<float>(s, cam, opt);
  const auto error = [&](const std::vector<float>& img) {
    double e = 0.0;
    for (std::size_t i = 0; i < img.size(); ++i) {
      const double d = double(difftrans::io::tone_map_value(img[i])) -
                       double(difftrans::io::tone_map_value(converged[i]));
      e += d * d;
    }
    return e;
  };
  dr::LevelOptions l;
  l.per_axis = {2};
  const double first = error(dr::render_image_levels(s, cam, opt, l));
  l.per_axis = {2, 8};
  l.tolerance = 8.0f;
  dr::LevelStats st;
  const double refined = error(dr::render_image_levels(s, cam, opt, l, &st));
  MESSAGE("squared error " << first << " -> " << refined << ", " << st.mean_samples << " samples per pixel");
  CHECK(refined < 0.5 * first);
  CHECK(st.mean_samples < 0.5 * 64.0);  // the plain map stops at 2 x 2
}
