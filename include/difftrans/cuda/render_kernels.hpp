// The tracer's per-pixel kernels, written once over an index and run by a
// CUDA launch (cuda/render.cuh) or host threads (cuda/host_launch.hpp): a
// float render, a Dual<float, 1> directional derivative and a Var<float>
// gradient with a per-thread tape of fixed capacity. They read one plain
// parameter struct, PixelJob, whose pointers are device or host pointers
// alike. run_gradient_waves, the reverse pass's schedule (waves of tapes
// that fit the memory, overflowed pixels redone on longer tapes), is written
// once over a launch backend as well, so that its host twin runs in every
// test run.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/ad/ad.hpp"
#include "difftrans/render/pass_options.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/camera.hpp"

namespace difftrans::cuda {

// Everything a pixel kernel reads and writes. Trivially copyable: it is the
// kernel's argument.
struct PixelJob {
  render::SceneView scene;            // the tracer's view (device or host pointers)
  accel::BvhView bvh;                 // the intersector
  scene::Camera camera;
  render::TraceSettings trace;
  const ad::ParamSet* params = nullptr;  // values (+ tangents, gradients) of the parameter buffers
  int samples_per_axis = 1;           // n: n² box-filtered samples per pixel, as render::PassOptions
  float* image = nullptr;             // width·height·3, written (not accumulated)
  float* derivative = nullptr;        // Dual: width·height·3, the derivative along the tangents
  const float* pixel_adjoint = nullptr;  // Var: dLoss/dpixel, width·height·3
  std::uint32_t* counters = nullptr;  // optional, see PixelCounter
};

// A job over a scene view and a BVH for one camera; its outputs (image,
// derivative, adjoint, counters) are left to the caller.
inline PixelJob pixel_job(const render::SceneView& scene, const accel::BvhView& bvh, const scene::Camera& camera,
                          const render::TraceSettings& trace, const ad::ParamSet* params, int samples_per_axis) {
  PixelJob job;
  job.scene = scene;
  job.bvh = bvh;
  job.camera = camera;
  job.trace = trace;
  job.params = params;
  job.samples_per_axis = samples_per_axis;
  return job;
}

// Counters a pass may ask for (atomically added).
enum PixelCounter : int {
  counter_segments = 0,  // rays sent to the BVH
  counter_hits = 1,      // surface interactions
  counter_overflow = 2,  // Var: rays whose tape or leaf log overflowed (part of their gradient lost)
  counter_max_tape = 3,  // Var: largest tape (nodes) of any ray (its peak in the streamed trace)
  counter_overflow_pixels = 4,  // Var: entries written to an overflow list (pixels or ray groups)
  counter_clipped_1 = 5,         // ray groups: groups whose clip class 1 was clipped (RayJob::clip)
  counter_clipped_2 = 6,         // ray groups: likewise class 2
  counter_count = 7,
};

namespace detail {

DT_HOST_DEVICE inline void counter_add(std::uint32_t* c, std::uint32_t v) {
#if DT_DEVICE_PASS
  atomicAdd(c, v);
#else
  __atomic_fetch_add(c, v, __ATOMIC_RELAXED);
#endif
}

// Raises *c to v. On the device a plain read first: most calls (every ray,
// every branch) find the maximum already above theirs and skip the atomic.
DT_HOST_DEVICE inline void counter_max(std::uint32_t* c, std::uint32_t v) {
#if DT_DEVICE_PASS
  if (v > *static_cast<volatile std::uint32_t*>(c)) atomicMax(c, v);
#else
  std::uint32_t old = __atomic_load_n(c, __ATOMIC_RELAXED);
  while (old < v && !__atomic_compare_exchange_n(c, &old, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
#endif
}

// Appends `item` to an overflow list, counted in counters[counter_overflow_pixels].
DT_HOST_DEVICE inline void list_overflow(std::uint32_t* counters, std::int32_t* list, std::int32_t item) {
#if DT_DEVICE_PASS
  const std::uint32_t k = atomicAdd(counters + counter_overflow_pixels, 1u);
#else
  const std::uint32_t k = __atomic_fetch_add(counters + counter_overflow_pixels, 1u, __ATOMIC_RELAXED);
#endif
  list[k] = item;
}

DT_HOST_DEVICE inline void add_counts(const PixelJob& job, const render::TraceStats& st) {
  if (!job.counters) return;
  counter_add(job.counters + counter_segments, std::uint32_t(st.segments));
  counter_add(job.counters + counter_hits, std::uint32_t(st.hits));
}

}  // namespace detail

// Radiance of one pixel with S = float (value) or Dual<float, N> (value and
// the derivative along lane 0's tangents, written to job.derivative).
template <class S>
struct RenderPixel {
  PixelJob job;

  DT_HOST_DEVICE void operator()(int pix) const {
    ad::ParamReader<S> reader(job.params);
    render::TraceStats st;
    float value[3] = {0.0f, 0.0f, 0.0f}, tangent[3] = {0.0f, 0.0f, 0.0f};
    render::for_each_pixel_sample(job.camera, job.samples_per_axis, pix,
                                  [&](const Vec3f& o, const Vec3f& d, float w) {
                                    const Vec3<S> L = render::trace<S>(job.scene, job.bvh, reader, o, d, job.trace, &st);
                                    for (int c = 0; c < 3; ++c) {
                                      if constexpr (ad::is_dual_v<S>) {
                                        value[c] += w * L[c].value;
                                        tangent[c] += w * L[c].grad[0];
                                      } else {
                                        value[c] += w * L[c];
                                      }
                                    }
                                  });
    for (int c = 0; c < 3; ++c) {
      job.image[3 * std::int64_t(pix) + c] = value[c];
      if (job.derivative) job.derivative[3 * std::int64_t(pix) + c] = tangent[c];
    }
    detail::add_counts(job, st);
  }
};

namespace detail {

// One pixel in reverse mode on the given tape and leaf log: per sample, the
// streamed trace (render::trace_streamed) with w · dLoss/dpixel as the
// adjoint, which scatters the leaves' adjoints into the gradient buffers
// (atomic adds) as the tree is traced, on a tape bounded by the depth. A ray
// whose tape or log overflows has lost part of its gradient and is counted.
// Writes the image if asked. adjoint_scale multiplies dLoss/dpixel: −1
// takes back exactly what a run with +1 and the same tape capacity added.
// Returns whether any of the pixel's rays overflowed.
DT_HOST_DEVICE inline bool gradient_pixel(const PixelJob& job, int pix, ad::Tape<float>& tape,
                                          ad::LeafRecord* log, std::int32_t log_capacity,
                                          float adjoint_scale = 1.0f) {
  using V = ad::Var<float>;
  ad::ParamReader<V> reader(job.params, &tape, log, log_capacity);
  render::TraceStats st;
  float value[3] = {0.0f, 0.0f, 0.0f};
  bool overflowed = false;
  const float* a = job.pixel_adjoint + 3 * std::int64_t(pix);
  render::for_each_pixel_sample(job.camera, job.samples_per_axis, pix, [&](const Vec3f& o, const Vec3f& d, float w) {
    const float ws = w * adjoint_scale;
    const Vec3f adjoint(ws * a[0], ws * a[1], ws * a[2]);
    const Vec3f L = render::trace_streamed<float>(job.scene, job.bvh, reader, o, d, adjoint, job.trace, &st);
    for (int c = 0; c < 3; ++c) value[c] += w * L[c];
    if (job.counters) counter_max(job.counters + counter_max_tape, std::uint32_t(tape.peak()));
    if (tape.overflowed() || reader.overflowed()) {
      overflowed = true;
      if (job.counters) counter_add(job.counters + counter_overflow, 1u);
    }
  });
  if (job.image)
    for (int c = 0; c < 3; ++c) job.image[3 * std::int64_t(pix) + c] = value[c];
  add_counts(job, st);
  return overflowed;
}

}  // namespace detail

// A tape of Capacity nodes and a leaf log of LogCapacity entries in the
// thread's own (local) memory.
template <int Capacity, int LogCapacity>
struct LocalTape {
  static constexpr std::size_t bytes = Capacity * ad::Tape<float>::bytes_per_node + LogCapacity * sizeof(ad::LeafRecord);
  ad::Node<float> nodes[Capacity];
  float adjoints[Capacity];
  ad::LeafRecord log[LogCapacity];
};

// Reverse mode with the tape (TapeCapacity nodes) and leaf log in the
// thread's own local memory: simplest, for scenes whose rays record few
// nodes (a ray through a grid-absorbing sphere at depth 5 records ~8000).
template <int TapeCapacity = 4096, int LogCapacity = 512>
struct GradientPixel {
  PixelJob job;

  static constexpr std::size_t tape_bytes = LocalTape<TapeCapacity, LogCapacity>::bytes;

  DT_HOST_DEVICE void operator()(int pix) const {
    LocalTape<TapeCapacity, LogCapacity> local;
    ad::Tape<float> tape(local.nodes, local.adjoints, TapeCapacity);
    detail::gradient_pixel(job, pix, tape, local.log, LogCapacity);
  }
};

// Per-thread tapes cut from one caller-owned buffer: slot s uses nodes
// [s·capacity, (s+1)·capacity), the same range of adjoints and log entries
// [s·log_capacity, ...).
struct TapePool {
  ad::Node<float>* nodes = nullptr;
  float* adjoints = nullptr;
  ad::LeafRecord* logs = nullptr;
  std::int32_t capacity = 0, log_capacity = 0;

  static constexpr std::size_t bytes_per_slot(std::int32_t capacity, std::int32_t log_capacity) {
    return std::size_t(capacity) * ad::Tape<float>::bytes_per_node + std::size_t(log_capacity) * sizeof(ad::LeafRecord);
  }
};

// Reverse mode with tapes of run-time capacity from a TapePool. A launch
// over `slots` threads handles items [first, first + slots) of
// [0, item_count): pixel = item, or pixel_list[item] when a list is given.
// A pixel whose rays overflowed is appended to overflow_list (counted in
// job.counters[counter_overflow_pixels]) when that list is given.
struct PooledGradientPixel {
  PixelJob job;
  TapePool pool;
  std::int64_t first = 0;
  std::int64_t item_count = 0;
  const std::int32_t* pixel_list = nullptr;
  float adjoint_scale = 1.0f;
  std::int32_t* overflow_list = nullptr;

  DT_HOST_DEVICE void operator()(int slot) const {
    const std::int64_t item = first + slot;
    if (item >= item_count) return;
    const int pix = pixel_list ? pixel_list[item] : int(item);
    const std::int64_t s = slot;
    ad::Tape<float> tape(pool.nodes + s * pool.capacity, pool.adjoints + s * pool.capacity, pool.capacity);
    const bool overflowed =
        detail::gradient_pixel(job, pix, tape, pool.logs + s * pool.log_capacity, pool.log_capacity, adjoint_scale);
    if (overflowed && overflow_list) detail::list_overflow(job.counters, overflow_list, pix);
  }
};

// How a reverse pass is scheduled (run_gradient_waves).
struct GradientSchedule {
  std::int32_t tape_capacity = 1 << 12;      // nodes per ray on the first try
  std::int32_t leaf_log_capacity = 1 << 10;  // parameter leaves per ray on the first try
  std::int32_t max_tape_capacity = 1 << 21;  // the longest tape an overflowed pixel is redone with
  std::size_t tape_memory = std::size_t(1) << 30;  // bytes of tapes at once: pixels run in waves that fit
};

// What run_gradient_waves did.
struct GradientWaves {
  int waves = 0;              // launches, all tries together
  std::int64_t slots = 0;     // threads of the first try's waves
  std::int64_t redone_pixels = 0;   // pixels redone on a longer tape (each try counted)
  std::int64_t dropped_pixels = 0;  // pixels that overflowed even the longest tape: gradient partial
  std::int32_t final_capacity = 0;  // the longest tape used
};

// Threads per wave: as many tapes of `bytes_per_slot` as `memory` holds,
// at least 64 (or `items`, if fewer) and at most `items`.
inline std::int64_t wave_slots(std::int64_t items, std::size_t bytes_per_slot, std::size_t memory) {
  std::int64_t slots = std::int64_t(memory / std::max<std::size_t>(bytes_per_slot, 1));
  slots = std::max<std::int64_t>(slots, 64);
  return std::max<std::int64_t>(std::min(slots, items), 0);
}

namespace detail {

// The schedule of a reverse pass over `items` work items (pixels, ray
// groups), written once over a launch backend B (device: cuda/render.cuh;
// host threads: cuda/host_launch.hpp), which offers
//   be.template make<T>(n)   an owning array of n elements (contents unset)
//                            in its memory, with data();
//   be.launch(n, kernel)     kernel(i) for i in [0, n), then waits;
//   be.read_counters(c)      copies the counter_count counters of the pass;
//   be.set_counter(i, v)     sets one of them.
// make(pool, items, list, scale, overflow_list, first_try) returns the
// kernel of one try (with a member `first`, the first item of a wave): the
// items of `list` (every item when null) on tapes of `pool`, dLoss/d output
// times `scale`, overflowed items appended to overflow_list when it is given.
// First every item in waves of tapes of schedule.tape_capacity nodes. An item
// whose tape overflowed is, with take_back, run again on the same tape with
// scale −1 (it scattered part of its gradient: this takes exactly that part
// back); then it is run on a tape 8 times longer, until none overflows or
// the longest tape is reached (those are dropped).
template <class B, class MakeKernel>
GradientWaves run_waves(B& be, std::int64_t items, const GradientSchedule& schedule, bool take_back,
                        MakeKernel&& make) {
  GradientWaves out;
  std::int32_t cap = std::max<std::int32_t>(schedule.tape_capacity, 16);
  std::int32_t log_cap = std::max<std::int32_t>(schedule.leaf_log_capacity, 16);
  auto list_a = be.template make<std::int32_t>(std::size_t(std::max<std::int64_t>(items, 1)));
  auto list_b = be.template make<std::int32_t>(std::size_t(std::max<std::int64_t>(items, 1)));
  std::int32_t* lists[2] = {list_a.data(), list_b.data()};
  const auto overflow_count = [&]() {
    std::uint32_t c[counter_count];
    be.read_counters(c);
    return std::int64_t(c[counter_overflow_pixels]);
  };
  // one try: the items of `list` (all when null) on tapes of cap / log_cap
  const auto run = [&](const std::int32_t* list, std::int64_t n, float scale, std::int32_t* overflow_list,
                       bool first_try) {
    const std::int64_t slots = wave_slots(n, TapePool::bytes_per_slot(cap, log_cap), schedule.tape_memory);
    if (slots == 0) return std::int64_t(0);
    auto nodes = be.template make<ad::Node<float>>(std::size_t(slots) * std::size_t(cap));
    auto adjoints = be.template make<float>(std::size_t(slots) * std::size_t(cap));
    auto logs = be.template make<ad::LeafRecord>(std::size_t(slots) * std::size_t(log_cap));
    auto k = make(TapePool{nodes.data(), adjoints.data(), logs.data(), cap, log_cap}, n, list, scale, overflow_list,
                  first_try);
    for (std::int64_t first = 0; first < n; first += slots) {
      k.first = first;
      be.launch(int(std::min(slots, n - first)), k);
      ++out.waves;
    }
    return slots;
  };
  be.set_counter(counter_overflow_pixels, 0u);
  out.slots = run(nullptr, items, 1.0f, lists[0], true);
  std::int64_t over = overflow_count();
  int cur = 0;
  while (over > 0) {
    if (cap >= schedule.max_tape_capacity) {
      out.dropped_pixels = over;
      break;
    }
    out.redone_pixels += over;
    if (take_back) run(lists[cur], over, -1.0f, nullptr, false);
    cap = std::int32_t(std::min<std::int64_t>(std::int64_t(cap) * 8, schedule.max_tape_capacity));
    log_cap = std::int32_t(std::min<std::int64_t>(std::int64_t(log_cap) * 8, schedule.max_tape_capacity));
    be.set_counter(counter_overflow_pixels, 0u);
    run(lists[cur], over, 1.0f, lists[1 - cur], false);
    over = overflow_count();
    cur = 1 - cur;
  }
  out.final_capacity = cap;
  return out;
}

}  // namespace detail

// The reverse pass over `pixels` pixels (detail::run_waves with the
// per-pixel streamed body, PooledGradientPixel). job.counters must point at
// the backend's counters. A pixel whose rays overflowed has scattered part
// of its gradient as it was traced: it is taken back before the redo.
template <class B>
GradientWaves run_gradient_waves(B& be, PixelJob job, std::int64_t pixels, const GradientSchedule& schedule) {
  return detail::run_waves(be, pixels, schedule, true,
                           [&](const TapePool& pool, std::int64_t items, const std::int32_t* list, float scale,
                               std::int32_t* overflow_list, bool first_try) {
                             PooledGradientPixel k{job, pool, 0, items, list, scale, overflow_list};
                             if (!first_try) k.job.image = nullptr;
                             return k;
                           });
}

}  // namespace difftrans::cuda
