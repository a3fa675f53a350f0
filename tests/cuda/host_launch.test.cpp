// The host twin of the device launch (cuda/host_launch.hpp): the reverse
// pass's schedule, run_gradient_waves, on host threads with the device's
// waves, tape pools and overflow redo, against the same per-pixel body on
// one long tape per worker.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "support/ad_check.hpp"
#include "support/scenes.hpp"
#include "support/shapes.hpp"
#include "training_batch.hpp"

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/host_launch.hpp"
#include "difftrans/render/ray_batch.hpp"

using namespace dt_test;
using difftrans::Vec3f;
using difftrans::accel::Bvh;

namespace {

// The per-pixel reverse body with one long tape per worker and no schedule:
// what run_gradient_waves must reproduce.
void plain_gradient(const difftrans::cuda::PixelJob& job, std::int64_t pixels) {
  using namespace difftrans;
  ThreadPool& pool = ThreadPool::global();
  std::vector<std::unique_ptr<ad::Tape<float>>> tapes(std::size_t(pool.size()));
  std::vector<std::vector<ad::LeafRecord>> logs(std::size_t(pool.size()));
  pool.parallel_for(pixels, 16, [&](std::int64_t b, std::int64_t e, int w) {
    auto& tape = tapes[std::size_t(w)];
    auto& log = logs[std::size_t(w)];
    if (!tape) {
      tape = std::make_unique<ad::Tape<float>>(1 << 20);
      log.resize(1 << 16);
    }
    for (std::int64_t p = b; p < e; ++p)
      cuda::detail::gradient_pixel(job, int(p), *tape, log.data(), std::int32_t(log.size()));
  });
}

double relative_l2(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    den += double(b[i]) * b[i];
  }
  return std::sqrt(num / std::max(den, 1e-30));
}

}  // namespace

TEST_CASE("the device's reverse schedule, on host threads, at the command's sizes") {
  // run_gradient_waves as the device runs it (cuda/host_launch.hpp): many
  // waves of short tapes, so that most rays overflow and are taken back and
  // redone on longer tapes; against the same per-pixel body on one long tape
  // per worker. Spot (homogeneous absorption, IoR 1.45) at 512² depth 16 and
  // 1024² depth 4, one sample per pixel.
  using namespace difftrans;
  render::HostScene s = spot_scene();
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "spot");
  struct Size {
    int size, depth;
  };
  for (const Size sz : {Size{512, 16}, Size{1024, 4}}) {
    CAPTURE(sz.size);
    const scene::Camera cam =
        scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, sz.size, sz.size);
    const std::int64_t pixels = std::int64_t(sz.size) * sz.size;
    render::TraceSettings trace;
    trace.max_depth = sz.depth;
    std::vector<float> adjoint(std::size_t(pixels) * 3);
    for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));

    // the reference: no waves, no overflow
    render::SceneGradient ref(s);
    ad::ParamSet params = s.params();
    ref.attach(params);
    std::uint32_t counters[cuda::counter_count] = {};
    cuda::PixelJob job;
    job.scene = s.view(true, true);
    job.bvh = bvh.view();
    job.camera = cam;
    job.trace = trace;
    job.params = &params;
    job.pixel_adjoint = adjoint.data();
    job.counters = counters;
    plain_gradient(job, pixels);
    ref.fold_normals(s);
    REQUIRE(counters[cuda::counter_overflow] == 0);
    const std::uint32_t longest = counters[cuda::counter_max_tape];

    // short tapes (a quarter of the longest ray's), 4 MiB of them at once
    cuda::GradientSchedule schedule;
    schedule.tape_capacity = std::int32_t(longest / 4);
    schedule.leaf_log_capacity = 64;
    schedule.tape_memory = std::size_t(4) << 20;
    render::SceneGradient twin(s);
    cuda::TwinGradientStats st;
    cuda::twin_render_gradient(s, bvh, cam, adjoint.data(), twin, trace, 1, schedule, &st);
    std::printf("%d² depth %d: longest tape %u nodes; %d waves of %lld threads, %lld pixels redone, tape %d at the end\n",
                sz.size, sz.depth, longest, st.waves.waves, (long long)st.waves.slots,
                (long long)st.waves.redone_pixels, st.waves.final_capacity);
    std::printf("  against one long tape per worker: dL/dIoR %.7g vs %.7g; relative L2 positions %.3g, absorption %.3g,"
                " environment %.3g\n",
                twin.ior[0], ref.ior[0], relative_l2(twin.positions, ref.positions),
                relative_l2(twin.absorption, ref.absorption), relative_l2(twin.environment, ref.environment));
    CHECK(st.waves.waves > 100);
    CHECK(st.waves.redone_pixels > 0);
    CHECK(st.waves.dropped_pixels == 0);
    CHECK(std::abs(twin.ior[0] - ref.ior[0]) <= 1e-4 * std::abs(ref.ior[0]));
    CHECK(relative_l2(twin.positions, ref.positions) <= 1e-4);
    CHECK(relative_l2(twin.absorption, ref.absorption) <= 1e-5);
    CHECK(relative_l2(twin.environment, ref.environment) <= 1e-5);

    // a longest tape that is still too short: the pixels are counted, never silent
    if (sz.depth == 16) {
      schedule.max_tape_capacity = std::int32_t(longest / 2);
      render::SceneGradient partial(s);
      cuda::TwinGradientStats ps;
      cuda::twin_render_gradient(s, bvh, cam, adjoint.data(), partial, trace, 1, schedule, &ps);
      CHECK(ps.waves.dropped_pixels > 0);
      CHECK(ps.waves.final_capacity == std::int32_t(longest / 2));
    }
  }
}

