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

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/host_launch.hpp"

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
    const render::DoubleSums wide(params);  // summed as the device sums (the IoR, the absorption in double)
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
    wide.add_to();
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
