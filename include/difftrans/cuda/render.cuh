// The tracer on the GPU: a HostScene and its portable BVH uploaded to device
// buffers, and the passes of render/passes.hpp (image, directional derivative
// with Dual<float, 1>, gradient with Var<float>) as CUDA launches of the
// kernels in cuda/render_kernels.hpp, cuda/wavefront.hpp and
// cuda/tree_gradient.hpp. Compiled only by nvcc.
// (render/passes.hpp is not included: its host passes instantiate the tracer
// with EmbreeScene, which nvcc would warn about in every device TU.)
// Length: the device scene, the launch backend, the gradient buffers and the
// passes that share them; each pass is a short wrapper around a schedule
// written, once for the device and its host twin, in the headers above.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/launch.cuh"
#include "difftrans/cuda/ray_groups.hpp"
#include "difftrans/cuda/render_kernels.hpp"
#include "difftrans/cuda/tree_gradient.hpp"
#include "difftrans/cuda/wavefront.hpp"
#include "difftrans/render/gradient_sums.hpp"
#include "difftrans/render/host_scene.hpp"

namespace difftrans::cuda {

namespace detail {
template <class T>
std::unique_ptr<DeviceBuffer<T>> upload_vector(const std::vector<T>& v) {
  auto b = std::make_unique<DeviceBuffer<T>>(v.size());
  if (!v.empty()) b->upload(v.data());
  return b;
}
template <class T>
std::unique_ptr<DeviceBuffer<T>> upload_array(const T* p, std::size_t n) {
  auto b = std::make_unique<DeviceBuffer<T>>(n);
  if (n) b->upload(p);
  return b;
}
}  // namespace detail

// A device copy of a HostScene (mesh positions, triangles, vertex normals,
// vertex -> face adjacency, IoR, absorption parameters, environment texels)
// and of a Bvh over its mesh. Views and parameter sets it hands out hold
// device pointers, with the same buffer ids as HostScene (render::ParamId).
class DeviceScene {
 public:
  DeviceScene(const render::HostScene& s, const accel::Bvh& bvh) : host_(&s) {
    upload(s);
    upload_bvh(bvh);
  }

  // After the host scene's parameters changed (e.g. an optimizer step):
  // re-uploads every array; pass the refitted or rebuilt BVH as well.
  void update(const render::HostScene& s, const accel::Bvh& bvh) {
    upload(s);
    upload_bvh(bvh);
  }

  // The tracer's view with device pointers (ad, reverse: as HostScene::view).
  render::SceneView view(bool ad, bool reverse = false) const {
    render::SceneView v = host_->view(ad, reverse);
    v.mesh.positions.values = positions_->data();
    v.mesh.triangles = triangles_->data();
    v.mesh.vertex_normals = v.mesh.vertex_normals ? normals_->data() : nullptr;
    v.mesh.normals.values = v.mesh.normals.values ? normals_->data() : nullptr;
    v.mesh.vf_offsets = v.mesh.vf_offsets ? vf_offsets_->data() : nullptr;
    v.mesh.vf_faces = vf_faces_->data();
    v.mesh.records = nullptr;  // host memory; the device reads the arrays
    v.ior.values = ior_->data();
    v.absorption.params.values = absorption_->data();
    v.absorption.softplus_table = nullptr;  // host memory; the device evaluates softplus
    v.environment.texels.values = environment_->data();
    return v;
  }

  accel::BvhView bvh() const {
    accel::BvhView b;
    b.nodes = nodes_->data();
    b.vertices = bvh_vertices_->data();
    b.prims = prims_->data();
    b.node_count = node_count_;
    b.triangle_count = triangle_count_;
    return b;
  }

  // Values of every parameter buffer as device pointers (host-side struct).
  ad::ParamSet params() const {
    ad::ParamSet set;
    set.buffers[render::param_positions] = {positions_->data(), std::int32_t(positions_->size())};
    set.buffers[render::param_ior] = {ior_->data(), 1};
    set.buffers[render::param_absorption] = {absorption_->data(), std::int32_t(absorption_->size())};
    set.buffers[render::param_environment] = {environment_->data(), std::int32_t(environment_->size())};
    set.buffers[render::param_normals] = {normals_->data(), std::int32_t(normals_->size())};
    return set;
  }

