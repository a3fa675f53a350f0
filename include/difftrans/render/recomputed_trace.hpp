// Reverse mode by recomputation (trace_recomputed): the gradient of one
// camera ray's radiance on a tape that holds half a segment at a time,
// whatever the depth, each segment traced twice — the walk in plain floating
// point, then the segment again on the tape from the values the walk kept.
// The physics is the tracer's own (render/tracer.hpp: detail::arrive and
// detail::depart, the two halves of detail::interact).
#pragma once

#include <cstdint>

#include "difftrans/accel/ray_hit.hpp"
#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/param_source.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/absorption.hpp"

namespace difftrans::render {

namespace detail {

// Intersectors for trace_recomputed: KeepHit passes the ray on and keeps
// the answer; RecordedHit gives that answer back when the same segment is
// traced again, without a second query.
template <class Accel>
struct KeepHit {
  const Accel* inner;
  accel::RayHit* kept;
  DT_HOST_DEVICE accel::RayHit intersect(const Vec3f& o, const Vec3f& d, float tnear, float tfar) const {
    *kept = inner->intersect(o, d, tnear, tfar);
    return *kept;
  }
};
struct RecordedHit {
  accel::RayHit hit;
  DT_HOST_DEVICE accel::RayHit intersect(const Vec3f&, const Vec3f&, float, float) const { return hit; }
};

// One level of trace_recomputed's walk down the tree: a branch (values),
// where its segment ended, the children it made that carry derivatives, and
// the adjoints of their inputs (origin, direction, weight) as their subtrees
// send them back.
template <class T>
struct RecomputeLevel {
  Branch<T> branch;
  accel::RayHit hit;  // what the BVH answered for its segment
  SegmentEnd<T> end;
  bool escaped = false;
  Branch<T> child[2];
  Vec3<T> child_adjoint[2][3];
  int children = 0;
  int walked = 0;  // children whose subtrees have been walked or entered
};

}  // namespace detail

// Reverse mode by recomputation: the gradient of adjoint · L(ray), as
// trace_streamed, on a tape that holds half a segment at a time. The tree is
// walked depth first in plain T, keeping only the values of each branch on
// the way down (its origin, direction and weight, what the BVH answered,
// where its segment ended); when a branch's subtrees are done, its segment
// is traced again in Var<T> from those values as new leaves, in two halves
// (detail::depart, then detail::arrive, with the kept BVH answer), the
// adjoints its children sent back (or the pixel's, where it leaves the
// object) seeded on the outputs of each half and swept back to its inputs
// and to the parameters it read, and the tape is cut back after each. The
// tape then holds the larger half of one segment (the hit re-evaluated on
// the vertices, the shading normal and the absorption along the way — of a
// grid integrated by samples, one sample at a time, apart; or Fresnel,
// refraction and the children's weights), whatever the depth; the
// price is each segment traced twice. The recomputed halves take the walk's
// values as inputs and run the same code, so they make the same children; a
// child the walk did not make (or the other way round) gets no adjoint and
// is counted in `mismatched` when given. The IoR is a new leaf at each
// surface interaction; its adjoints are summed over the ray and added to its
// gradient once.
template <class T, class Accel, class Escape = DistantEscape>
DT_HOST_DEVICE Vec3<T> trace_recomputed(const SceneView& scene, const Accel& accel,
                                        ad::ParamReader<ad::Var<T>>& reader, const Vec3f& origin,
                                        const Vec3f& direction, const Vec3<T>& adjoint,
                                        const TraceSettings& settings, TraceStats* stats = nullptr,
                                        const Escape& escape = Escape{}, int* mismatched = nullptr) {
  using V = ad::Var<T>;
  ad::Tape<T>* tape = reader.tape();
  tape->reset();
  tape->zero_on_push(true);
  reader.clear();
  ad::ParamReader<T> values(reader.params());
  const T eta = ad::load<T>(values, scene.ior, 0);
  const std::uint64_t ray_hash = detail::choice_hash(settings, origin, direction);
  TraceStats local;
  Vec3<T> radiance(T(0), T(0), T(0));
  // the IoR's adjoint over the ray's interactions, added to its gradient once
  // at the end (a leaf per interaction through the reader would scatter into
  // the one shared value at every interaction)
  T eta_adjoint = T(0);

  // the segment of level `at` in plain T: its light, or where it ended and its children
  const auto walk_segment = [&](detail::RecomputeLevel<T>& at) {
    at.children = 0;
    at.walked = 0;
    at.escaped = false;
    at.end = detail::arrive<T>(scene, detail::KeepHit<Accel>{&accel, &at.hit}, values, at.branch, settings, local,
                               escape, [&](const Vec3<T>& light) {
      radiance += light;
      at.escaped = true;
    });
    if (!at.end.more) return;
    detail::depart<T>(at.branch, at.end, eta, ray_hash, settings, local,
                      [&](detail::Branch<T>& next) {
                        if (!detail::carries_derivatives(settings, next.depth, next.path)) {
                          // a constant: its whole subtree now
                          radiance += detail::follow<T>(scene, accel, values, next, eta, ray_hash, settings, local,
                                                        escape);
                          return;
                        }
                        at.child[at.children++] = next;
                      });
  };
  const auto leaves = [&](const Vec3<T>& v) { return Vec3<V>(tape->variable(v.x), tape->variable(v.y), tape->variable(v.z)); };
  const auto seed = [&](const Vec3<V>& y, const Vec3<T>& w) {
    for (int c = 0; c < 3; ++c) tape->seed(y[c], w[c]);
  };
  const auto adjoints = [&](const Vec3<V>& x) { return Vec3<T>(tape->adjoint(x.x), tape->adjoint(x.y), tape->adjoint(x.z)); };
  // the sweep of what was recorded from `base` on: the parameters' adjoints
  // scattered; the caller reads its leaves' before the cut
  const auto sweep = [&](std::int32_t base) {
    if (tape->size() > base) tape->propagate(tape->size() - 1, base);
    reader.scatter_from(base);
  };
  // the segment of level `at` again in Var<T>, each half seeded, swept back
  // and cut; the adjoints of its inputs into `out` (none for the camera ray's)
  const auto sweep_segment = [&](const detail::RecomputeLevel<T>& at, Vec3<T>* out) {
    const detail::Branch<T>& b = at.branch;
    if (!at.end.more && !at.escaped) {  // cut or degenerate: it brings nothing
      if (out) out[0] = out[1] = out[2] = Vec3<T>(T(0), T(0), T(0));
      return;
    }
    // the departure: from the point, the normals, the way in and the weight
    Vec3<T> at_p(T(0), T(0), T(0)), at_n = at_p, at_direction = at_p, at_weight = at_p;
    if (at.end.more) {
      const std::int32_t base = tape->mark();
      detail::SegmentEnd<V> end;
      end.more = true;
      end.p = leaves(at.end.p);
      end.n = leaves(at.end.n);
      end.weight = leaves(at.end.weight);
      end.ng = lift<V>(at.end.ng);
      end.cos_geo = at.end.cos_geo;
      const Vec3<V> way_in = leaves(b.direction);
      const detail::Branch<V> bv{lift<V>(b.origin), way_in, lift<V>(b.weight), b.depth, b.path};
      const V eta_v = scene.ior.differentiable() ? tape->variable(eta) : V(eta);
      TraceStats again;
      int made = 0;
      detail::depart<V>(bv, end, eta_v, ray_hash, settings, again, [&](detail::Branch<V>& next) {
        if (!detail::carries_derivatives(settings, next.depth, next.path)) return;
        ++made;
        for (int k = 0; k < at.children; ++k)
          if (at.child[k].path == next.path) {
            seed(next.origin, at.child_adjoint[k][0]);
            seed(next.direction, at.child_adjoint[k][1]);
            seed(next.weight, at.child_adjoint[k][2]);
          }
      });
      if (made != at.children && mismatched) ++*mismatched;
      sweep(base);
      eta_adjoint += tape->adjoint(eta_v);
      at_p = adjoints(end.p);
      at_n = adjoints(end.n);
      at_weight = adjoints(end.weight);
      at_direction = adjoints(way_in);
      tape->truncate(base);
    }
    // A segment inside a grid integrated by samples: its absorption apart,
    // before the rest of the arrival, one piece on the tape at a time — the
    // interval and the samples' weight (scene::SampledSegment), above it the
    // corners of the cell being sampled, above those one sample's share of
    // the optical depth, each swept into the pieces below it and cut. The
    // weight is the branch's × the transmittance, so the transmittance's
    // adjoint is the weight's × the branch's weight (values), and the
    // depth's −transmittance × that; what the pieces send to the segment's
    // ends joins the arrival's adjoints below.
    const bool shares = at.end.more && at.end.cos_geo < T(0) &&
                        scene.absorption.kind == scene::AbsorptionKind::grid && settings.integration.samples > 0;
    SceneView arrival_scene = scene;
    Vec3<T> weight_adjoint = at_weight, share_origin(T(0), T(0), T(0)), share_end = share_origin;
    if (shares) {
      arrival_scene.absorption.kind = scene::AbsorptionKind::none;  // the weight passes unchanged
      const Vec3<T> tau = scene::optical_depth<T>(values, scene.absorption, b.origin, at.end.p, settings.integration);
      const Vec3<T> transmitted = scene::transmittance_from_depth(tau);
      Vec3<T> tau_adjoint;
      for (int c = 0; c < 3; ++c) {
        weight_adjoint[c] = at_weight[c] * transmitted[c];
        tau_adjoint[c] = tau[c] < scene::max_optical_depth<T> ? -transmitted[c] * at_weight[c] * b.weight[c] : T(0);
      }
      const bool ends_move = settings.attenuation_path_gradient;
      const std::int32_t segment_base = tape->mark();
      const Vec3<V> from = ends_move ? leaves(b.origin) : lift<V>(b.origin);
      const Vec3<V> to = ends_move ? leaves(at.end.p) : lift<V>(at.end.p);
      const scene::SampledSegment<V> piece = scene::sampled_segment(scene.absorption, from, to, settings.integration);
      if (piece.hit) {
        scene::detail::CellSigma<V> corners;
        bool have = false;
        std::int32_t cell_base = tape->mark();
        for (int k = 0; k < piece.samples; ++k) {
          const Vec3i cell = scene::sample_cell(piece, k);
          if (!have || cell != corners.cell) {
            if (have) {  // the last cell's samples are done
              sweep(cell_base);
              tape->truncate(cell_base);
            }
            cell_base = tape->mark();
            scene::detail::read_cell(reader, scene.absorption, cell, corners);
            have = true;
          }
          const std::int32_t sample_base = tape->mark();
          seed(scene::sample_share(reader, scene.absorption, piece, k, corners), tau_adjoint);
          sweep(sample_base);
          tape->truncate(sample_base);
        }
        if (have) {
          sweep(cell_base);
          tape->truncate(cell_base);
        }
      }
      sweep(segment_base);
      share_origin = adjoints(from);
      share_end = adjoints(to);
      tape->truncate(segment_base);
    }
    // the arrival: from the branch's origin, direction and weight
    const std::int32_t base = tape->mark();
    detail::Branch<V> in{lift<V>(b.origin), lift<V>(b.direction), lift<V>(b.weight), b.depth, b.path};
    if (out) {
      in.origin = leaves(b.origin);
      in.direction = leaves(b.direction);
      in.weight = leaves(b.weight);
    }
    TraceStats again;
    const detail::SegmentEnd<V> end =
        detail::arrive<V>(arrival_scene, detail::RecordedHit{at.hit}, reader, in, settings, again, escape,
                          [&](const Vec3<V>& light) { seed(light, adjoint); });
    if (end.more != at.end.more && mismatched) ++*mismatched;
    if (end.more && at.end.more) {
      seed(end.p, at_p + share_end);
      seed(end.n, at_n);
      seed(end.weight, weight_adjoint);
    }
    sweep(base);
    if (out) {
      out[0] = adjoints(in.origin) + (end.more ? share_origin : Vec3<T>(T(0), T(0), T(0)));
      out[1] = adjoints(in.direction) + at_direction;
      out[2] = adjoints(in.weight);
    }
    tape->truncate(base);
  };

  detail::RecomputeLevel<T> level[max_trace_depth + 2];
  level[0].branch = detail::Branch<T>{lift<T>(origin), lift<T>(direction), Vec3<T>(T(1), T(1), T(1)), 0, 1u};
  walk_segment(level[0]);
  int top = 1;
  while (top > 0) {
    detail::RecomputeLevel<T>& at = level[top - 1];
    if (at.walked < at.children) {  // down: the refraction first, as follow() takes them
      level[top].branch = at.child[at.children - 1 - at.walked];
      ++at.walked;
      walk_segment(level[top]);
      ++top;
      continue;
    }
    // up: every subtree below is done
    --top;
    if (top > 0) {
      detail::RecomputeLevel<T>& parent = level[top - 1];
      sweep_segment(at, parent.child_adjoint[parent.children - parent.walked]);
    } else {
      sweep_segment(at, nullptr);
    }
  }
  tape->zero_on_push(false);
  if (scene.ior.differentiable() && eta_adjoint != T(0))
    ad::detail::add_gradient(reader.params()->buffers[scene.ior.buffer], 0, eta_adjoint);
  if (stats) stats->add(local);
  return radiance;
}

}  // namespace difftrans::render
