// The host twin of the device passes: the kernels of cuda/render_kernels.hpp
// (and the wavefront image of cuda/wavefront.hpp, the tree gradient of
// cuda/tree_gradient.hpp) launched on the thread pool instead of a CUDA grid, with the device's
// schedule (run_gradient_waves: waves of tapes cut from one pool, pixels
// whose tape overflowed taken back and redone on longer tapes, gradients
// accumulated with atomic adds). Whatever in a device pass depends on the
// image size runs here too, on machines without a GPU, and can be checked
// against the plain host passes (render/passes.hpp).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/core/parallel.hpp"
#include "difftrans/cuda/ray_groups.hpp"
#include "difftrans/cuda/render_kernels.hpp"
#include "difftrans/cuda/tree_gradient.hpp"
#include "difftrans/cuda/wavefront.hpp"
#include "difftrans/render/gradient_sums.hpp"
#include "difftrans/render/host_scene.hpp"

namespace difftrans::cuda {

// The launch backend of run_gradient_waves on host threads.
class HostLaunch {
 public:
  template <class T>
  std::vector<T> make(std::size_t n) {
    return std::vector<T>(n);
  }
  template <class K>
  void launch(int n, const K& kernel) {
    ThreadPool::global().parallel_for(n, 16, [&](std::int64_t b, std::int64_t e, int) {
      for (std::int64_t i = b; i < e; ++i) kernel(int(i));
    });
  }
  template <class T>
  void upload(std::vector<T>& array, const T* host, std::size_t n) {
    std::copy(host, host + n, array.begin());
  }
  template <class T>
  void download(T* host, const std::vector<T>& array, std::size_t n) {
    std::copy(array.begin(), array.begin() + std::ptrdiff_t(n), host);
  }
  std::uint32_t* counters() { return counters_; }
  void read_counters(std::uint32_t* c) const {
    for (int i = 0; i < counter_count; ++i) c[i] = __atomic_load_n(counters_ + i, __ATOMIC_RELAXED);
  }
  void set_counter(int i, std::uint32_t v) { __atomic_store_n(counters_ + i, v, __ATOMIC_RELAXED); }

