// Stage 2's training pass as device kernels, written once over a launch
// backend like the image passes of cuda/render_kernels.hpp: camera rays given
// one by one (pixels of several views), in groups of a pixel's samples, their
// radiance (RayRadiance), then, with the loss's adjoints known, each group's
// gradient on one tape, clipped per clip class before it is scattered
// (GroupGradient), scheduled by run_ray_groups in waves of tapes that fit the
// memory. Launched on a GPU by cuda/render.cuh (cuda::ray_group_gradient) and
// on host threads by cuda/host_launch.hpp (twin_ray_group_gradient).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/ad/ad.hpp"
#include "difftrans/cuda/render_kernels.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/tracer.hpp"

namespace difftrans::cuda {

// Everything a ray-batch kernel reads and writes: rays given one by one (an
// origin and a direction each: pixels of several views, as stage 2 draws
// them) in groups of `group` consecutive rays, the samples of one pixel, whose
// loss is known only once the whole group is traced. Trivially copyable.
struct RayJob {
  render::SceneView scene;
  accel::BvhView bvh;
  render::TraceSettings trace;
  const ad::ParamSet* params = nullptr;
  const float* rays = nullptr;       // origin xyz, direction xyz per ray
  int group = 1;                     // rays per group
  float* radiance = nullptr;         // RayRadiance: 3 per ray, written
  const float* adjoint = nullptr;    // GroupGradient: dLoss/dradiance, 3 per ray
  // GroupGradient: a group's gradient capped per clip class
  // (ad::ParamReader::scatter_clipped; render::vertex_and_ior_clip)
  render::GroupClip clip;
  std::uint32_t* counters = nullptr;  // optional, see PixelCounter
};

// The radiance along ray i (plain float).
struct RayRadiance {
  RayJob job;

  DT_HOST_DEVICE void operator()(int i) const {
    ad::ParamReader<float> reader(job.params);
    render::TraceStats st;
    const float* r = job.rays + 6 * std::int64_t(i);
    const Vec3f L = render::trace<float>(job.scene, job.bvh, reader, Vec3f(r[0], r[1], r[2]), Vec3f(r[3], r[4], r[5]),
                                         job.trace, &st);
    for (int c = 0; c < 3; ++c) job.radiance[3 * std::int64_t(i) + c] = L[c];
    if (job.counters) {
      detail::counter_add(job.counters + counter_segments, std::uint32_t(st.segments));
      detail::counter_add(job.counters + counter_hits, std::uint32_t(st.hits));
    }
  }
};

// The gradient of Σ adjoint · radiance over one group of rays, given the
// adjoints (the loss's, from the radiance of RayRadiance), with the group's
// gradient clipped per clip class (as render::ray_group_gradient clips the
// vertices' and the IoR's):
// every ray of the group traced on one tape (the whole tree: the clip needs
// the group's gradient before any of it is scattered), each seeded as it
// ends, one sweep, then the scatter. A group whose tape or leaf log overflows
// scatters nothing and is appended to overflow_list (to be redone on a longer
// tape); a group whose adjoints are all zero is not traced.
struct GroupGradient {
  RayJob job;
  TapePool pool;
  std::int64_t first = 0;
  std::int64_t item_count = 0;
  const std::int32_t* group_list = nullptr;
  std::int32_t* overflow_list = nullptr;

