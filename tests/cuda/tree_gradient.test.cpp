// The device reverse pass with branches as work items (cuda/tree_gradient.hpp),
// run on host threads with the device's schedule, against the per-pixel
// reverse pass (PooledGradientPixel, run_gradient_waves) over the same BVH:
// the same image and gradients up to the order of float additions, at the
// command's sizes, with waves of camera rays far smaller than the image,
// with the drawn and roulette choices, with branches whose own tape is too
// short, and with a gradient cut at a depth.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>

#include "support/scenes.hpp"
#include "support/shapes.hpp"

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/host_launch.hpp"
#include "difftrans/cuda/tree_gradient.hpp"

using namespace dt_test;
using difftrans::Vec3f;
using difftrans::accel::Bvh;

namespace {

double relative_l2(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    den += double(b[i]) * b[i];
  }
  return std::sqrt(num / std::max(den, 1e-300));
}

double max_relative(const std::vector<float>& a, const std::vector<float>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    m = std::max(m, std::abs(double(a[i]) - double(b[i])) / (1e-3 + std::abs(double(b[i]))));
  return m;
}

std::vector<float> wavy_adjoint(const difftrans::scene::Camera& cam) {
  std::vector<float> a(std::size_t(cam.width) * cam.height * 3);
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));
  return a;
}

// The per-pixel reverse pass on host threads (long tapes, nothing redone).
struct Reference {
  std::vector<float> image;
  difftrans::render::SceneGradient grad;
  std::int64_t segments = 0;
};
Reference per_pixel(const difftrans::render::HostScene& s, const Bvh& bvh, const difftrans::scene::Camera& cam,
                    const std::vector<float>& adjoint, const difftrans::render::TraceSettings& trace, int n) {
  using namespace difftrans;
  Reference r{{}, render::SceneGradient(s), 0};
  cuda::GradientSchedule schedule;
  schedule.tape_capacity = 1 << 16;
  schedule.leaf_log_capacity = 1 << 13;
  schedule.tape_memory = std::size_t(64) << 20;
  cuda::TwinGradientStats st;
  r.image = cuda::twin_render_gradient(s, bvh, cam, adjoint.data(), r.grad, trace, n, schedule, &st);
  REQUIRE(st.waves.dropped_pixels == 0);
  r.segments = st.counters[cuda::counter_segments];
  return r;
}

// Every buffer of `g` against the reference, to `tol` relative (L2).
void check_same(const difftrans::render::SceneGradient& g, const std::vector<float>& image, const Reference& r,
                double tol) {
  CHECK(max_relative(image, r.image) < 1e-4);
  CHECK(std::abs(g.ior[0] - r.grad.ior[0]) <= tol * std::abs(r.grad.ior[0]));
  CHECK(relative_l2(g.positions, r.grad.positions) <= tol);
  CHECK(relative_l2(g.absorption, r.grad.absorption) <= tol);
  CHECK(relative_l2(g.environment, r.grad.environment) <= tol);
  CHECK(std::abs(r.grad.ior[0]) > 0.0f);
}

}  // namespace

TEST_CASE("the tree gradient equals the per-pixel gradient, at the command's sizes") {
  // spot with homogeneous absorption, IoR 1.45: 256² at depth 16 (the whole
  // Fresnel tree) and 512² at depth 4, with room for 2^16 branches at once
  // (tens of waves of camera rays)
  using namespace difftrans;
  const render::HostScene s = spot_scene();
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "spot");
  struct Size {
    int size, depth, samples_per_axis;
  };
  for (const Size sz : {Size{256, 16, 1}, Size{512, 4, 1}, Size{96, 16, 2}}) {
    CAPTURE(sz.size);
    CAPTURE(sz.depth);
    const scene::Camera cam =
        scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, sz.size, sz.size);
    render::TraceSettings trace;
    trace.max_depth = sz.depth;
    const std::vector<float> adjoint = wavy_adjoint(cam);
    const Reference ref = per_pixel(s, bvh, cam, adjoint, trace, sz.samples_per_axis);
    cuda::TreeSchedule schedule;
    schedule.capacity = std::int64_t(1) << 16;
    render::SceneGradient g(s);
    cuda::TreeGradientRun run;
    std::uint32_t counters[cuda::counter_count] = {};
    const std::vector<float> image =
        cuda::twin_render_tree_gradient(s, bvh, cam, adjoint.data(), g, trace, sz.samples_per_axis, schedule, &run,
                                        counters);
    std::printf("tree gradient %d² depth %d, %d spp: %d waves (%d grown again), %d launches, %lld branches, "
                "largest wave %lld camera rays / %lld branches, %lld redone, longest replay tape %u nodes; "
                "|dL/dIoR - per pixel| %.3g relative, positions %.3g\n",
                sz.size, sz.depth, sz.samples_per_axis * sz.samples_per_axis, run.waves, run.regrown, run.launches,
                (long long)run.branches, (long long)run.largest_wave, (long long)run.largest_tree,
                (long long)run.redone, counters[cuda::counter_max_tape],
                std::abs(g.ior[0] - ref.grad.ior[0]) / std::abs(ref.grad.ior[0]),
                relative_l2(g.positions, ref.grad.positions));
    CHECK(run.branches == ref.segments);  // every branch the per-pixel pass traced, once
    CHECK(run.waves > 4);
    CHECK(run.largest_tree <= schedule.capacity);
    CHECK(run.dropped == 0);
    CHECK(counters[cuda::counter_max_tape] < 512);  // one interaction fits the thread's own tape (run_tree_gradient's default)
    check_same(g, image, ref, 1e-4);
  }
}

