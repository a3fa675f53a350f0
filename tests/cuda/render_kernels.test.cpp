// The device pixel kernels of cuda/render_kernels.hpp compiled by the host
// compiler and run in a loop — the same code the CUDA launches run — against
// the host passes render_image, render_derivative and render_gradient.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "support/ad_check.hpp"
#include "support/scenes.hpp"
#include "support/shapes.hpp"

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/render_kernels.hpp"
#include "difftrans/render/passes.hpp"

using namespace dt_test;
using difftrans::Vec3f;
using difftrans::accel::Bvh;


TEST_CASE("the device pixel kernels, run on the host, match the host passes") {
  // cuda/render_kernels.hpp compiled by the host compiler and run in a loop:
  // the same code the CUDA launches run, against render_image,
  // render_derivative and render_gradient (which use Embree)
  using namespace difftrans;
  const render::HostScene s = absorbing_sphere_scene(3);
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "sphere");
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.2f, -0.3f, 1.5f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.8f, 24, 20);
  render::PassOptions opt;
  opt.trace.max_depth = 5;
  opt.samples_per_axis = 2;
  const int pixels = cam.width * cam.height;
  const std::size_t n = std::size_t(pixels) * 3;
  std::uint32_t counters[cuda::counter_count] = {};
  const auto make_job = [&](bool ad, const ad::ParamSet* params, bool reverse = false) {
    cuda::PixelJob job;
    job.scene = s.view(ad, reverse);
    job.bvh = bvh.view();
    job.camera = cam;
    job.trace = opt.trace;
    job.params = params;
    job.samples_per_axis = opt.samples_per_axis;
    job.counters = counters;
    return job;
  };
  const auto max_abs_diff = [](const std::vector<float>& a, const std::vector<float>& b) {
    double m = 0;
    for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(double(a[i]) - double(b[i])));
    return m;
  };

  // float
  const ad::ParamSet values = s.params();
  std::vector<float> image(n, -1.0f);
  cuda::PixelJob job = make_job(false, &values);
  job.image = image.data();
  const cuda::RenderPixel<float> render_pixel{job};
  for (int p = 0; p < pixels; ++p) render_pixel(p);
  render::PassStats st;
  const std::vector<float> reference = render::render_image(s, cam, opt, &st);
  CHECK(max_abs_diff(image, reference) <= 1e-5);
  CHECK(counters[cuda::counter_segments] == std::uint32_t(st.trace.segments));
  CHECK(counters[cuda::counter_hits] == std::uint32_t(st.trace.hits));
  CHECK(st.trace.hits > pixels);  // the sphere fills a good part of the view

  // Dual<float, 1> along the IoR and the absorption
  std::vector<float> dir_abs(s.absorption_raw.size());
  for (std::size_t i = 0; i < dir_abs.size(); ++i) dir_abs[i] = float(i % 3) - 0.7f;
  const float one = 1.0f;
  const float* direction[render::param_count] = {nullptr, &one, dir_abs.data(), nullptr};
  ad::ParamSet tangents = s.params();
  for (int b = 0; b < render::param_count; ++b) tangents.buffers[b].tangents[0] = direction[b];
  std::vector<float> value(n), derivative(n);
  job = make_job(true, &tangents);
  job.image = value.data();
  job.derivative = derivative.data();
  const cuda::RenderPixel<ad::Dual<float, 1>> dual_pixel{job};
  for (int p = 0; p < pixels; ++p) dual_pixel(p);
  const render::ImageDerivative ref_d = render::render_derivative(s, cam, direction, opt);
  CHECK(max_abs_diff(value, ref_d.value) <= 1e-5);
  CHECK(max_abs_diff(derivative, ref_d.derivative) <= 1e-4);
  CHECK(std::any_of(derivative.begin(), derivative.end(), [](float x) { return std::abs(x) > 1e-2f; }));

  // Var<float>: tapes in the kernel's own arrays (GradientPixel) and cut
  // from a pool in waves of 7 threads (PooledGradientPixel)
  std::vector<float> adjoint(n);
  for (std::size_t i = 0; i < n; ++i) adjoint[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));
  render::SceneGradient ref_g(s);
  render::PassStats gst;
  render::render_gradient(s, cam, adjoint.data(), ref_g, opt, &gst);
  const auto rel = [](const std::vector<float>& a, const std::vector<float>& b) {
    double num = 0, den = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
      den += double(b[i]) * b[i];
    }
    return std::sqrt(num / std::max(den, 1e-30));
  };
  for (int pooled = 0; pooled < 2; ++pooled) {
    CAPTURE(pooled);
    render::SceneGradient g(s);
    ad::ParamSet grads = s.params();
    g.attach(grads);
    std::vector<float> gimage(n);
    std::fill(counters, counters + cuda::counter_count, 0u);
    job = make_job(true, &grads, true);
    job.image = gimage.data();
    job.pixel_adjoint = adjoint.data();
    if (pooled) {
      const int slots = 7, cap = 1 << 14, log_cap = 1 << 11;
      std::vector<ad::Node<float>> nodes(std::size_t(slots * cap));
      std::vector<float> adjoints(std::size_t(slots * cap));
      std::vector<ad::LeafRecord> logs(std::size_t(slots * log_cap));
      cuda::PooledGradientPixel k{job, cuda::TapePool{nodes.data(), adjoints.data(), logs.data(), cap, log_cap}, 0,
                                  pixels};
      for (int first = 0; first < pixels; first += slots) {
        k.first = first;
        for (int slot = 0; slot < slots; ++slot) k(slot);
      }
    } else {
      const auto local = std::make_unique<cuda::GradientPixel<1 << 14, 1 << 11>>(cuda::GradientPixel<1 << 14, 1 << 11>{job});
      for (int p = 0; p < pixels; ++p) (*local)(p);
    }
    g.fold_normals(s);  // two-level normals, as the passes do after their sweep
    CHECK(counters[cuda::counter_overflow] == 0);
    CHECK(counters[cuda::counter_max_tape] == std::uint32_t(gst.max_tape_nodes));
    CHECK(max_abs_diff(gimage, reference) <= 1e-5);
    CHECK(std::abs(g.ior[0] - ref_g.ior[0]) <= 1e-4 * std::abs(ref_g.ior[0]));
    CHECK(rel(g.positions, ref_g.positions) <= 1e-4);
    CHECK(rel(g.absorption, ref_g.absorption) <= 1e-4);
    CHECK(rel(g.environment, ref_g.environment) <= 1e-4);
    // the IoR gradient agrees with the Dual derivative along the IoR alone
    const float* ior_only[render::param_count] = {nullptr, &one, nullptr, nullptr};
    const render::ImageDerivative d_ior = render::render_derivative(s, cam, ior_only, opt);
    double dot = 0;
    for (std::size_t i = 0; i < n; ++i) dot += double(adjoint[i]) * d_ior.derivative[i];
    CHECK(std::abs(dot) > 1e-2);
    CHECK(g.ior[0] == doctest::Approx(dot).epsilon(1e-3));
  }
  std::printf("gradient kernel: largest tape %d nodes\n", gst.max_tape_nodes);
  {
    // a homogeneous-absorption sphere at depth 4 records few nodes per ray
    render::HostScene h = sphere_scene();
    render::SceneGradient hg(h);
    render::PassOptions ho;
    ho.trace.max_depth = 4;
    render::PassStats hs;
    render::render_gradient(h, cam, adjoint.data(), hg, ho, &hs);
    CHECK(hs.max_tape_nodes < 4096);  // tests/cuda/render.test.cu runs this case with GradientPixel<4096>
  }

  // a tape too small: every ray that needs more is dropped and counted
  std::fill(counters, counters + cuda::counter_count, 0u);
  render::SceneGradient small(s);
  ad::ParamSet small_set = s.params();
  small.attach(small_set);
  job = make_job(true, &small_set, true);
  job.image = nullptr;
  job.pixel_adjoint = adjoint.data();
  const cuda::GradientPixel<64, 16> tiny{job};
  for (int p = 0; p < pixels; ++p) tiny(p);
  CHECK(counters[cuda::counter_overflow] > 0);
}