  DT_HOST_DEVICE void operator()(int slot) const {
    using V = ad::Var<float>;
    const std::int64_t item = first + slot;
    if (item >= item_count) return;
    const std::int32_t g = group_list ? group_list[item] : std::int32_t(item);
    const std::int64_t r0 = std::int64_t(g) * job.group;
    bool any = false;
    for (std::int64_t k = 3 * r0; k < 3 * (r0 + job.group); ++k) any = any || job.adjoint[k] != 0.0f;
    if (!any) return;
    const std::int64_t s = slot;
    ad::Tape<float> tape(pool.nodes + s * pool.capacity, pool.adjoints + s * pool.capacity, pool.capacity);
    ad::ParamReader<V> reader(job.params, &tape, pool.logs + s * pool.log_capacity, pool.log_capacity);
    tape.reset();
    tape.zero_on_push(true);  // each node's adjoint starts at zero: a ray is seeded as soon as it ends
    render::TraceStats st;
    for (std::int64_t q = r0; q < r0 + job.group; ++q) {
      const float* r = job.rays + 6 * q;
      const Vec3<V> L =
          render::trace<V>(job.scene, job.bvh, reader, Vec3f(r[0], r[1], r[2]), Vec3f(r[3], r[4], r[5]), job.trace, &st);
      for (int c = 0; c < 3; ++c) tape.seed(L[c], job.adjoint[3 * q + c]);
    }
    tape.zero_on_push(false);
    if (job.counters) {
      detail::counter_add(job.counters + counter_segments, std::uint32_t(st.segments));
      detail::counter_add(job.counters + counter_hits, std::uint32_t(st.hits));
      detail::counter_max(job.counters + counter_max_tape, std::uint32_t(tape.size()));
    }
    if (tape.overflowed() || reader.overflowed()) {
      if (job.counters) detail::counter_add(job.counters + counter_overflow, std::uint32_t(job.group));
      if (overflow_list) detail::list_overflow(job.counters, overflow_list, g);
      reader.clear();
      return;
    }
    tape.propagate();
    const int capped = reader.scatter_clipped(job.clip.classes, job.clip.caps);
    if (job.counters) {
      if (capped & 1) detail::counter_add(job.counters + counter_clipped_1, 1u);
      if (capped & 2) detail::counter_add(job.counters + counter_clipped_2, 1u);
    }
  }
};

// What run_ray_groups did.
struct RayGroupRun {
  double loss = 0.0;                  // Σ of the groups' losses
  std::uint32_t counters[counter_count] = {};  // of both passes (segments, hits) and the schedule
  GradientWaves waves;
};

// Stage 2's training pass over a launch backend (as run_waves', plus
//   be.upload(array, host, n) / be.download(host, array, n)):
// the radiance of every ray (RayRadiance), then loss(j, L, dL) on the host
// for each group j (L: its rays' radiances; it writes dLoss/dL and returns
// the group's loss), then the groups' gradients (GroupGradient) in waves of
// tapes that fit schedule.tape_memory, the overflowed groups redone on
// longer tapes. job: scene, bvh, trace, params (whose gradient buffers
// receive the gradient), group and clips; its rays, radiance, adjoint and
// counters are set here. `radiance` (host, 3 per ray) receives the radiance.
template <class B, class Loss>
RayGroupRun run_ray_groups(B& be, RayJob job, const float* rays, std::int64_t ray_count, Loss&& loss,
                           const GradientSchedule& schedule, float* radiance) {
  RayGroupRun out;
  const int group = job.group < 1 ? 1 : job.group;
  job.group = group;
  const std::int64_t groups = ray_count / group;
  auto d_rays = be.template make<float>(std::size_t(std::max<std::int64_t>(ray_count, 1)) * 6);
  auto d_radiance = be.template make<float>(std::size_t(std::max<std::int64_t>(ray_count, 1)) * 3);
  auto d_adjoint = be.template make<float>(std::size_t(std::max<std::int64_t>(ray_count, 1)) * 3);
  if (ray_count > 0) be.upload(d_rays, rays, std::size_t(ray_count) * 6);
  job.rays = d_rays.data();
  job.radiance = d_radiance.data();
  job.adjoint = d_adjoint.data();
  job.counters = be.counters();
  for (int c = 0; c < counter_count; ++c) be.set_counter(c, 0u);
  be.launch(int(ray_count), RayRadiance{job});
  if (ray_count > 0) be.download(radiance, d_radiance, std::size_t(ray_count) * 3);
  std::vector<float> adjoint(std::size_t(ray_count) * 3, 0.0f);
  std::vector<Vec3f> values(static_cast<std::size_t>(group)), adjoints(static_cast<std::size_t>(group));
  Vec3f* const L = values.data();
  Vec3f* const dL = adjoints.data();
  for (std::int64_t j = 0; j < groups; ++j) {
    const std::size_t r0 = std::size_t(j) * std::size_t(group);
    for (std::size_t q = 0; q < std::size_t(group); ++q) {
      const float* c = radiance + 3 * (r0 + q);
      L[q] = Vec3f(c[0], c[1], c[2]);
      dL[q] = Vec3f(0.0f);
    }
    out.loss += loss(j, static_cast<const Vec3f*>(L), dL);
    for (std::size_t q = 0; q < std::size_t(group); ++q)
      for (int c = 0; c < 3; ++c) adjoint[3 * (r0 + q) + std::size_t(c)] = dL[q][c];
  }
  if (ray_count > 0) be.upload(d_adjoint, adjoint.data(), adjoint.size());
  // the first tapes as long as the memory holds for every group at once (up
  // to 65,536 nodes): the deep groups then run beside the others instead of
  // in later waves of their own, each as long as its slowest thread
  GradientSchedule first = schedule;
  while (first.tape_capacity < (1 << 16) && first.tape_capacity < schedule.max_tape_capacity &&
         std::size_t(groups) * TapePool::bytes_per_slot(2 * first.tape_capacity, 2 * first.leaf_log_capacity) <=
             schedule.tape_memory) {
    first.tape_capacity *= 2;
    first.leaf_log_capacity *= 2;
  }
  out.waves = detail::run_waves(be, groups, first, false,
                                [&](const TapePool& pool, std::int64_t items, const std::int32_t* list, float,
                                    std::int32_t* overflow_list, bool) {
                                  return GroupGradient{job, pool, 0, items, list, overflow_list};
                                });
  be.read_counters(out.counters);
  return out;
}

}  // namespace difftrans::cuda
