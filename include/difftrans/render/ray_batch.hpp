// Reverse mode over an arbitrary batch of camera rays — pixels drawn from
// several views, as stage 2 trains — with the loss evaluated per ray: each
// ray is traced on a tape, the caller's loss turns its radiance into a value
// and an adjoint, and the tape is swept back at once. No image is kept and no
// second pass is needed, which a per-pixel loss (L2, relative L2, a colour
// cosine) allows.
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
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
  std::int64_t clipped_ior_rays = 0;  // rays whose IoR derivative was clipped
};

// Rays in groups of `group` consecutive rays — the samples of one pixel:
// every ray of group j is traced on one tape, loss(j, L, dL) sees their
// radiances L[0 .. group) and writes dLoss/dL[k] for each, and the tape is
// swept back once. A loss of the pixel's mean over its samples, or of the
// product of two samples' residuals (an unbiased (E ĉ − c)²), needs the
// whole group before any adjoint is known. The gradient of the summed loss
// w.r.t. every buffer marked in s.differentiate is added to `grad`. `loss`
// is called concurrently from worker threads (distinct j). A group whose
// tape overflows (PassOptions::max_tape_nodes, all its rays together) adds
// its loss but no gradient (its rays count in stats.overflowed_rays).
//
// The groups are cut into fixed blocks (ad/block_gradients.hpp), so the
// gradient and the loss are the same bit for bit for any number of threads.
//
// clip_geometry > 0: each group's gradient w.r.t. the vertices (positions and
// normals together) is scaled down to at most that L2 norm before it is
// added — a robust gradient against the few rays whose deep, chaotic paths
// carry huge vertex derivatives (RayBatchResult::clipped_rays counts the
// groups clipped). clip_ior > 0: likewise the group's derivative w.r.t. the
// IoR, at most that in magnitude (RayBatchResult::clipped_ior_rays). Near the
// critical angle the Fresnel reflectance has a square-root singularity in
// the IoR (cos θt = √(1 − η² sin² θi)), so a ray's IoR derivative has a heavy
// tail: on spot-clear (true mesh, depth 4) a few rays decide the sign of a
// batch's IoR gradient (docs/stage2-diagnostics.md, "ior").
template <class T = float, class GroupLoss>
RayBatchResult ray_group_gradient(const HostScene& s, const std::vector<BatchRay>& rays, int group, GroupLoss&& loss,
                                  SceneGradient& grad, const PassOptions& opt = {}, bool keep_radiance = false,
                                  float clip_geometry = 0.0f, float clip_ior = 0.0f) {
  using V = ad::Var<T>;
  if (group < 1 || rays.size() % std::size_t(group) != 0)
    throw std::invalid_argument("ray_group_gradient: the ray count is not a multiple of the group size");
  const std::int64_t groups = std::int64_t(rays.size()) / group;
  RayBatchResult out;
  if (keep_radiance) out.radiance.assign(rays.size(), Vec3f(0.0f));
  const SceneView view = s.view(true, true);
  ad::ParamSet params = s.params();
  grad.attach(params);
  for (int b = 0; b < ad::max_param_buffers; ++b)  // only what is differentiated gets block copies
    if (!(b < param_count && (s.differentiate[b] || (b == param_normals && s.differentiate[param_positions]))))
      params.buffers[b].gradient = nullptr;
  // fixed blocks of groups, each summed into its own gradient copy: the same
  // result bit for bit whatever the number of threads (ad/block_gradients.hpp)
  ad::BlockGradients blocks(params, groups);
  ThreadPool& pool = ThreadPool::global();
  detail::StatsPerWorker st(pool.size());
  std::vector<double> losses(std::size_t(blocks.count()), 0.0);
  std::vector<std::int64_t> clipped(std::size_t(blocks.count()), 0), clipped_ior(std::size_t(blocks.count()), 0);
  const GroupClip clip = vertex_and_ior_clip(clip_geometry, clip_ior);
  detail::WorkerTapes<T> tapes(pool.size(), opt);
  pool.parallel_for(blocks.count(), 1, [&](std::int64_t kb, std::int64_t ke, int w) {
    PassStats& ps = st.per[std::size_t(w)];
    std::vector<Vec3<V>> L(static_cast<std::size_t>(group));
    std::vector<Vec3f> value(static_cast<std::size_t>(group)), adjoint(static_cast<std::size_t>(group));
    for (std::int64_t k = kb; k < ke; ++k) {
      ad::ParamReader<V> reader = tapes.reader(w, &blocks.set(k));
      ad::Tape<T>* tape = reader.tape();
      for (std::int64_t j = blocks.begin(k); j < blocks.end(k); ++j) {
        tape->reset();
        reader.clear();
        for (int q = 0; q < group; ++q) {
          const std::size_t i = std::size_t(j) * std::size_t(group) + std::size_t(q);
          const BatchRay& r = rays[i];
          const auto before = tape->size();
          s.with_escape([&](const auto& escape) {
            L[std::size_t(q)] = trace<V>(view, s.accel(), reader, r.origin, r.direction, opt.trace, &ps.trace, escape);
          });
          ++ps.rays;
          const std::int32_t nodes = std::int32_t(tape->size() - before);
          ps.tape_nodes += nodes;
          ps.max_tape_nodes = nodes > ps.max_tape_nodes ? nodes : ps.max_tape_nodes;
          const Vec3<V>& c = L[std::size_t(q)];
          value[std::size_t(q)] = Vec3f(float(c.x.value), float(c.y.value), float(c.z.value));
          if (keep_radiance) out.radiance[i] = value[std::size_t(q)];
          adjoint[std::size_t(q)] = Vec3f(0.0f);
        }
        losses[std::size_t(k)] += loss(std::int64_t(j), static_cast<const Vec3f*>(value.data()), adjoint.data());
        if (tape->overflowed() || reader.overflowed()) {
          ps.overflowed_rays += group;
          reader.clear();
          continue;
        }
        bool any = false;
        for (const Vec3f& a : adjoint) any = any || a != Vec3f(0.0f);
        if (!any) {
          reader.clear();
          continue;
        }
        tape->zero_adjoints();
        for (int q = 0; q < group; ++q)
          for (int c = 0; c < 3; ++c) tape->seed(L[std::size_t(q)][c], T(adjoint[std::size_t(q)][c]));
        tape->propagate();
        if (clip_geometry > 0.0f || clip_ior > 0.0f) {  // this group's gradients, clipped
          const int capped = reader.scatter_clipped(clip.classes, clip.caps);
          clipped[std::size_t(k)] += capped & 1;
          clipped_ior[std::size_t(k)] += (capped >> 1) & 1;
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
  for (std::int64_t c : clipped_ior) out.clipped_ior_rays += c;
  return out;
}

// The radiance along every ray (plain float, no tape), on the thread pool,
// with the given escape (what a ray leaving the object sees; tracer.hpp).
// With `segments`, each ray's count of traced segments (TraceStats) is
// written there: the work, the same on any machine.
template <class Escape>
std::vector<Vec3f> trace_batch(const HostScene& s, const std::vector<BatchRay>& rays, const TraceSettings& settings,
                               const Escape& escape, std::vector<std::int32_t>* segments = nullptr) {
  std::vector<Vec3f> out(rays.size(), Vec3f(0.0f));
  if (segments) segments->assign(rays.size(), 0);
  const SceneView view = s.view(false);
  const ad::ParamSet params = s.params();
  ThreadPool::global().parallel_for(std::int64_t(rays.size()), 64, [&](std::int64_t b, std::int64_t e, int) {
    ad::ParamReader<float> reader(&params);
    for (std::int64_t i = b; i < e; ++i) {
      const BatchRay& r = rays[std::size_t(i)];
      TraceStats stats;
      out[std::size_t(i)] = trace<float>(view, s.accel(), reader, r.origin, r.direction, settings, &stats, escape);
      if (segments) (*segments)[std::size_t(i)] = stats.segments;
    }
  });
  return out;
}

// The same with the scene's own environment (its map or near field).
inline std::vector<Vec3f> trace_batch(const HostScene& s, const std::vector<BatchRay>& rays, const TraceSettings& settings,
                                      std::vector<std::int32_t>* segments = nullptr) {
  std::vector<Vec3f> out;
  s.with_escape([&](const auto& escape) { out = trace_batch(s, rays, settings, escape, segments); });
  return out;
}

// One ray per group: loss(i, L, dL) returns ray i's loss and writes
// dLoss/dL (see ray_group_gradient for the rest).
template <class T = float, class Loss>
RayBatchResult ray_batch_gradient(const HostScene& s, const std::vector<BatchRay>& rays, Loss&& loss,
                                  SceneGradient& grad, const PassOptions& opt = {}, bool keep_radiance = false,
                                  float clip_geometry = 0.0f, float clip_ior = 0.0f) {
  return ray_group_gradient<T>(
      s, rays, 1,
      [&loss](std::int64_t i, const Vec3f* L, Vec3f* dL) { return loss(std::int32_t(i), L[0], dL[0]); }, grad, opt,
      keep_radiance, clip_geometry, clip_ior);
}

}  // namespace difftrans::render