TEST_CASE("the tree gradient with drawn choices, roulette, short own tapes and a depth cut") {
  // the grid-absorbing sphere (each segment reads the voxels it crosses:
  // long replay tapes) at depth 12, the tree to depth 3, roulette below 0.05;
  // the thread's own tape holds 96 nodes, so most branches are replayed
  // again on pooled tapes of 128, then 1024 nodes
  using namespace difftrans;
  const render::HostScene s = absorbing_sphere_scene(4);
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "sphere");
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.2f, -0.3f, 1.5f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.8f, 48, 40);
  render::TraceSettings trace;
  trace.max_depth = 12;
  trace.tree_depth = 3;
  trace.prune_throughput = 0.05f;
  trace.roulette = true;
  const std::vector<float> adjoint = wavy_adjoint(cam);
  cuda::TreeSchedule schedule;
  schedule.capacity = 4096;
  schedule.redo = {128, 16, 1 << 14, std::size_t(1) << 20};
  for (const int cut : {0, 3}) {
    CAPTURE(cut);
    render::TraceSettings t = trace;
    t.gradient_depth = cut;
    const Reference ref = per_pixel(s, bvh, cam, adjoint, t, 2);
    render::SceneGradient g(s);
    cuda::TreeGradientRun run;
    const std::vector<float> image =
        cuda::twin_render_tree_gradient<96, 16>(s, bvh, cam, adjoint.data(), g, t, 2, schedule, &run);
    std::printf("tree gradient, sphere, gradient depth %d: %d waves, %lld branches, %lld replayed again, "
                "%lld dropped\n",
                cut, run.waves, (long long)run.branches, (long long)run.redone, (long long)run.dropped);
    CHECK(run.branches == ref.segments);
    CHECK(run.redone > run.branches / 10);
    CHECK(run.dropped == 0);
    check_same(g, image, ref, 1e-4);
  }
  // the cut matters: the gradient cut at depth 3 is not the whole one
  render::SceneGradient whole(s), cut(s);
  render::TraceSettings t3 = trace;
  t3.gradient_depth = 3;
  cuda::twin_render_tree_gradient(s, bvh, cam, adjoint.data(), whole, trace, 2, schedule);
  cuda::twin_render_tree_gradient(s, bvh, cam, adjoint.data(), cut, t3, 2, schedule);
  CHECK(relative_l2(cut.absorption, whole.absorption) > 1e-3);

  // the longest pooled tape too short: the branches are counted as dropped, never silent
  cuda::TreeSchedule tight = schedule;
  tight.redo = {128, 16, 128, std::size_t(1) << 20};
  render::SceneGradient lost(s);
  cuda::TreeGradientRun run;
  cuda::twin_render_tree_gradient<96, 16>(s, bvh, cam, adjoint.data(), lost, trace, 2, tight, &run);
  CHECK(run.dropped > 0);
}

