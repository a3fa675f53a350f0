// The tracer's per-pixel kernels, written once over an index and run by a
// CUDA launch (cuda/render.cuh) or a plain host loop: a float render, a
// Dual<float, 1> directional derivative and a Var<float> gradient with a
// per-thread tape of fixed capacity. They read one plain parameter struct,
// PixelJob, whose pointers are device or host pointers alike.
#pragma once

#include <cstdint>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/ad/ad.hpp"
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

// Counters a pass may ask for (atomically added).
enum PixelCounter : int {
  counter_segments = 0,  // rays sent to the BVH
  counter_hits = 1,      // surface interactions
  counter_overflow = 2,  // Var: rays whose tape or leaf log overflowed (part of their gradient lost)
  counter_max_tape = 3,  // Var: largest tape (nodes) of any ray (its peak in the streamed trace)
  counter_count = 4,
};

namespace detail {

DT_HOST_DEVICE inline void counter_add(std::uint32_t* c, std::uint32_t v) {
#if DT_DEVICE_PASS
  atomicAdd(c, v);
#else
  __atomic_fetch_add(c, v, __ATOMIC_RELAXED);
#endif
}

DT_HOST_DEVICE inline void counter_max(std::uint32_t* c, std::uint32_t v) {
#if DT_DEVICE_PASS
  atomicMax(c, v);
#else
  std::uint32_t old = __atomic_load_n(c, __ATOMIC_RELAXED);
  while (old < v && !__atomic_compare_exchange_n(c, &old, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
#endif
}

// Calls f(origin, direction, weight) for the n×n sub-pixel samples of pixel
// `pix`, in the order render::render_image uses.
template <class F>
DT_HOST_DEVICE void for_each_pixel_sample(const scene::Camera& cam, int n, std::int64_t pix, F&& f) {
  const float inv = 1.0f / float(n), weight = 1.0f / float(n * n);
  const int x = int(pix % cam.width), y = int(pix / cam.width);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const scene::Ray r = cam.generate_ray(x, y, (float(i) + 0.5f) * inv, (float(j) + 0.5f) * inv);
      f(r.origin, r.direction, weight);
    }
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
    detail::for_each_pixel_sample(job.camera, job.samples_per_axis, pix,
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
// Writes the image if asked.
DT_HOST_DEVICE inline void gradient_pixel(const PixelJob& job, int pix, ad::Tape<float>& tape,
                                          ad::LeafRecord* log, std::int32_t log_capacity) {
  using V = ad::Var<float>;
  ad::ParamReader<V> reader(job.params, &tape, log, log_capacity);
  render::TraceStats st;
  float value[3] = {0.0f, 0.0f, 0.0f};
  const float* a = job.pixel_adjoint + 3 * std::int64_t(pix);
  for_each_pixel_sample(job.camera, job.samples_per_axis, pix, [&](const Vec3f& o, const Vec3f& d, float w) {
    const Vec3f adjoint(w * a[0], w * a[1], w * a[2]);
    const Vec3f L = render::trace_streamed<float>(job.scene, job.bvh, reader, o, d, adjoint, job.trace, &st);
    for (int c = 0; c < 3; ++c) value[c] += w * L[c];
    if (job.counters) counter_max(job.counters + counter_max_tape, std::uint32_t(tape.peak()));
    if ((tape.overflowed() || reader.overflowed()) && job.counters) counter_add(job.counters + counter_overflow, 1u);
  });
  if (job.image)
    for (int c = 0; c < 3; ++c) job.image[3 * std::int64_t(pix) + c] = value[c];
  add_counts(job, st);
}

}  // namespace detail

// Reverse mode with the tape (TapeCapacity nodes) and leaf log in the
// thread's own local memory: simplest, for scenes whose rays record few
// nodes (a ray through a grid-absorbing sphere at depth 5 records ~8000).
template <int TapeCapacity = 4096, int LogCapacity = 512>
struct GradientPixel {
  PixelJob job;

  static constexpr std::size_t tape_bytes =
      TapeCapacity * ad::Tape<float>::bytes_per_node + LogCapacity * sizeof(ad::LeafRecord);

  DT_HOST_DEVICE void operator()(int pix) const {
    ad::Node<float> nodes[TapeCapacity];
    float adjoints[TapeCapacity];
    ad::LeafRecord log[LogCapacity];
    ad::Tape<float> tape(nodes, adjoints, TapeCapacity);
    detail::gradient_pixel(job, pix, tape, log, LogCapacity);
  }
};

// Per-thread tapes cut from one caller-owned buffer: slot s uses nodes
// [s·capacity, (s+1)·capacity), the same range of adjoints and log entries
// [s·log_capacity, ...). A launch over `slots` threads handles pixels
// [first_pixel, first_pixel + slots).
struct TapePool {
  ad::Node<float>* nodes = nullptr;
  float* adjoints = nullptr;
  ad::LeafRecord* logs = nullptr;
  std::int32_t capacity = 0, log_capacity = 0;
};

// Reverse mode with tapes of run-time capacity from a TapePool.
struct PooledGradientPixel {
  PixelJob job;
  TapePool pool;
  int first_pixel = 0;
  int pixel_count = 0;

  DT_HOST_DEVICE void operator()(int slot) const {
    const int pix = first_pixel + slot;
    if (pix >= pixel_count) return;
    const std::int64_t s = slot;
    ad::Tape<float> tape(pool.nodes + s * pool.capacity, pool.adjoints + s * pool.capacity, pool.capacity);
    detail::gradient_pixel(job, pix, tape, pool.logs + s * pool.log_capacity, pool.log_capacity);
  }
};

}  // namespace difftrans::cuda
