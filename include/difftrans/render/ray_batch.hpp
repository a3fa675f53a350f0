// Reverse mode over an arbitrary batch of camera rays — pixels drawn from
// several views, as stage 2 trains — with the loss evaluated per ray: each
// ray is traced on a tape, the caller's loss turns its radiance into a value
// and an adjoint, and the tape is swept back at once. No image is kept and no
// second pass is needed, which a per-pixel loss (L2, relative L2, a colour
// cosine) allows.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "difftrans/ad/block_gradients.hpp"
#include "difftrans/core/parallel.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/passes.hpp"

namespace difftrans::render {

struct BatchRay {
  Vec3f origin, direction;
};

struct RayBatchResult {
  double loss = 0.0;      // sum of the per-ray losses
  PassStats stats;
  std::vector<Vec3f> radiance;  // per ray, when asked for
  std::int64_t clipped_rays = 0;  // rays whose vertex gradient was clipped
};

// For every ray i: L = trace(ray i); loss(i, L, dL) returns the ray's loss and
// writes dLoss/dL; the gradient of the summed loss w.r.t. every buffer marked
// in s.differentiate is added to `grad`. `loss` is called concurrently from
// the pool's workers (for different i). Rays whose tape overflows contribute
// their loss but no gradient (counted in stats.overflowed_rays).
//
// The rays are cut into fixed blocks (ad/block_gradients.hpp), so the
// gradient and the loss are the same bit for bit for any number of threads.
//
// clip_geometry > 0: each ray's gradient w.r.t. the vertices (positions and
// normals together) is scaled down to at most that L2 norm before it is
// added — a robust gradient against the few rays whose deep, chaotic paths
// carry huge vertex derivatives (RayBatchResult::clipped_rays counts them).
template <class T = float, class Loss>
RayBatchResult ray_batch_gradient(const HostScene& s, const std::vector<BatchRay>& rays, Loss&& loss,
                                  SceneGradient& grad, const PassOptions& opt = {}, bool keep_radiance = false,
                                  float clip_geometry = 0.0f) {
  using V = ad::Var<T>;
  RayBatchResult out;
  if (keep_radiance) out.radiance.assign(rays.size(), Vec3f(0.0f));
  const SceneView view = s.view(true, true);
  ad::ParamSet params = s.params();
  grad.attach(params);
  for (int b = 0; b < ad::max_param_buffers; ++b)  // only what is differentiated gets block copies
    if (!(b < param_count && (s.differentiate[b] || (b == param_normals && s.differentiate[param_positions]))))
      params.buffers[b].gradient = nullptr;
  // fixed blocks of rays, each summed into its own gradient copy: the same
  // result bit for bit whatever the number of threads (ad/block_gradients.hpp)
  ad::BlockGradients blocks(params, std::int64_t(rays.size()));
  ThreadPool& pool = ThreadPool::global();
  detail::StatsPerWorker st(pool.size());
  std::vector<double> losses(std::size_t(blocks.count()), 0.0);
  std::vector<std::int64_t> clipped(std::size_t(blocks.count()), 0);
  detail::WorkerTapes<T> tapes(pool.size(), opt);
  pool.parallel_for(blocks.count(), 1, [&](std::int64_t kb, std::int64_t ke, int w) {
    PassStats& ps = st.per[std::size_t(w)];
    for (std::int64_t k = kb; k < ke; ++k) {
      ad::ParamReader<V> reader = tapes.reader(w, &blocks.set(k));
      ad::Tape<T>* tape = reader.tape();
      for (std::int64_t i = blocks.begin(k); i < blocks.end(k); ++i) {
        tape->reset();
        reader.clear();
        const BatchRay& r = rays[std::size_t(i)];
        Vec3<V> L;
        s.with_escape([&](const auto& escape) {
          L = trace<V>(view, s.accel(), reader, r.origin, r.direction, opt.trace, &ps.trace, escape);
        });
        ++ps.rays;
        ps.tape_nodes += tape->size();
        ps.max_tape_nodes = tape->size() > ps.max_tape_nodes ? tape->size() : ps.max_tape_nodes;
        const Vec3f value(float(L.x.value), float(L.y.value), float(L.z.value));
        if (keep_radiance) out.radiance[std::size_t(i)] = value;
        Vec3f adjoint(0.0f);
        losses[std::size_t(k)] += loss(std::int32_t(i), value, adjoint);
        if (tape->overflowed() || reader.overflowed()) {
          ++ps.overflowed_rays;
          reader.clear();
          continue;
        }
        if (adjoint == Vec3f(0.0f)) {
          reader.clear();
          continue;
        }
        tape->zero_adjoints();
        for (int c = 0; c < 3; ++c) tape->seed(L[c], T(adjoint[c]));
        tape->propagate();
        if (clip_geometry > 0.0f) {  // this ray's gradient w.r.t. the vertices (positions and normals), clipped
          const T n2 = reader.adjoint_norm2(param_positions) + reader.adjoint_norm2(param_normals);
          T scale[ad::max_param_buffers];
          for (T& x : scale) x = T(1);
          if (n2 > T(clip_geometry) * T(clip_geometry)) {
            scale[param_positions] = scale[param_normals] = T(clip_geometry) / std::sqrt(n2);
            ++clipped[std::size_t(k)];
          }
          reader.scatter_scaled(scale);
        } else {
          reader.scatter();
        }
      }
    }
  });
  blocks.reduce();
  grad.fold_normals(s);
  out.stats = st.total();
  for (double l : losses) out.loss += l;
  for (std::int64_t c : clipped) out.clipped_rays += c;
  return out;
}

}  // namespace difftrans::render