TEST_CASE("the tree gradient grows a wave again, smaller, when its trees do not fit") {
  using namespace difftrans;
  const render::HostScene s = spot_scene();
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "spot");
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 40, 40);
  render::TraceSettings trace;
  trace.max_depth = 16;
  const std::vector<float> adjoint = wavy_adjoint(cam);
  const Reference ref = per_pixel(s, bvh, cam, adjoint, trace, 1);
  // room for 600 branches: the first wave (75 camera rays) grows trees of
  // more than that on the object, so it is halved until it fits
  cuda::TreeSchedule schedule;
  schedule.capacity = 600;
  render::SceneGradient g(s);
  cuda::TreeGradientRun run;
  const std::vector<float> image =
      cuda::twin_render_tree_gradient(s, bvh, cam, adjoint.data(), g, trace, 1, schedule, &run);
  CHECK(run.regrown > 0);
  CHECK(run.largest_tree <= 600);
  CHECK(run.branches == ref.segments);
  check_same(g, image, ref, 1e-4);
  // a capacity below one camera ray's tree cannot work: it says so
  schedule.capacity = 2;
  render::SceneGradient none(s);
  CHECK_THROWS_AS(cuda::twin_render_tree_gradient(s, bvh, cam, adjoint.data(), none, trace, 1, schedule),
                  std::runtime_error);
}

TEST_CASE("the device reverse passes sum the IoR's and the absorption's gradients in double") {
  // the grid-absorbing sphere at 256², depth 4: every branch adds to dL/dIoR
  // and to a few voxels. Summed in float, the tree pass's dL/dIoR landed
  // 4.2e-5 and the per-pixel pass's absorption 9.4e-5 off forward mode, the
  // same way in every order (a bias: at 512² 7e-4 and 4.9e-4); in double
  // (ad::ParamBuffer::wide_gradient) both agree with forward mode
  // (Dual<float>, a pixel's derivative summed on its own) to 1e-6
  using namespace difftrans;
  const dt_test::Shape shape = dt_test::make_icosphere(0.5f, 3);
  render::HostScene s(shape.positions, shape.triangles, "sphere");
  s.ior = 1.45f;
  s.set_environment_map(dt_test::smooth_sky(32, 16), 32, 16);
  std::vector<float> raw(4 * 4 * 4 * 3);
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = scene::raw_from_sigma(0.2f + 0.1f * float(i % 7));
  s.set_grid_absorption(Vec3i(4, 4, 4), Vec3f(-0.55f), Vec3f(0.55f), raw);
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "sphere");
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 256, 256);
  render::TraceSettings trace;
  trace.max_depth = 4;
  const std::vector<float> adjoint = wavy_adjoint(cam);
  const Reference pixel = per_pixel(s, bvh, cam, adjoint, trace, 1);
  render::SceneGradient tree(s);
  cuda::twin_render_tree_gradient(s, bvh, cam, adjoint.data(), tree, trace, 1, cuda::TreeSchedule{});
  std::vector<float> dir(s.absorption_raw.size());
  for (std::size_t i = 0; i < dir.size(); ++i) dir[i] = float(i % 3) - 0.7f;
  for (const int which : {0, 1}) {  // along the IoR, along `dir` in the absorption
    CAPTURE(which);
    const float one = 1.0f;
    ad::ParamSet tangents = s.params();
    if (which == 0) tangents.buffers[render::param_ior].tangents[0] = &one;
    else tangents.buffers[render::param_absorption].tangents[0] = dir.data();
    std::vector<float> value(adjoint.size()), derivative(adjoint.size());
    cuda::PixelJob job = cuda::pixel_job(s.view(true), bvh.view(), cam, trace, &tangents, 1);
    job.image = value.data();
    job.derivative = derivative.data();
    cuda::HostLaunch be;
    be.launch(cam.width * cam.height, cuda::RenderPixel<ad::Dual<float, 1>>{job});
    double forward = 0, along_pixel = 0, along_tree = 0;
    for (std::size_t i = 0; i < adjoint.size(); ++i) forward += double(adjoint[i]) * derivative[i];
    if (which == 0) {
      along_pixel = pixel.grad.ior[0];
      along_tree = tree.ior[0];
    } else {
      for (std::size_t i = 0; i < dir.size(); ++i) {
        along_pixel += double(pixel.grad.absorption[i]) * dir[i];
        along_tree += double(tree.absorption[i]) * dir[i];
      }
    }
    std::printf("%s: forward %.7g, per-pixel %.7g, tree %.7g\n", which == 0 ? "dL/dIoR" : "dL/dabsorption along dir",
                forward, along_pixel, along_tree);
    CHECK(std::abs(forward) > 10.0);
    CHECK(std::abs(along_pixel - forward) <= 1e-5 * std::abs(forward));
    CHECK(std::abs(along_tree - forward) <= 1e-5 * std::abs(forward));
  }
}