 private:
  std::uint32_t counters_[counter_count] = {};
};

// The device image with branches as work items (run_wavefront) on host
// threads, over the portable BVH `bvh` of the scene's mesh; returns the
// image (width·height·3), and what the schedule did in `run`.
inline std::vector<float> twin_render_wavefront(const render::HostScene& s, const accel::Bvh& bvh,
                                                const scene::Camera& cam, const render::TraceSettings& trace,
                                                int samples_per_axis, const WavefrontSchedule& schedule,
                                                WavefrontRun* run = nullptr, std::uint32_t* counters = nullptr) {
  const std::int64_t pixels = std::int64_t(cam.width) * cam.height;
  std::vector<float> image(std::size_t(pixels) * 3, 0.0f);
  HostLaunch be;
  const ad::ParamSet params = s.params();
  PixelJob job = pixel_job(s.view(false), bvh.view(), cam, trace, &params, samples_per_axis);
  job.image = image.data();
  job.counters = be.counters();
  const WavefrontRun r = run_wavefront(be, job, pixels, schedule);
  if (run) *run = r;
  if (counters) be.read_counters(counters);
  return image;
}

// What the host twin of a reverse pass reports.
struct TwinGradientStats {
  std::uint32_t counters[counter_count] = {};
  GradientWaves waves;
};

namespace detail {

// What the host twins of the two reverse passes share: the scene's
// parameters with `grad` attached (the IoR and the absorption summed in
// double, as on the device), a job over the portable BVH with the image,
// dLoss/dpixel and the backend's counters; run(job, pixels) runs the pass.
// Returns the image.
template <class Run>
std::vector<float> twin_reverse(HostLaunch& be, const render::HostScene& s, const accel::Bvh& bvh,
                                const scene::Camera& cam, const float* pixel_adjoint, render::SceneGradient& grad,
                                const render::TraceSettings& trace, int samples_per_axis, Run&& run) {
  const std::int64_t pixels = std::int64_t(cam.width) * cam.height;
  std::vector<float> image(std::size_t(pixels) * 3, 0.0f);
  ad::ParamSet params = s.params();
  grad.attach(params);
  const render::DoubleSums sums(params);
  PixelJob job = pixel_job(s.view(true, true), bvh.view(), cam, trace, &params, samples_per_axis);
  job.image = image.data();
  job.pixel_adjoint = pixel_adjoint;
  job.counters = be.counters();
  run(job, pixels);
  sums.add_to();
  grad.fold_normals(s);
  return image;
}

}  // namespace detail

// The device reverse pass (cuda::render_gradient) on host threads, over the
// portable BVH `bvh` of the scene's mesh: adds dLoss/dparameter to `grad`
// given dLoss/dpixel; returns the image.
inline std::vector<float> twin_render_gradient(const render::HostScene& s, const accel::Bvh& bvh,
                                               const scene::Camera& cam, const float* pixel_adjoint,
                                               render::SceneGradient& grad, const render::TraceSettings& trace,
                                               int samples_per_axis, const GradientSchedule& schedule,
                                               TwinGradientStats* stats = nullptr) {
  HostLaunch be;
  GradientWaves waves;
  std::vector<float> image = detail::twin_reverse(
      be, s, bvh, cam, pixel_adjoint, grad, trace, samples_per_axis,
      [&](const PixelJob& job, std::int64_t pixels) { waves = run_gradient_waves(be, job, pixels, schedule); });
  if (stats) {
    be.read_counters(stats->counters);
    stats->waves = waves;
  }
  return image;
}

// The device reverse pass with branches as work items (run_tree_gradient) on
// host threads, over the portable BVH `bvh` of the scene's mesh: adds
// dLoss/dparameter to `grad` given dLoss/dpixel; returns the image.
// LocalCapacity / LocalLog: the tape each branch's replay has first.
template <int LocalCapacity = 512, int LocalLog = 64>
std::vector<float> twin_render_tree_gradient(const render::HostScene& s, const accel::Bvh& bvh,
                                             const scene::Camera& cam, const float* pixel_adjoint,
                                             render::SceneGradient& grad, const render::TraceSettings& trace,
                                             int samples_per_axis, const TreeSchedule& schedule,
                                             TreeGradientRun* run = nullptr, std::uint32_t* counters = nullptr) {
  HostLaunch be;
  TreeGradientRun r;
  std::vector<float> image = detail::twin_reverse(
      be, s, bvh, cam, pixel_adjoint, grad, trace, samples_per_axis, [&](const PixelJob& job, std::int64_t pixels) {
        r = run_tree_gradient<LocalCapacity, LocalLog>(be, job, pixels, schedule);
      });
  if (run) *run = r;
  if (counters) be.read_counters(counters);
  return image;
}

// The device's training pass over ray groups (cuda::ray_group_gradient:
// run_ray_groups, the radiance then the groups' clipped gradients in waves
// of tapes) on host threads, over the portable BVH `bvh` of the scene's mesh:
// rays are 6 floats each (origin, direction), `group` consecutive rays one
// group; loss(j, L, dL) as render::ray_group_gradient's. Adds the gradient to
// `grad`; returns the run (loss, counters, waves); `radiance`, if given,
// receives 3 floats per ray.
template <class Loss>
RayGroupRun twin_ray_group_gradient(const render::HostScene& s, const accel::Bvh& bvh, const std::vector<float>& rays,
                                    int group, Loss&& loss, render::SceneGradient& grad,
                                    const render::TraceSettings& trace, float clip_geometry, float clip_ior,
                                    const GradientSchedule& schedule, std::vector<float>* radiance = nullptr) {
  HostLaunch be;
  ad::ParamSet params = s.params();
  grad.attach(params);
  const render::DoubleSums wide(params);
  RayJob job;
  job.scene = s.view(true, true);
  job.bvh = bvh.view();
  job.trace = trace;
  job.params = &params;
  job.group = group;
  job.clip = render::vertex_and_ior_clip(clip_geometry, clip_ior);
  const std::int64_t n = std::int64_t(rays.size() / 6);
  std::vector<float> L(std::size_t(n) * 3, 0.0f);
  const RayGroupRun run = run_ray_groups(be, job, rays.data(), n, loss, schedule, L.data());
  wide.add_to();
  grad.fold_normals(s);
  if (radiance) *radiance = std::move(L);
  return run;
}

}  // namespace difftrans::cuda
