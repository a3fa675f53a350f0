// The image pass with branches as work items. RenderPixel gives each thread
// a whole camera ray's Fresnel tree, so a launch lasts as long as its
// deepest trees while most threads idle; here every thread takes one branch,
// sends it to the BVH through the tracer's own step (render::detail::interact),
// adds the light of an escape into its pixel and queues the branch's
// children for the next launch. The queues are kept per depth and the
// deepest non-empty one is drained first, at most half a queue per launch,
// so a launch's children always fit the (empty) queue below it and the
// memory stays bounded by the depth times one queue, whatever the size of
// the trees. Written once over a launch backend (cuda/render.cuh on the
// device, cuda/host_launch.hpp on host threads), float values only.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/ad/params.hpp"
#include "difftrans/cuda/render_kernels.hpp"
#include "difftrans/render/pass_options.hpp"
#include "difftrans/render/tracer.hpp"

// Cooperative groups under __CUDACC__ (nvcc's host and device passes), not
// only __CUDA_ARCH__: the host stub nvcc writes for a kernel refers to the
// types the device pass declared, so both passes need the declarations.
#if defined(__CUDACC__)
#include <cooperative_groups.h>
#include <cooperative_groups/reduce.h>
#include <cooperative_groups/scan.h>
#endif

namespace difftrans::cuda {

// A branch waiting in a queue: the tracer's branch, the pixel its light goes
// to and the hash of its camera ray's drawn choices.
struct QueuedBranch {
  render::detail::Branch<float> branch;
  std::int32_t pixel = 0;
  std::uint64_t ray_hash = 0;
};

namespace detail {

// Reserves k consecutive entries of a list whose length is *count; returns
// the first. On the device the threads of a warp that reserve together make
// one atomic add (of their sum) and take their offsets from a scan.
DT_HOST_DEVICE inline std::uint32_t reserve(std::uint32_t* count, std::uint32_t k) {
#if DT_DEVICE_PASS
  namespace cg = cooperative_groups;
  const cg::coalesced_group g = cg::coalesced_threads();
  const std::uint32_t total = cg::reduce(g, k, cg::plus<std::uint32_t>());
  const std::uint32_t before = cg::exclusive_scan(g, k, cg::plus<std::uint32_t>());
  std::uint32_t base = 0;
  if (g.thread_rank() == 0 && total > 0) base = atomicAdd(count, total);
  return g.shfl(base, 0) + before;
#else
  return __atomic_fetch_add(count, k, __ATOMIC_RELAXED);
#endif
}

}  // namespace detail

// One launch of the wavefront: thread i takes branch in[i], or, when `in` is
// null, the camera ray of pixel sample first + i (sample s: pixel s / n²,
// render::pixel_sample k = s mod n²). Escaped light times the sample's
// weight 1 / n² is added into job.image (which must start at zero); the
// children are appended to `out`, counted in *out_count.
struct WavefrontStep {
  PixelJob job;
  const QueuedBranch* in = nullptr;
  std::int64_t first = 0;
  QueuedBranch* out = nullptr;
  std::uint32_t* out_count = nullptr;