  float* positions() { return positions_->data(); }
  const render::HostScene& host() const { return *host_; }

 private:
  void upload(const render::HostScene& s) {
    if (s.near_field)
      throw std::invalid_argument("device scene: a near-field environment (radiance field) is traced on the host only");
    host_ = &s;
    positions_ = detail::upload_vector(s.mesh.positions);
    triangles_ = detail::upload_vector(s.mesh.triangles);
    normals_ = detail::upload_vector(s.mesh.vertex_normals);
    vf_offsets_ = detail::upload_vector(s.mesh.vf_offsets);
    vf_faces_ = detail::upload_vector(s.mesh.vf_faces);
    ior_ = detail::upload_array(&s.ior, 1);
    absorption_ = detail::upload_vector(s.absorption_raw);
    environment_ = detail::upload_vector(s.environment);
  }
  void upload_bvh(const accel::Bvh& bvh) {
    nodes_ = detail::upload_vector(bvh.nodes());
    bvh_vertices_ = detail::upload_vector(bvh.vertices());
    prims_ = detail::upload_vector(bvh.prims());
    node_count_ = std::int32_t(bvh.nodes().size());
    triangle_count_ = bvh.triangle_count();
  }

  const render::HostScene* host_;
  std::unique_ptr<DeviceBuffer<float>> positions_, normals_, ior_, absorption_, environment_, bvh_vertices_;
  std::unique_ptr<DeviceBuffer<std::int32_t>> triangles_, vf_offsets_, vf_faces_, prims_;
  std::unique_ptr<DeviceBuffer<accel::BvhNode>> nodes_;
  std::int32_t node_count_ = 0, triangle_count_ = 0;
};

// As render::PassOptions, for the device passes. schedule.tape_memory = 0:
// half of the device memory free when the pass starts.
struct PassOptions {
  render::TraceSettings trace;
  int samples_per_axis = 1;  // n: n² sub-pixel samples at the centres of an n×n grid
  GradientSchedule schedule = {1 << 12, 1 << 10, 1 << 21, 0};  // reverse mode: tapes, waves, redo
  // The image: branches as work items (cuda/wavefront.hpp), or, false, a
  // thread per pixel tracing its whole trees (RenderPixel).
  bool wavefront = true;
  // The wavefront's kernel with registers capped for 16 resident blocks of
  // 64 threads (WavefrontStepCapped: 6–16% faster on an H100, docs/cuda.md),
  // or as the compiler likes.
  bool wavefront_capped = true;
  WavefrontSchedule wavefront_schedule;
  // The gradient: branches as work items (cuda/tree_gradient.hpp: the trees
  // grown in float, then each branch's interaction replayed on a tape of its
  // own, depth by depth from the deepest), or, false, a thread per pixel
  // streaming its whole trees on one tape (run_gradient_waves, `schedule`).
  bool tree_gradient = true;
  // tree_schedule.capacity = 0: as many branches as a quarter of the device
  // memory free when the pass starts holds, at most 2^26
  TreeSchedule tree_schedule = {0, {1 << 13, 1 << 10, 1 << 21, 0}};
};

// The image (value) and its derivative along a direction.
using ImageDerivative = render::ImageDerivative;

// What a device pass reports (summed over pixels and, for the gradient,
// over its tries: segments and hits count the redone pixels again).
struct DevicePassStats {
  std::uint64_t rays = 0, segments = 0, hits = 0;
  std::uint64_t overflowed_rays = 0;  // Var: rays that overflowed a tape on some try
  std::uint32_t max_tape_nodes = 0;
  GradientWaves waves;                // Var: the schedule run_gradient_waves followed (the tree gradient:
                                      // its waves, branches redone on pooled tapes, branches dropped)
  TreeGradientRun tree;               // Var with PassOptions::tree_gradient: what run_tree_gradient did
  WavefrontRun wavefront;             // the image with branches as work items: its launches
  double milliseconds = 0;            // kernel time (CUDA events); the wavefront image and the tree gradient:
                                      // wall time of their launches
};

namespace detail {
// A kernel's request for resident blocks (K::resident_blocks: launch_bounded), 0 when it has none.
template <class K, class = void>
struct resident_blocks {
  static constexpr int value = 0;
};
template <class K>
struct resident_blocks<K, std::void_t<decltype(K::resident_blocks)>> {
  static constexpr int value = K::resident_blocks;
};
}  // namespace detail

// cuda::launch (or launch_bounded, when the kernel asks for resident
// blocks), then waits for it; returns its time in milliseconds (CUDA events).
template <class K>
float timed_launch(int n, const K& kernel, int block) {
  cudaEvent_t start, stop;
  check(cudaEventCreate(&start), "cudaEventCreate");
  check(cudaEventCreate(&stop), "cudaEventCreate");
  check(cudaEventRecord(start), "cudaEventRecord");
  if constexpr (detail::resident_blocks<K>::value > 0) launch_bounded<detail::resident_blocks<K>::value>(n, kernel);
  else launch(n, kernel, block);
  check(cudaEventRecord(stop), "cudaEventRecord");
  check(cudaEventSynchronize(stop), "kernel");
  float ms = 0;
  check(cudaEventElapsedTime(&ms, start, stop), "cudaEventElapsedTime");
  cudaEventDestroy(start);
  cudaEventDestroy(stop);
  return ms;
}

// The device launch backend of run_gradient_waves: buffers in device memory,
// synchronous launches timed with CUDA events, the pass's counters.
class DeviceLaunch {
 public:
  DeviceLaunch() : counters_(counter_count) {
    const std::uint32_t zero[counter_count] = {};
    counters_.upload(zero);
  }
  template <class T>
  DeviceBuffer<T> make(std::size_t n) {
    return DeviceBuffer<T>(n);
  }
  template <class K>
  void launch(int n, const K& kernel, int block = 64) {
    milliseconds += timed_launch(n, kernel, block);
  }
  template <class T>
  void upload(DeviceBuffer<T>& array, const T* host, std::size_t n) {
    check(cudaMemcpy(array.data(), host, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
  }
  template <class T>
  void download(T* host, const DeviceBuffer<T>& array, std::size_t n) {
    check(cudaMemcpy(host, array.data(), n * sizeof(T), cudaMemcpyDeviceToHost), "download");
  }
  std::uint32_t* counters() { return counters_.data(); }
  void read_counters(std::uint32_t* c) const { counters_.download(c); }
  void set_counter(int i, std::uint32_t v) {
    check(cudaMemcpy(counters_.data() + i, &v, sizeof v, cudaMemcpyHostToDevice), "set counter");
  }
  // Half of the device memory free now.
  static std::size_t half_free_memory() {
    std::size_t free = 0, total = 0;
    check(cudaMemGetInfo(&free, &total), "cudaMemGetInfo");
    return free / 2;
  }

  double milliseconds = 0;

 private:
  DeviceBuffer<std::uint32_t> counters_;
};

namespace detail {

// Runs `kernel` over every pixel with counters and timing, synchronously.
template <class K>
void run_pixels(const K& kernel, const scene::Camera& cam, int samples, DeviceBuffer<std::uint32_t>& counters,
                DevicePassStats* stats, int block = 128) {
  const int n = cam.width * cam.height;
  const float ms = timed_launch(n, kernel, block);
  if (stats) {
    std::uint32_t c[counter_count];
    counters.download(c);
    stats->rays = std::uint64_t(n) * std::uint64_t(samples) * std::uint64_t(samples);
    stats->segments = c[counter_segments];
    stats->hits = c[counter_hits];
    stats->overflowed_rays = c[counter_overflow];
    stats->max_tape_nodes = c[counter_max_tape];
    stats->milliseconds = ms;
  }
}

// A job for the scene and camera, with device image and counter buffers.
inline PixelJob make_job(const DeviceScene& ds, bool ad, bool reverse, const scene::Camera& cam,
                         const PassOptions& opt, const ad::ParamSet* d_params, DeviceBuffer<float>& image,
                         DeviceBuffer<std::uint32_t>& counters) {
  PixelJob job = pixel_job(ds.view(ad, reverse), ds.bvh(), cam, opt.trace, d_params, opt.samples_per_axis);
  job.image = image.data();
  const std::uint32_t zero[counter_count] = {};
  counters.upload(zero);
  job.counters = counters.data();
  return job;
}

// Zeroed device gradient buffers for every parameter of a scene, set into a
// parameter set (the IoR's and the absorption's in double: render::sums_in_double);
// add_to() adds them into the host gradient afterwards.
class DeviceGradients {
 public:
  DeviceGradients(render::SceneGradient& grad, ad::ParamSet& set) {
    host_[render::param_positions] = &grad.positions;
    host_[render::param_ior] = &grad.ior;
    host_[render::param_absorption] = &grad.absorption;
    host_[render::param_environment] = &grad.environment;
    host_[render::param_normals] = &grad.normals;
    for (int b = 0; b < render::param_count; ++b) {
      const std::vector<float> zeros(host_[b]->size(), 0.0f);
      device_.push_back(upload_vector(zeros));
      set.buffers[b].gradient = device_.back()->data();
      if (render::sums_in_double(b) && !host_[b]->empty()) {
        wide_[b] = upload_vector(std::vector<double>(host_[b]->size(), 0.0));
        set.buffers[b].wide_gradient = wide_[b]->data();
      }
    }
  }
  void add_to() const {
    for (int b = 0; b < render::param_count; ++b) {
      std::vector<float> g(host_[b]->size());
      if (!g.empty()) device_[std::size_t(b)]->download(g.data());
      std::vector<double> w(wide_[b] ? wide_[b]->size() : 0);
      if (wide_[b]) wide_[b]->download(w.data());
      for (std::size_t i = 0; i < g.size(); ++i) (*host_[b])[i] += w.empty() ? g[i] : float(w[i]);
    }
  }

 private:
  std::vector<float>* host_[render::param_count] = {};
  std::vector<std::unique_ptr<DeviceBuffer<float>>> device_;
  std::unique_ptr<DeviceBuffer<double>> wide_[render::param_count];  // the buffers summed in double
};

}  // namespace detail

// Linear RGB radiance, width·height·3 floats, as render::render_image; by
// default with branches as work items (opt.wavefront).
inline std::vector<float> render_image(const DeviceScene& ds, const scene::Camera& cam,
                                       const PassOptions& opt = {}, DevicePassStats* stats = nullptr) {
  const std::size_t n = std::size_t(cam.width) * std::size_t(cam.height) * 3;
  DeviceBuffer<float> image(n);
  DeviceBuffer<std::uint32_t> counters(counter_count);
  DeviceBuffer<ad::ParamSet> params(1);
  const ad::ParamSet set = ds.params();
  params.upload(&set);
  if (!opt.wavefront) {
    const PixelJob job = detail::make_job(ds, false, false, cam, opt, params.data(), image, counters);
    detail::run_pixels(RenderPixel<float>{job}, cam, opt.samples_per_axis, counters, stats);
  } else {
    DeviceLaunch be;
    const std::vector<float> zeros(n, 0.0f);
    image.upload(zeros.data());
    PixelJob job = detail::make_job(ds, false, false, cam, opt, params.data(), image, counters);
    job.counters = be.counters();
    const auto t0 = std::chrono::steady_clock::now();
    const std::int64_t pixels = std::int64_t(cam.width) * cam.height;
    const WavefrontRun run = opt.wavefront_capped
                                 ? run_wavefront<WavefrontStepCapped>(be, job, pixels, opt.wavefront_schedule)
                                 : run_wavefront(be, job, pixels, opt.wavefront_schedule);
    const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (stats) {
      std::uint32_t c[counter_count];
      be.read_counters(c);
      *stats = DevicePassStats{};
      stats->rays = std::uint64_t(cam.width) * std::uint64_t(cam.height) * std::uint64_t(opt.samples_per_axis) *
                    std::uint64_t(opt.samples_per_axis);
      stats->segments = c[counter_segments];
      stats->hits = c[counter_hits];
      stats->wavefront = run;
      stats->milliseconds = wall;  // the launches and the queue lengths read back between them
    }
  }
  std::vector<float> out(n);
  image.download(out.data());
  return out;
}

// The image and its derivative along `direction` (host arrays, one per
// parameter buffer, null where the direction is zero), as render::render_derivative.
inline ImageDerivative render_derivative(const DeviceScene& ds, const scene::Camera& cam,
                                                 const float* const direction[render::param_count],
                                                 const PassOptions& opt = {}, DevicePassStats* stats = nullptr) {
  const std::size_t n = std::size_t(cam.width) * std::size_t(cam.height) * 3;
  DeviceBuffer<float> image(n), derivative(n);
  DeviceBuffer<std::uint32_t> counters(counter_count);
  ad::ParamSet set = ds.params();
  std::vector<std::unique_ptr<DeviceBuffer<float>>> tangents;
  for (int b = 0; b < render::param_count; ++b)
    if (direction[b]) {
      tangents.push_back(detail::upload_array(direction[b], std::size_t(set.buffers[b].size)));
      set.buffers[b].tangents[0] = tangents.back()->data();
    }
  DeviceBuffer<ad::ParamSet> params(1);
  params.upload(&set);
  PixelJob job = detail::make_job(ds, true, false, cam, opt, params.data(), image, counters);
  job.derivative = derivative.data();
  detail::run_pixels(RenderPixel<ad::Dual<float, 1>>{job}, cam, opt.samples_per_axis, counters, stats);
  ImageDerivative out;
  out.value.resize(n);
  out.derivative.resize(n);
  image.download(out.value.data());
  derivative.download(out.derivative.data());
  return out;
}

// Adds to `grad` dLoss/dparameter given dLoss/dpixel (host, width·height·3),
// as render::render_gradient. Returns the image. By default
// (opt.tree_gradient) the branches are the work items: run_tree_gradient,
// stats->tree. Otherwise a thread per pixel; its tapes: LocalTapeCapacity = 0
// (default) cuts them from device buffers, scheduled by run_gradient_waves
// (waves of as many threads as opt.schedule.tape_memory holds; pixels whose
// tape overflowed are redone on longer tapes; stats->waves.dropped_pixels
// says how many still lost part of their gradient); otherwise each thread
// keeps a tape of LocalTapeCapacity nodes in its local memory (GradientPixel),
// and a ray that overflows it loses part of its gradient (counted in
// stats->overflowed_rays). The trace is streamed (render::trace_streamed): a
// tape holds one path and the pending branches, not the tree.
template <int LocalTapeCapacity = 0, int LocalLogCapacity = 512>
std::vector<float> render_gradient(const DeviceScene& ds, const scene::Camera& cam, const float* pixel_adjoint,
                                   render::SceneGradient& grad, const PassOptions& opt = {},
                                   DevicePassStats* stats = nullptr) {
  const int pixels = cam.width * cam.height;
  const std::size_t n = std::size_t(pixels) * 3;
  DeviceBuffer<float> image(n);
  DeviceLaunch be;
  auto adjoint = detail::upload_array(pixel_adjoint, n);
  ad::ParamSet set = ds.params();
  const detail::DeviceGradients d_grads(grad, set);
  DeviceBuffer<ad::ParamSet> params(1);
  params.upload(&set);
  // two-level normals (HostScene::view(true, true)): the normals' gradient is
  // folded into the positions on the host afterwards
  PixelJob job = pixel_job(ds.view(true, true), ds.bvh(), cam, opt.trace, params.data(), opt.samples_per_axis);
  job.image = image.data();
  job.pixel_adjoint = adjoint->data();
  job.counters = be.counters();
  GradientWaves waves;
  TreeGradientRun tree;
  if constexpr (LocalTapeCapacity > 0) {
    be.launch(pixels, GradientPixel<LocalTapeCapacity, LocalLogCapacity>{job});
    waves.waves = 1;
    waves.slots = pixels;
    waves.final_capacity = LocalTapeCapacity;
  } else if (opt.tree_gradient) {
    const std::vector<float> zeros(n, 0.0f);
    image.upload(zeros.data());  // the replays add their light into it
    TreeSchedule schedule = opt.tree_schedule;
    if (schedule.capacity == 0)
      schedule.capacity = std::min<std::int64_t>(std::int64_t(1) << 26,
                                                 std::int64_t(DeviceLaunch::half_free_memory() / 2 / sizeof(TreeBranch)));
    if (schedule.redo.tape_memory == 0) schedule.redo.tape_memory = DeviceLaunch::half_free_memory() / 4;
    const auto t0 = std::chrono::steady_clock::now();
    tree = run_tree_gradient(be, job, pixels, schedule);
    // the wall time of the launches and the counts read back between them
    be.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    waves.waves = tree.waves;
    waves.slots = tree.largest_wave;
    waves.redone_pixels = tree.redone;
    waves.dropped_pixels = tree.dropped;
  } else {
    GradientSchedule schedule = opt.schedule;
    if (schedule.tape_memory == 0) schedule.tape_memory = DeviceLaunch::half_free_memory();
    waves = run_gradient_waves(be, job, pixels, schedule);
  }
  if (stats) {
    std::uint32_t c[counter_count];
    be.read_counters(c);
    stats->rays = std::uint64_t(pixels) * std::uint64_t(opt.samples_per_axis) * std::uint64_t(opt.samples_per_axis);
    stats->segments = c[counter_segments];
    stats->hits = c[counter_hits];
    stats->overflowed_rays = c[counter_overflow];
    stats->max_tape_nodes = c[counter_max_tape];
    stats->waves = waves;
    stats->tree = tree;
    stats->milliseconds = be.milliseconds;
  }
  d_grads.add_to();
  grad.fold_normals(ds.host());
  std::vector<float> out(n);
  image.download(out.data());
  return out;
}

// Stage 2's training pass on the device, as render::ray_group_gradient:
// rays (6 floats each: origin, direction) in groups of `group`; loss(j, L,
// dL) sees group j's radiances and writes dLoss/dL, on the host, between the
// radiance pass and the gradient pass (run_ray_groups). The gradient of the
// summed loss w.r.t. every buffer marked in the scene's `differentiate` is
// added to `grad`, each group's vertex gradient clipped to clip_geometry and
// its IoR derivative to clip_ior (0: no clip). Unlike the host pass, a group
// whose tape overflows is redone on a longer tape (stats->waves); the sums
// are atomic, so the last bits differ from run to run. `radiance`, if given,
// receives 3 floats per ray.
struct RayGroupStats {
  double loss = 0.0;
  std::uint64_t rays = 0, segments = 0, hits = 0;
  std::uint64_t overflowed_rays = 0;        // rays of groups that overflowed a tape on some try
  std::uint64_t clipped_geometry = 0, clipped_ior = 0;  // groups clipped
  std::uint32_t max_tape_nodes = 0;
  GradientWaves waves;
  double milliseconds = 0;                  // kernel time
};

template <class Loss>
RayGroupStats ray_group_gradient(const DeviceScene& ds, const std::vector<float>& rays, int group, Loss&& loss,
                                 render::SceneGradient& grad, const PassOptions& opt = {}, float clip_geometry = 0.0f,
                                 float clip_ior = 0.0f, std::vector<float>* radiance = nullptr) {
  DeviceLaunch be;
  ad::ParamSet set = ds.params();
  const detail::DeviceGradients d_grads(grad, set);
  DeviceBuffer<ad::ParamSet> params(1);
  params.upload(&set);
  RayJob job;
  job.scene = ds.view(true, true);
  job.bvh = ds.bvh();
  job.trace = opt.trace;
  job.params = params.data();
  job.group = group;
  job.clip = render::vertex_and_ior_clip(clip_geometry, clip_ior);
  GradientSchedule schedule = opt.schedule;
  if (schedule.tape_memory == 0) schedule.tape_memory = DeviceLaunch::half_free_memory();
  const std::int64_t n = std::int64_t(rays.size() / 6);
  std::vector<float> L(std::size_t(n) * 3, 0.0f);
  const RayGroupRun run = run_ray_groups(be, job, rays.data(), n, loss, schedule, L.data());
  d_grads.add_to();
  grad.fold_normals(ds.host());
  RayGroupStats st;
  st.loss = run.loss;
  st.rays = std::uint64_t(n);
  st.segments = run.counters[counter_segments];
  st.hits = run.counters[counter_hits];
  st.overflowed_rays = run.counters[counter_overflow];
  st.clipped_geometry = run.counters[counter_clipped_1];
  st.clipped_ior = run.counters[counter_clipped_2];
  st.max_tape_nodes = run.counters[counter_max_tape];
  st.waves = run.waves;
  st.milliseconds = be.milliseconds;
  if (radiance) *radiance = std::move(L);
  return st;
}

}  // namespace difftrans::cuda
