// Stage 2's training pass as the device runs it (cuda/ray_groups.hpp:
// run_ray_groups, over the host launch of cuda/host_launch.hpp) against the
// host's render::ray_group_gradient.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "support/ad_check.hpp"
#include "support/scenes.hpp"
#include "support/shapes.hpp"
#include "training_batch.hpp"

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/host_launch.hpp"
#include "difftrans/cuda/ray_groups.hpp"
#include "difftrans/render/ray_batch.hpp"

using namespace dt_test;
using difftrans::Vec3f;
using difftrans::accel::Bvh;

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