  DT_HOST_DEVICE void operator()(int i) const {
    ad::ParamReader<float> reader(job.params);
    const int n = job.samples_per_axis;
    QueuedBranch q;
    if (in) {
      q = in[i];
    } else {
      const std::int64_t s = first + i;
      q.pixel = std::int32_t(s / (n * n));
      const scene::Ray r = render::pixel_sample(job.camera, n, q.pixel, int(s % (n * n)));
      q.branch = render::detail::Branch<float>{r.origin, r.direction, Vec3f(1.0f), 0, 1u};
      q.ray_hash = render::detail::choice_hash(job.trace, r.origin, r.direction);
    }
    const float eta = ad::load<float>(reader, job.scene.ior, 0);
    const float weight = 1.0f / float(n * n);
    float* pixel = job.image + 3 * std::int64_t(q.pixel);
    render::TraceStats st;
    QueuedBranch children[2];
    std::uint32_t k = 0;
    render::detail::interact<float>(
        job.scene, job.bvh, reader, q.branch, eta, q.ray_hash, job.trace, st, render::DistantEscape{},
        [&](const Vec3f& light) {
          for (int c = 0; c < 3; ++c) ad::detail::atomic_add(pixel + c, weight * light[c]);
        },
        [&](const render::detail::Branch<float>& b) { children[k++] = QueuedBranch{b, q.pixel, q.ray_hash}; });
    const std::uint32_t at = detail::reserve(out_count, k);
    for (std::uint32_t c = 0; c < k; ++c) out[at + c] = children[c];
    if (job.counters) {
      detail::reserve(job.counters + counter_segments, 1u);
      detail::reserve(job.counters + counter_hits, std::uint32_t(st.hits));
    }
  }
};

// The same step, compiled with its registers capped so that 16 blocks of 64
// threads stay resident per multiprocessor (on the device; cuda/launch.cuh,
// launch_bounded): more rays in flight to hide the BVH's memory latency,
// against whatever spills.
struct WavefrontStepCapped : WavefrontStep {
  static constexpr int resident_blocks = 16;
};

// How the wavefront is scheduled: the capacity of each depth's queue
// (branches; 64 bytes each). Camera rays enter half a queue at a time.
struct WavefrontSchedule {
  std::int64_t queue_capacity = std::int64_t(1) << 21;
};

// What run_wavefront did.
struct WavefrontRun {
  int launches = 0;
  std::int64_t branches = 0;         // branches traced (segments)
  std::int64_t largest_launch = 0;   // threads
  int queues = 0;                    // depth queues allocated
};

// The image pass over `pixels` pixels with the launch backend B (as
// detail::run_waves: make, launch, upload, download): job.image must hold
// zeros; job.counters, if set, the backend's counters.
template <class Step = WavefrontStep, class B>
WavefrontRun run_wavefront(B& be, const PixelJob& job, std::int64_t pixels, const WavefrontSchedule& schedule) {
  WavefrontRun run;
  const int max_depth = std::min(job.trace.max_depth, render::max_trace_depth);
  const std::int64_t samples = pixels * job.samples_per_axis * job.samples_per_axis;
  // a queue as long as two camera waves at most, even, and counted in 32 bits
  const std::int64_t capacity =
      std::max<std::int64_t>(2, std::min({schedule.queue_capacity, 2 * samples, std::int64_t(1) << 31})) &
      ~std::int64_t(1);
  const std::int64_t wave = capacity / 2;
  using Queue = decltype(be.template make<QueuedBranch>(1));
  std::vector<Queue> queues;                    // queues[d - 1]: branches of depth d
  std::vector<std::int64_t> count(std::size_t(max_depth) + 2, 0);
  auto out_count = be.template make<std::uint32_t>(1);
  Step step;
  step.job = job;
  step.out_count = out_count.data();
  std::int64_t next = 0;  // the next camera sample
  const std::uint32_t zero = 0;
  while (true) {
    int d = max_depth;
    while (d >= 1 && count[std::size_t(d)] == 0) --d;
    if (d < 1 && next >= samples) break;
    const int from = d < 1 ? 0 : d;
    const std::int64_t m = std::min(wave, from == 0 ? samples - next : count[std::size_t(from)]);
    const bool spawns = from + 1 <= max_depth;  // the deepest branches are cut at their hit
    if (spawns && int(queues.size()) < from + 1) queues.push_back(be.template make<QueuedBranch>(std::size_t(capacity)));
    step.out = spawns ? queues[std::size_t(from)].data() : nullptr;
    if (from == 0) {
      step.in = nullptr;
      step.first = next;
      next += m;
    } else {
      count[std::size_t(from)] -= m;
      step.in = queues[std::size_t(from) - 1].data() + count[std::size_t(from)];
    }
    be.upload(out_count, &zero, 1);
    be.launch(int(m), step);
    ++run.launches;
    run.branches += m;
    run.largest_launch = std::max(run.largest_launch, m);
    if (spawns) {
      std::uint32_t made = 0;
      be.download(&made, out_count, 1);
      count[std::size_t(from) + 1] = made;
    }
  }
  run.queues = int(queues.size());
  return run;
}

}  // namespace difftrans::cuda
