// Host passes of the tracer over a camera image, on the thread pool:
//   render_image       float radiance per pixel;
//   render_gradient    reverse mode: given dLoss/dpixel, the gradient of the
//                      loss w.r.t. every parameter buffer (one tape per worker,
//                      each ray streamed through it: render/tracer.hpp,
//                      trace_streamed, or trace_recomputed with
//                      PassOptions::recompute; leaf adjoints scattered as it
//                      goes);
//   render_derivative  forward mode: the image and its derivative along one
//                      direction in parameter space (Dual<float, 1>).
// Pixel values are box-filtered over n×n stratified sub-pixel positions.
// Rays that leave the object read the scene's escape (HostScene::with_escape:
// its near field when set, else the distant map); render_image_with takes an
// explicit escape (e.g. synth's procedural room).
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "difftrans/core/parallel.hpp"
#include "difftrans/render/gradient_sums.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/pass_options.hpp"
#include "difftrans/render/recomputed_trace.hpp"
#include "difftrans/scene/camera.hpp"

namespace difftrans::render {

struct PassStats {
  TraceStats trace;
  std::int64_t rays = 0;
  std::int64_t tape_nodes = 0;      // each ray's largest tape, summed over rays (reverse mode)
  std::int32_t max_tape_nodes = 0;  // largest single ray
  std::int64_t overflowed_rays = 0; // rays whose tape or leaf log overflowed (their gradient is dropped)
  void add(const PassStats& o) {
    trace.add(o.trace);
    rays += o.rays;
    tape_nodes += o.tape_nodes;
    max_tape_nodes = max_tape_nodes > o.max_tape_nodes ? max_tape_nodes : o.max_tape_nodes;
    overflowed_rays += o.overflowed_rays;
  }
};

namespace detail {

// Calls f(pixel, origin, direction, weight) for every sample
// (for_each_pixel_sample) of every pixel index in [p0, p1).
template <class F>
void for_each_sample(const scene::Camera& cam, int n, std::int64_t p0, std::int64_t p1, F&& f) {
  for (std::int64_t pix = p0; pix < p1; ++pix)
    for_each_pixel_sample(cam, n, pix, [&](const Vec3f& o, const Vec3f& d, float w) { f(pix, o, d, w); });
}

// Per-worker accumulation of statistics.
struct StatsPerWorker {
  std::vector<PassStats> per;
  explicit StatsPerWorker(int workers) : per(std::size_t(workers)) {}
  PassStats total() const {
    PassStats s;
    for (const auto& p : per) s.add(p);
    return s;
  }
};

// One tape and leaf log per pool worker (reverse-mode passes), made on first use.
template <class T>
class WorkerTapes {
 public:
  WorkerTapes(int workers, const PassOptions& opt) : tapes_(std::size_t(workers)), logs_(std::size_t(workers)), opt_(opt) {}
  // The reader of worker w over `params`, recording on the worker's tape (reader.tape()).
  ad::ParamReader<ad::Var<T>> reader(int w, const ad::ParamSet* params) {
    auto& tape = tapes_[std::size_t(w)];
    auto& log = logs_[std::size_t(w)];
    if (!tape) {
      tape = std::make_unique<ad::Tape<T>>(opt_.tape_capacity);
      log.resize(std::size_t(opt_.leaf_log_capacity));
    }
    return ad::ParamReader<ad::Var<T>>(params, tape.get(), log.data(), std::int32_t(log.size()));
  }

