// The device image with branches as work items (cuda/wavefront.hpp), run on
// host threads with the device's queues, against the image of a thread per
// pixel (RenderPixel) over the same BVH: equal up to the order of float
// additions, at the command's sizes, with queues short enough that most
// launches take part of a queue, and with the drawn and roulette choices.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <vector>

#include <doctest/doctest.h>

#include "support/scenes.hpp"
#include "support/shapes.hpp"

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/host_launch.hpp"
#include "difftrans/cuda/wavefront.hpp"

using namespace dt_test;
using difftrans::Vec3f;
using difftrans::accel::Bvh;

namespace {

// The image of a thread per pixel (the tracer's own loop) on host threads.
std::vector<float> per_pixel_image(const difftrans::render::HostScene& s, const Bvh& bvh,
                                   const difftrans::scene::Camera& cam, const difftrans::render::TraceSettings& trace,
                                   int samples_per_axis, std::uint32_t* counters) {
  using namespace difftrans;
  const int pixels = cam.width * cam.height;
  std::vector<float> image(std::size_t(pixels) * 3, 0.0f);
  const ad::ParamSet params = s.params();
  cuda::PixelJob job = cuda::pixel_job(s.view(false), bvh.view(), cam, trace, &params, samples_per_axis);
  job.image = image.data();
  job.counters = counters;
  cuda::HostLaunch be;
  be.launch(pixels, cuda::RenderPixel<float>{job});
  return image;
}

// The largest |a − b| / (1e-3 + |b|) over the pixels' values.
double max_relative(const std::vector<float>& a, const std::vector<float>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    m = std::max(m, std::abs(double(a[i]) - double(b[i])) / (1e-3 + std::abs(double(b[i]))));
  return m;
}

}  // namespace

TEST_CASE("the wavefront image equals a thread per pixel, at the command's sizes") {
  // spot with homogeneous absorption, IoR 1.45: 512² at depth 16 (the full
  // Fresnel tree) and 1024² at depth 4; the queues hold 2^18 branches, so
  // the camera rays come in several waves and the deep queues in slices
  using namespace difftrans;
  const render::HostScene s = spot_scene();
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "spot");
  struct Size {
    int size, depth, samples_per_axis;
  };
  for (const Size sz : {Size{512, 16, 1}, Size{1024, 4, 1}, Size{128, 16, 3}}) {
    CAPTURE(sz.size);
    CAPTURE(sz.depth);
    const scene::Camera cam =
        scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, sz.size, sz.size);
    render::TraceSettings trace;
    trace.max_depth = sz.depth;
    std::uint32_t pixel_counters[cuda::counter_count] = {}, wave_counters[cuda::counter_count] = {};
    const std::vector<float> reference = per_pixel_image(s, bvh, cam, trace, sz.samples_per_axis, pixel_counters);
    cuda::WavefrontSchedule schedule;
    schedule.queue_capacity = std::int64_t(1) << 18;
    cuda::WavefrontRun run;
    const std::vector<float> image =
        cuda::twin_render_wavefront(s, bvh, cam, trace, sz.samples_per_axis, schedule, &run, wave_counters);
    std::printf("wavefront %d² depth %d, %d spp: %d launches (largest %lld), %lld branches, %d queues; "
                "max relative difference %.3g\n",
                sz.size, sz.depth, sz.samples_per_axis * sz.samples_per_axis, run.launches,
                (long long)run.largest_launch, (long long)run.branches, run.queues, max_relative(image, reference));
    // every branch the per-pixel loop traced, and no other
    CHECK(std::int64_t(wave_counters[cuda::counter_segments]) == std::int64_t(pixel_counters[cuda::counter_segments]));
    CHECK(run.branches == std::int64_t(pixel_counters[cuda::counter_segments]));
    CHECK(wave_counters[cuda::counter_hits] == pixel_counters[cuda::counter_hits]);
    CHECK(run.largest_launch <= schedule.queue_capacity / 2);
    CHECK(run.queues == sz.depth);
    CHECK(max_relative(image, reference) < 1e-4);
  }
}

TEST_CASE("the wavefront keeps the drawn and roulette choices of each camera ray") {
  // beyond the tree a branch draws reflection or refraction, and the
  // roulette keeps dim branches by chance: both from the camera ray's hash,
  // which the queued branches carry; the grid-absorbing sphere at depth 12
  // with tiny queues (most launches a slice of 16 branches)
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
  std::uint32_t pixel_counters[cuda::counter_count] = {}, wave_counters[cuda::counter_count] = {};
  const std::vector<float> reference = per_pixel_image(s, bvh, cam, trace, 2, pixel_counters);
  cuda::WavefrontSchedule schedule;
  schedule.queue_capacity = 32;
  cuda::WavefrontRun run;
  const std::vector<float> image = cuda::twin_render_wavefront(s, bvh, cam, trace, 2, schedule, &run, wave_counters);
  CHECK(run.largest_launch == 16);
  CHECK(run.launches > run.branches / 16);
  CHECK(std::int64_t(wave_counters[cuda::counter_segments]) == std::int64_t(pixel_counters[cuda::counter_segments]));
  CHECK(max_relative(image, reference) < 1e-4);
  // the choices matter: the same image without them differs
  render::TraceSettings full = trace;
  full.tree_depth = render::max_trace_depth;
  full.roulette = false;
  full.prune_throughput = 0.0f;
  const std::vector<float> tree = cuda::twin_render_wavefront(s, bvh, cam, full, 2, schedule);
  CHECK(max_relative(tree, reference) > 1e-3);
}