TEST_CASE("stage 2's training pass on the device's schedule, on host threads, against the host pass") {
  // cuda::twin_ray_group_gradient (run_ray_groups: the radiance of every ray,
  // the loss on the host, then each group's clipped gradient on one tape, in
  // waves of short tapes redone on longer ones) against
  // render::ray_group_gradient, at the training settings (depth 16, the tree
  // to depth 8, roulette, pruning at 0.01), two jittered rays per pixel of
  // two views, an L2 loss of their mean, the vertex and IoR clips on.
  using namespace difftrans;
  render::HostScene s = spot_scene();
  s.differentiate[render::param_positions] = true;
  s.differentiate[render::param_normals] = true;
  s.differentiate[render::param_ior] = true;
  s.differentiate[render::param_absorption] = true;
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "spot");
  const render::TraceSettings trace = TrainingBatch::trace();
  const TrainingBatch batch = TrainingBatch::make(96);
  const int size = 96, group = TrainingBatch::group;
  const std::vector<float>& rays6 = batch.rays;
  std::vector<render::BatchRay> rays(rays6.size() / 6);
  for (std::size_t i = 0; i < rays.size(); ++i)
    rays[i] = {Vec3f(rays6[6 * i], rays6[6 * i + 1], rays6[6 * i + 2]),
               Vec3f(rays6[6 * i + 3], rays6[6 * i + 4], rays6[6 * i + 5])};
  const std::int64_t groups = batch.groups;
  const auto loss = [&](std::int64_t j, const Vec3f* L, Vec3f* dL) { return batch.loss(j, L, dL); };
  const float clip_geometry = batch.clip_geometry, clip_ior = batch.clip_ior;

  render::SceneGradient host(s);
  render::PassOptions po;
  po.trace = trace;
  const render::RayBatchResult hr = render::ray_group_gradient<float>(s, rays, group, loss, host, po, true,
                                                                      clip_geometry, clip_ior);
  REQUIRE(hr.stats.overflowed_rays == 0);
  const std::int64_t longest = hr.stats.max_tape_nodes;

  cuda::GradientSchedule schedule;
  schedule.tape_capacity = std::int32_t(longest / 6);  // most groups overflow the first tapes
  schedule.leaf_log_capacity = 32;
  schedule.tape_memory = std::size_t(2) << 20;
  render::SceneGradient twin(s);
  std::vector<float> radiance;
  const cuda::RayGroupRun tr = cuda::twin_ray_group_gradient(s, bvh, rays6, group, loss, twin, trace, clip_geometry,
                                                             clip_ior, schedule, &radiance);
  double worst = 0.0;
  for (std::size_t i = 0; i < rays.size(); ++i)
    for (int c = 0; c < 3; ++c)
      worst = std::max(worst, std::abs(double(radiance[3 * i + std::size_t(c)]) - double(hr.radiance[i][c])));
  std::printf("ray groups: %lld groups, longest tape %lld nodes; %d waves, %lld groups redone; clipped %u / %lld"
              " (vertices), %u / %lld (IoR); loss %.9g vs %.9g; max |radiance| difference %.3g\n",
              (long long)groups, (long long)longest, tr.waves.waves, (long long)tr.waves.redone_pixels,
              tr.counters[cuda::counter_clipped_1], (long long)hr.clipped_rays,
              tr.counters[cuda::counter_clipped_2], (long long)hr.clipped_ior_rays, tr.loss, hr.loss, worst);
  std::printf("  dL/dIoR %.7g vs %.7g; relative L2 positions %.3g, absorption %.3g\n", twin.ior[0], host.ior[0],
              relative_l2(twin.positions, host.positions), relative_l2(twin.absorption, host.absorption));
  CHECK(tr.waves.redone_pixels > 0);
  CHECK(tr.waves.dropped_pixels == 0);
  CHECK(tr.counters[cuda::counter_overflow_pixels] == 0);
  CHECK(hr.clipped_rays > 0);
  CHECK(hr.clipped_ior_rays > 0);
  CHECK(std::int64_t(tr.counters[cuda::counter_clipped_1]) == hr.clipped_rays);
  CHECK(std::int64_t(tr.counters[cuda::counter_clipped_2]) == hr.clipped_ior_rays);
  CHECK(worst <= 1e-5);
  CHECK(std::abs(tr.loss - hr.loss) <= 1e-6 * hr.loss);
  CHECK(std::abs(twin.ior[0] - host.ior[0]) <= 1e-4 * std::abs(host.ior[0]));
  CHECK(relative_l2(twin.positions, host.positions) <= 1e-4);
  CHECK(relative_l2(twin.absorption, host.absorption) <= 1e-5);

  // with memory to spare the first tapes grow until every group fits at once:
  // one launch, nothing redone, the same gradient (1,024 groups across the object's middle)
  {
    const std::ptrdiff_t g0 = std::ptrdiff_t(size) * 40, g1 = g0 + 1024;
    const std::vector<render::BatchRay> few(rays.begin() + g0 * group, rays.begin() + g1 * group);
    const std::vector<float> few6(rays6.begin() + g0 * group * 6, rays6.begin() + g1 * group * 6);
    render::SceneGradient host_few(s), twin_few(s);
    const render::RayBatchResult hf =
        render::ray_group_gradient<float>(s, few, group, loss, host_few, po, false, clip_geometry, clip_ior);
    cuda::GradientSchedule roomy;
    roomy.tape_memory = std::size_t(512) << 20;
    const cuda::RayGroupRun tf = cuda::twin_ray_group_gradient(s, bvh, few6, group, loss, twin_few, trace,
                                                               clip_geometry, clip_ior, roomy);
    std::printf("  1,024 groups, 512 MiB of tapes: %d launch(es), %lld groups redone, longest tape %u nodes\n",
                tf.waves.waves, (long long)tf.waves.redone_pixels, tf.counters[cuda::counter_max_tape]);
    CHECK(tf.waves.waves == 1);
    CHECK(tf.waves.redone_pixels == 0);
    CHECK(tf.counters[cuda::counter_max_tape] > std::uint32_t(roomy.tape_capacity));  // it did grow
    CHECK(std::abs(tf.loss - hf.loss) <= 1e-6 * hf.loss);
    CHECK(relative_l2(twin_few.positions, host_few.positions) <= 1e-4);
    CHECK(std::abs(twin_few.ior[0] - host_few.ior[0]) <= 1e-4 * std::abs(host_few.ior[0]));
  }

  // the longest tape too short for some groups: they are counted, and their gradient is missing, not partial
  schedule.max_tape_capacity = std::int32_t(longest / 2);
  render::SceneGradient partial(s);
  const cuda::RayGroupRun pr = cuda::twin_ray_group_gradient(s, bvh, rays6, group, loss, partial, trace,
                                                             clip_geometry, clip_ior, schedule);
  CHECK(pr.waves.dropped_pixels > 0);
  CHECK(pr.waves.final_capacity == std::int32_t(longest / 2));
}