 private:
  std::vector<std::unique_ptr<ad::Tape<T>>> tapes_;
  std::vector<std::vector<ad::LeafRecord>> logs_;
  const PassOptions& opt_;
};

}  // namespace detail

namespace detail {

// A forward pass over every sample of every pixel (pixel_sample's order):
// trace_sample(reader, pixel, k, trace_stats) returns sample k's radiance,
// read through a ParamReader<S> of `params` (plain or Dual); accumulate(pixel
// · 3, radiance, weight) adds it to the caller's images.
template <class S, class TraceSample, class Accumulate>
void sample_pass(const ad::ParamSet& params, const scene::Camera& cam, int n, PassStats* stats,
                 TraceSample&& trace_sample, Accumulate&& accumulate) {
  ThreadPool& pool = ThreadPool::global();
  StatsPerWorker st(pool.size());
  const float weight = 1.0f / float(n * n);
  pool.parallel_for(std::int64_t(cam.width) * cam.height, 64, [&](std::int64_t b, std::int64_t e, int w) {
    ad::ParamReader<S> reader(&params);
    PassStats& ps = st.per[std::size_t(w)];
    for (std::int64_t pix = b; pix < e; ++pix)
      for (int k = 0; k < n * n; ++k) {
        accumulate(std::size_t(pix) * 3, trace_sample(reader, pix, k, ps.trace), weight);
        ++ps.rays;
      }
  });
  if (stats) *stats = st.total();
}

// The forward pass of the tracer (plain or Dual): each sample's camera ray
// traced with scalar S.
template <class S, class Escape, class Accumulate>
void forward_pass(const HostScene& s, const SceneView& view, const ad::ParamSet& params, const scene::Camera& cam,
                  const PassOptions& opt, PassStats* stats, const Escape& escape, Accumulate&& accumulate) {
  const int n = opt.samples_per_axis;
  sample_pass<S>(
      params, cam, n, stats,
      [&](ad::ParamReader<S>& reader, std::int64_t pix, int k, TraceStats& ts) {
        const scene::Ray r = pixel_sample(cam, n, pix, k);
        return trace<S>(view, s.accel(), reader, r.origin, r.direction, opt.trace, &ts, escape);
      },
      accumulate);
}

}  // namespace detail

// Linear RGB radiance, width·height·3 values, row 0 at the top; traced in
// precision T (float, or double for references).
// render_image_with: escaping rays read `escape` (render/tracer.hpp).
template <class T = float, class Escape>
std::vector<T> render_image_with(const HostScene& s, const scene::Camera& cam, const PassOptions& opt,
                                 const Escape& escape, PassStats* stats = nullptr) {
  std::vector<T> image(std::size_t(cam.width) * cam.height * 3, T(0));
  detail::forward_pass<T>(s, s.view(false), s.params(), cam, opt, stats, escape,
                          [&](std::size_t i, const Vec3<T>& L, float wt) {
                            for (int c = 0; c < 3; ++c) image[i + c] += wt * L[c];
                          });
  return image;
}

template <class T = float>
std::vector<T> render_image(const HostScene& s, const scene::Camera& cam, const PassOptions& opt = {},
                            PassStats* stats = nullptr) {
  std::vector<T> image;
  s.with_escape([&](const auto& escape) { image = render_image_with<T>(s, cam, opt, escape, stats); });
  return image;
}

// Adds to `grad` dLoss/dparameter for every buffer marked in s.differentiate,
// given dLoss/dpixel (width·height·3). Returns the rendered image as well.
// Tapes record in precision T (float; double for reference gradients).
template <class T = float>
std::vector<float> render_gradient(const HostScene& s, const scene::Camera& cam, const float* pixel_adjoint,
                                   SceneGradient& grad, const PassOptions& opt = {}, PassStats* stats = nullptr) {
  using V = ad::Var<T>;
  std::vector<float> image(std::size_t(cam.width) * cam.height * 3, 0.0f);
  const SceneView view = s.view(true, true);
  ad::ParamSet params = s.params();
  grad.attach(params);
  const DoubleSums sums(params);  // the IoR's and the absorption's gradients summed in double
  ThreadPool& pool = ThreadPool::global();
  detail::StatsPerWorker st(pool.size());
  detail::WorkerTapes<T> tapes(pool.size(), opt);
  pool.parallel_for(std::int64_t(cam.width) * cam.height, 16, [&](std::int64_t b, std::int64_t e, int w) {
    ad::ParamReader<V> reader = tapes.reader(w, &params);
    ad::Tape<T>* tape = reader.tape();
    PassStats& ps = st.per[std::size_t(w)];
    detail::for_each_sample(cam, opt.samples_per_axis, b, e, [&](std::int64_t pix, Vec3f o, Vec3f d, float wt) {
      const float* a = pixel_adjoint + std::size_t(pix) * 3;
      const Vec3<T> adjoint(T(wt * a[0]), T(wt * a[1]), T(wt * a[2]));
      Vec3<T> L;
      s.with_escape([&](const auto& escape) {
        L = opt.recompute ? trace_recomputed<T>(view, s.accel(), reader, o, d, adjoint, opt.trace, &ps.trace, escape)
                          : trace_streamed<T>(view, s.accel(), reader, o, d, adjoint, opt.trace, &ps.trace, escape);
      });
      ++ps.rays;
      ps.tape_nodes += tape->peak();
      ps.max_tape_nodes = tape->peak() > ps.max_tape_nodes ? tape->peak() : ps.max_tape_nodes;
      for (int c = 0; c < 3; ++c) image[std::size_t(pix) * 3 + c] += wt * float(L[c]);
      // (an overflow has lost part of this ray's gradient; the rest is scattered)
      if (tape->overflowed() || reader.overflowed()) ++ps.overflowed_rays;
    });
  });
  sums.add_to();
  grad.fold_normals(s);
  if (stats) *stats = st.total();
  return image;
}

// The image (value) and its derivative along `direction` (one array per
// parameter buffer, null where the direction is zero), with Dual<float, 1>.

inline ImageDerivative render_derivative(const HostScene& s, const scene::Camera& cam,
                                         const float* const direction[param_count], const PassOptions& opt = {},
                                         PassStats* stats = nullptr) {
  using D = ad::Dual<float, 1>;
  ImageDerivative out;
  out.value.assign(std::size_t(cam.width) * cam.height * 3, 0.0f);
  out.derivative.assign(out.value.size(), 0.0f);
  ad::ParamSet params = s.params();
  for (int b = 0; b < param_count; ++b) params.buffers[b].tangents[0] = direction[b];
  s.with_escape([&](const auto& escape) {
    detail::forward_pass<D>(s, s.view(true), params, cam, opt, stats, escape,
                            [&](std::size_t i, const Vec3<D>& L, float wt) {
                              for (int c = 0; c < 3; ++c) {
                                out.value[i + c] += wt * L[c].value;
                                out.derivative[i + c] += wt * L[c].grad[0];
                              }
                            });
  });
  return out;
}

}  // namespace difftrans::render
