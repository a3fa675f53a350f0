// Image passes: the float image matches the per-ray tracer, reverse mode
// (render_gradient) and forward mode (render_derivative) agree on an image
// loss, and both agree with central differences of a double render; the
// recomputed reverse mode gives the streamed one's gradient.
#include "support/ad_check.hpp"
#include "support/shapes.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "difftrans/render/passes.hpp"

using namespace dt_test;
namespace dr = difftrans::render;

namespace {
dr::HostScene small_scene() {
  const Shape sphere = make_icosphere(0.5f, 2);
  dr::HostScene s(sphere.positions, sphere.triangles, "sphere");
  s.ior = 1.45f;
  std::vector<float> env;
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 16; ++c) env.insert(env.end(), {0.2f + 0.05f * float(c), 0.3f + 0.08f * float(r), 0.6f});
  s.set_environment_map(env, 16, 8);
  s.set_homogeneous_absorption(Vec3f(0.4f, 0.8f, 1.6f));
  return s;
}
}  // namespace

TEST_CASE("render_image matches the tracer, pixel by pixel") {
  dr::HostScene s = small_scene();
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 24, 20);
  dr::PassOptions opt;
  opt.samples_per_axis = 2;
  dr::PassStats st;
  const std::vector<float> img = dr::render_image(s, cam, opt, &st);
  CHECK(st.rays == 24 * 20 * 4);
  const ad::ParamSet params = s.params();
  ad::ParamReader<float> reader(&params);
  for (int pix : {0, 131, 250, 479}) {
    Vec3f sum(0.0f);
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) {
        const auto r = cam.generate_ray(pix % 24, pix / 24, 0.25f + 0.5f * i, 0.25f + 0.5f * j);
        sum += dr::trace<float>(s.view(false), s.accel(), reader, r.origin, r.direction, opt.trace);
      }
    for (int c = 0; c < 3; ++c) CHECK(img[std::size_t(pix) * 3 + c] == doctest::Approx(sum[c] / 4).epsilon(1e-6));
  }
  const std::vector<double> img_d = dr::render_image<double>(s, cam, opt);
  double worst = 0;
  for (std::size_t i = 0; i < img.size(); ++i) worst = std::max(worst, std::abs(img_d[i] - img[i]));
  CHECK(worst < 1e-4);
}

TEST_CASE("reverse and forward passes agree with each other and with differences") {
  dr::HostScene s = small_scene();
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 16, 16);
  dr::PassOptions opt;
  opt.trace.max_depth = 5;
  // loss = Σ a · image with a fixed, varied adjoint
  std::vector<float> adjoint(16 * 16 * 3);
  for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = std::sin(0.7f * float(i)) + 0.5f;
  dr::SceneGradient g(s);
  dr::PassStats st;
  dr::render_gradient(s, cam, adjoint.data(), g, opt, &st);
  CHECK(st.overflowed_rays == 0);
  CHECK(st.max_tape_nodes > 0);
  // forward mode along the IoR and along one absorption channel
  const float one = 1.0f;
  const float sigma_dir[3] = {0.0f, 1.0f, 0.0f};
  const float* along_ior[dr::param_count] = {nullptr, &one, nullptr, nullptr, nullptr};
  const float* along_sigma[dr::param_count] = {nullptr, nullptr, sigma_dir, nullptr, nullptr};
  const auto dot = [&](const std::vector<float>& img) {
    double sum = 0;
    for (std::size_t i = 0; i < img.size(); ++i) sum += double(adjoint[i]) * img[i];
    return sum;
  };
  const double fwd_ior = dot(dr::render_derivative(s, cam, along_ior, opt).derivative);
  const double fwd_sigma = dot(dr::render_derivative(s, cam, along_sigma, opt).derivative);
  CHECK(g.ior[0] == doctest::Approx(fwd_ior).epsilon(1e-4));
  CHECK(g.absorption[1] == doctest::Approx(fwd_sigma).epsilon(1e-4));
  // central differences of a double render
  const auto loss_at = [&](float ior) {
    s.ior = ior;
    const std::vector<double> img = dr::render_image<double>(s, cam, opt);
    double sum = 0;
    for (std::size_t i = 0; i < img.size(); ++i) sum += double(adjoint[i]) * img[i];
    return sum;
  };
  // small steps: over a wider one some pixel's path crosses a TIR boundary
  // (measured: h = 4e-3 gives -1.027, 1e-3 -1.048, 2.5e-4 -1.0631 = reverse)
  const float h = 2.5e-4f;
  const double fd = (loss_at(1.45f + h) - loss_at(1.45f - h)) / (double(1.45f + h) - double(1.45f - h));
  s.ior = 1.45f;
  CHECK(g.ior[0] == doctest::Approx(fd).epsilon(2e-3));
}

TEST_CASE("PassOptions::recompute: the same gradient, a segment's tape per ray") {
  dr::HostScene s = small_scene();
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.2f, 0.3f, 1.0f), 16, 16);
  dr::PassOptions opt;
  opt.trace.max_depth = 8;
  opt.samples_per_axis = 2;
  std::vector<float> adjoint(16 * 16 * 3);
  for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = std::cos(0.3f * float(i)) + 0.2f;
  dr::SceneGradient streamed(s), recomputed(s);
  dr::PassStats st_streamed, st_recomputed;
  const std::vector<float> img_streamed = dr::render_gradient(s, cam, adjoint.data(), streamed, opt, &st_streamed);
  dr::PassOptions again = opt;
  again.recompute = true;
  const std::vector<float> img_recomputed =
      dr::render_gradient(s, cam, adjoint.data(), recomputed, again, &st_recomputed);
  CHECK(st_recomputed.overflowed_rays == 0);
  CHECK(st_recomputed.trace.segments == st_streamed.trace.segments);  // each segment counted once
  for (std::size_t i = 0; i < img_streamed.size(); ++i) CHECK(img_recomputed[i] == doctest::Approx(img_streamed[i]).epsilon(1e-6));
  const auto close = [](const std::vector<float>& a, const std::vector<float>& b) {
    REQUIRE(a.size() == b.size());
    float scale = 0.0f, worst = 0.0f;
    for (std::size_t i = 0; i < a.size(); ++i) {
      scale = std::max(scale, std::abs(a[i]));
      worst = std::max(worst, std::abs(a[i] - b[i]));
    }
    CHECK(scale > 0.0f);
    CHECK(worst <= 1e-4f * scale);
  };
  close(streamed.positions, recomputed.positions);
  close(streamed.ior, recomputed.ior);
  close(streamed.absorption, recomputed.absorption);
  close(streamed.environment, recomputed.environment);
  MESSAGE("largest tape: streamed ", st_streamed.max_tape_nodes, " nodes, recomputed ", st_recomputed.max_tape_nodes);
  CHECK(2 * st_recomputed.max_tape_nodes < st_streamed.max_tape_nodes);
}
