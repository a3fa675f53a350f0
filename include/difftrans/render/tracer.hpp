// The recursive differentiable tracer of DiffTrans stage 2, written once over
// the scalar S. A camera ray is followed through a closed triangle mesh: at
// every surface hit both the reflected and the refracted ray are traced,
// weighted by Fresnel R and T = 1 − R (only reflection on total internal
// reflection); segments inside the object are attenuated by Beer–Lambert;
// rays that leave read the environment. The BVH answers in float which
// triangle is hit; the hit is re-evaluated on that triangle in S, so radiance
// carries derivatives to vertices, IoR, absorption and environment texels.
// Where an escaping ray's radiance comes from is a template parameter (the
// "escape" below): the distant map of the SceneView by default, or a
// near-field environment read from the ray's origin and direction.
#pragma once

#include <cstdint>

#include "difftrans/ad/glm.hpp"
#include "difftrans/core/hash.hpp"
#include "difftrans/optics/interface.hpp"
#include "difftrans/scene/absorption.hpp"
#include "difftrans/scene/envmap.hpp"
#include "difftrans/scene/mesh.hpp"

namespace difftrans::render {

// Deepest ray tree the tracer supports (the reference renders use 16).
inline constexpr int max_trace_depth = 16;

// Everything the tracer reads: non-owning views, device-copyable.
struct SceneView {
  scene::MeshView mesh;        // closed, outward-facing (counter-clockwise) triangles
  scene::EnvMap environment;   // distant environment
  scene::AbsorptionField absorption;
  ad::ParamSource ior;      // one value: IoR of the object (the outside is 1)
};

struct TraceSettings {
  int max_depth = 8;                // surface interactions per path; deeper branches are dropped
  float prune_throughput = 0.0f;    // drop branches whose largest RGB weight falls below this (0: full tree)
  // Interactions that spawn both children (the Fresnel tree). Beyond, up to
  // max_depth, a branch goes on as one path: it reflects with probability R
  // and refracts with probability T, its weight divided by that probability
  // (held constant: the value and its derivative stay unbiased). Deep light
  // is then sampled instead of dropped, at one segment per interaction.
  // ≥ max_depth: the whole tree (the default).
  int tree_depth = max_trace_depth;
  // Pruning by Russian roulette: a branch below prune_throughput goes on
  // with probability (its largest RGB weight) / prune_throughput, its weight
  // divided by that probability, instead of being dropped (unbiased).
  bool roulette = false;
  scene::AbsorptionIntegration integration;  // grid absorption: exact (samples = 0) or K samples
  scene::NormalMode normal_mode = scene::NormalMode::automatic;
  bool smooth_normals = true;       // shade with interpolated vertex normals (the paper); false: flat facets
  // Which branches carry derivatives (AD scalars only; the radiance is the
  // same either way). 0: every branch. k > 0: the main refraction path only —
  // the camera ray and its refracted children through the first k
  // interactions (2: the entry and the exit, as DRT differentiates); every
  // other branch (a reflection, a total internal reflection, anything past
  // the k-th interaction) is traced in plain floating point, off the tape, and
  // adds its radiance as a constant, and the tape holds the main path only
  // (5x fewer nodes on a glass sphere at depth 8). On spot-clear it did not
  // point the vertex gradient closer to the true surface once smoothed as
  // stage 2 steps (docs/stage2-diagnostics.md, "home"): an option there.
  int gradient_refractions = 0;
  // 0: every depth. k > 0: only the branches of the first k interactions
  // carry derivatives (reflections as well as refractions); a branch deeper
  // than k is traced in plain floating point and adds a constant, its weight
  // included, so the derivative is that of the tree cut at k with the deeper
  // light held fixed. Beyond about 8 interactions a path's derivative is
  // carried by a few chaotic rays (docs/stage2-diagnostics.md, "gradcheck at
  // depth").
  int gradient_depth = 0;
  // false: a segment's Beer–Lambert transmittance carries no derivative
  // through where the segment runs (its endpoints, hence its length): the
  // absorption's derivative stays, the vertices' and the IoR's through the
  // path length go. The colour of an absorbing object fixes σ·length along
  // each path, so a fit whose σ is wrong can make it up by a thicker or
  // thinner object; without this derivative the vertices answer to the
  // bending of the light and the Fresnel weights only (Stage2Config::
  // attenuation_moves_vertices). The radiance is the same either way.
  bool attenuation_path_gradient = true;
};

// What happened along one camera ray (counted on values).
struct TraceStats {
  std::int32_t segments = 0;      // rays sent to the BVH
  std::int32_t hits = 0;          // surface interactions
  std::int32_t tir = 0;           // total internal reflections
  std::int32_t depth_cut = 0;     // branches dropped at max_depth
  std::int32_t pruned = 0;        // branches dropped by the throughput threshold
  std::int32_t fallback_hits = 0; // hits whose triangle could not be re-evaluated in S (BVH values used)
  double cut_weight = 0;          // mean RGB weight of the dropped branches: the radiance lost, per unit radiance
  float min_cos2_t = 1.0f;        // the smallest cos²θt of a refraction (how close to the critical angle); add() keeps the least
  DT_HOST_DEVICE void add(const TraceStats& o) {
    cut_weight += o.cut_weight;
    min_cos2_t = o.min_cos2_t < min_cos2_t ? o.min_cos2_t : min_cos2_t;
    segments += o.segments;
    hits += o.hits;
    tir += o.tir;
    depth_cut += o.depth_cut;
    pruned += o.pruned;
    fallback_hits += o.fallback_hits;
  }
};

namespace detail {

template <class S>
struct Branch {
  Vec3<S> origin, direction, weight;
  int depth;
  std::uint32_t path;    // 1, then one bit per interaction: 0 reflected, 1 refracted
  std::int32_t mark = 0; // streamed reverse mode: the tape's length when the branch was made
};

// Origin of a ray spawned at p towards `side` (±1 along the unit geometric
// normal): moved off the surface by a bound on the float error of p, so that
// the new ray cannot hit the triangle it leaves (Mitsuba and pbrt do the same).
template <class S>
DT_HOST_DEVICE Vec3<S> offset_origin(const Vec3<S>& p, const Vec3<S>& ng, float side) {
  using T = ad::scalar_t<S>;
  const Vec3<T> pv = value_of(p), nv = value_of(ng);
  const T scale = T(1) + max(max(abs(pv.x), abs(pv.y)), abs(pv.z));
  const T eps = scale * T(1.0 / (1 << 21));  // ~5e-7 (1 + |p|): 8 float ulps of |p|, as Mitsuba
  return p + Vec3<S>(S(nv.x * eps * side), S(nv.y * eps * side), S(nv.z * eps * side));
}

template <class S>
DT_HOST_DEVICE ad::scalar_t<S> max_component(const Vec3<S>& v) {
  return max(max(value_of(v.x), value_of(v.y)), value_of(v.z));
}

template <class S>
DT_HOST_DEVICE double mean_component(const Vec3<S>& v) {
  return (double(value_of(v.x)) + double(value_of(v.y)) + double(value_of(v.z))) / 3.0;
}

// A uniform number in [0, 1) for a choice on a branch: a hash of the camera
// ray (`ray`, from its origin and direction) and of the branch's place in the
// tree (`path`: 1, then one bit per interaction, 0 reflected, 1 refracted),
// salted by what is chosen. It depends on nothing the parameters move, so a
// ray's choices repeat run to run, on any thread, and under the small
// changes of a finite-difference check; no generator is carried along.
DT_HOST_DEVICE inline std::uint64_t camera_ray_hash(const Vec3f& o, const Vec3f& d) {
  const std::uint64_t h = splitmix64((std::uint64_t(float_bits(o.x)) << 32) | float_bits(o.y));
  const std::uint64_t g = splitmix64(h ^ ((std::uint64_t(float_bits(o.z)) << 32) | float_bits(d.x)));
  return splitmix64(g ^ ((std::uint64_t(float_bits(d.y)) << 32) | float_bits(d.z)));
}

DT_HOST_DEVICE inline float branch_random(std::uint64_t ray, std::uint32_t path, std::uint32_t salt) {
  return float(unit_from_bits(splitmix64(ray ^ ((std::uint64_t(path) << 8) | salt))));
}

}  // namespace detail

// Escapes: what a ray that leaves the object sees. An escape is a callable
//   Vec3<S> escape(Reader& reader, const SceneView& scene, const Vec3<S>& origin, const Vec3<S>& direction)
// called once per escaping branch; `direction` is unit.

// The distant environment of the scene (direction only); differentiable in
// its texels (through the reader) and in the direction.
struct DistantEscape {
  template <class S, class Reader>
  DT_HOST_DEVICE Vec3<S> operator()(Reader& reader, const SceneView& scene, const Vec3<S>&, const Vec3<S>& d) const {
    return scene::lookup(reader, scene.environment, d);
  }
};

// A fixed near-field environment: radiance(origin, direction) -> Vec3f on
// float values (a radiance field, a procedural room). It is a constant of the
// pass: no derivatives flow into it, nor to the ray that reads it (stage 2
// holds the environment fixed; the origin's and direction's derivatives stop
// here, which is exact for the environment's unknowns and leaves out only
// the second-order effect of the ray's own motion on what it sees).
template <class Radiance>
struct FixedEscape {
  Radiance radiance;
  template <class S, class Reader>
  DT_HOST_DEVICE Vec3<S> operator()(Reader&, const SceneView&, const Vec3<S>& o, const Vec3<S>& d) const {
    const Vec3<ad::scalar_t<S>> ov = value_of(o), dv = value_of(d);
    const Vec3f L = radiance(Vec3f(float(ov.x), float(ov.y), float(ov.z)), Vec3f(float(dv.x), float(dv.y), float(dv.z)));
    return Vec3<S>(S(L.x), S(L.y), S(L.z));
  }
};

template <class Radiance>
DT_HOST_DEVICE FixedEscape<Radiance> fixed_escape(const Radiance& r) {
  return FixedEscape<Radiance>{r};
}

namespace detail {

// Whether a branch (its depth and path bits) carries derivatives under
// TraceSettings::gradient_depth (none deeper) and gradient_refractions: all
// branches, or the all-refracted path (path = 0b1…1) up to that depth.
DT_HOST_DEVICE inline bool carries_derivatives(const TraceSettings& settings, int depth, std::uint32_t path) {
  if (settings.gradient_depth > 0 && depth > settings.gradient_depth) return false;
  return settings.gradient_refractions <= 0 ||
         (depth <= settings.gradient_refractions && (path & (path + 1u)) == 0u);
}

// How follow() collects what the branches bring. SumBranches: their sum, in
// the pass's scalar (every pass but the streamed gradient).
struct SumBranches {
  template <class S>
  DT_HOST_DEVICE void made(Branch<S>&) const {}
  template <class S>
  DT_HOST_DEVICE void taken(const Branch<S>&) const {}
  template <class S>
  DT_HOST_DEVICE void add(Vec3<S>& radiance, const Vec3<S>& light) const {
    radiance += light;
  }
};

// Streamed reverse mode, where the adjoint of the camera ray's radiance is
// known before it is traced: each branch's light is seeded with that adjoint
// as it arrives (the radiance is a sum), and when the loop takes a branch from
// its stack, everything recorded since that branch was made — the finished
// subtrees of its later siblings — is swept back, its leaves scattered into
// the gradient buffers, and cut from the tape. The tape then holds the path
// from the camera to the branch being traced and the pending siblings'
// weights: bounded by the depth, not by the size of the tree.
template <class T>
struct StreamBranches {
  ad::ParamReader<ad::Var<T>>* reader;
  Vec3<T> adjoint;
  DT_HOST_DEVICE void made(Branch<ad::Var<T>>& b) const { b.mark = reader->tape()->mark(); }
  DT_HOST_DEVICE void taken(const Branch<ad::Var<T>>& b) const { settle(b.mark); }
  DT_HOST_DEVICE void add(Vec3<ad::Var<T>>& radiance, const Vec3<ad::Var<T>>& light) const {
    ad::Tape<T>* tape = reader->tape();
    for (int c = 0; c < 3; ++c) {
      tape->seed(light[c], adjoint[c]);
      radiance[c] += ad::Var<T>(light[c].value);  // the value only: its derivatives are on their way
    }
  }
  // Sweeps back the nodes recorded from `mark` on, scatters their leaves and cuts them.
  DT_HOST_DEVICE void settle(std::int32_t mark) const {
    ad::Tape<T>* tape = reader->tape();
    if (tape->size() <= mark) return;
    tape->propagate(tape->size() - 1, mark);
    reader->scatter_from(mark);
    tape->truncate(mark);
  }
};

// Where one branch's segment ends: it left the object (its light has been
// delivered) or stopped (depth cut, a degenerate triangle) — `more` false —
// or it meets the surface at p, with the geometric normal ng (its value
// only is used beyond this point), the shading normal n and the branch's
// weight after the segment's absorption; cos_geo: the cosine of the
// geometric normal with the way back (> 0: the branch came from outside).
template <class S>
struct SegmentEnd {
  bool more = false;
  Vec3<S> p, ng, n, weight;
  ad::scalar_t<S> cos_geo = 0;
};

// The first half of interact(): the segment is sent to the BVH; a branch
// that leaves the object calls light(weight × what it sees); one that meets
// the surface is re-evaluated there and attenuated along the segment.
template <class S, class Accel, class Reader, class Escape, class Light>
DT_HOST_DEVICE DT_FORCEINLINE SegmentEnd<S> arrive(const SceneView& scene, const Accel& accel, Reader& reader,
                                                   const Branch<S>& b, const TraceSettings& settings,
                                                   TraceStats& local, const Escape& escape, Light&& light) {
  using T = ad::scalar_t<S>;
  SegmentEnd<S> end;
  const int max_depth = settings.max_depth < max_trace_depth ? settings.max_depth : max_trace_depth;
  const Vec3f o = value_of(b.origin), d = value_of(b.direction);
  ++local.segments;
  const auto h = accel.intersect(o, d, 0.0f, 3.4e38f);
  if (!h.hit()) {
    light(b.weight * escape(reader, scene, b.origin, b.direction));
    return end;
  }
  ++local.hits;
  scene::SurfaceHit<S> sh = scene::reevaluate_hit(reader, scene.mesh, h.prim, b.origin, b.direction, settings.normal_mode);
  S t = sh.hit.t;
  if (!sh.hit.valid || !sh.point.valid) {
    // a (nearly) degenerate triangle: keep the BVH's answer, without derivatives
    ++local.fallback_hits;
    t = S(h.t);
    sh.point = scene::surface_point(reader, scene.mesh, h.prim, S(h.u), S(h.v), settings.normal_mode);
    if (!sh.point.valid) return end;  // zero area: nothing to refract at
  }
  end.p = b.origin + b.direction * t;
  end.ng = sh.point.ng;
  // which side, on values (nothing recorded)
  const Vec3<T> wi = -value_of(b.direction);
  end.cos_geo = glm::dot(wi, value_of(end.ng));
  // shading normal, unless it disagrees with the geometry about the side
  const bool shading_agrees = (glm::dot(wi, value_of(sh.point.n)) > T(0)) == (end.cos_geo > T(0));
  end.n = settings.smooth_normals && shading_agrees ? sh.point.n : end.ng;

  end.weight = b.weight;
  if (end.cos_geo < T(0) && scene.absorption.kind != scene::AbsorptionKind::none)  // the segment ran inside the object
    end.weight = end.weight * (settings.attenuation_path_gradient
                                   ? scene::transmittance(reader, scene.absorption, b.origin, end.p, settings.integration)
                                   : scene::transmittance(reader, scene.absorption, detach(b.origin), detach(end.p),
                                                          settings.integration));

  if (b.depth + 1 > max_depth) {
    ++local.depth_cut;
    local.cut_weight += mean_component(end.weight);
    return end;
  }
  end.more = true;
  return end;
}

// The second half of interact(): at the surface point `end` of branch b
// (its direction, depth and path are read), the Fresnel children are made,
// the reflection first, then the refraction, and child(branch) is called
// for each that survives the drawn choice and the roulette.
template <class S, class Child>
DT_HOST_DEVICE DT_FORCEINLINE void depart(const Branch<S>& b, const SegmentEnd<S>& end, const S& eta,
                                          std::uint64_t ray_hash, const TraceSettings& settings, TraceStats& local,
                                          Child&& child) {
  using T = ad::scalar_t<S>;
  const optics::InterfaceEvent<S> ev = optics::interface_event(-b.direction, end.n, eta);
  const float incoming_side = end.cos_geo > T(0) ? 1.0f : -1.0f;
  if (!ev.tir) {
    const float c2 = float(value_of(ev.cos_theta_t) * value_of(ev.cos_theta_t));
    local.min_cos2_t = c2 < local.min_cos2_t ? c2 : local.min_cos2_t;
  }

  // the children; a zero Fresnel weight (R at eta = 1) spawns nothing
  const bool refracts = !ev.tir && value_of(ev.T) > T(0);
  const bool reflects = value_of(ev.R) > T(0);
  if (ev.tir) ++local.tir;
  bool take_r = reflects, take_t = refracts;
  T choice = T(1);  // the probability of the child taken, beyond the tree
  if (b.depth >= settings.tree_depth && reflects && refracts) {
    const T r = value_of(ev.R), tt = value_of(ev.T);
    const bool r_first = T(branch_random(ray_hash, b.path, 0u)) * (r + tt) < r;
    take_r = r_first;
    take_t = !r_first;
    choice = (r_first ? r : tt) / (r + tt);
  }
  const Vec3<S> chosen = choice < T(1) ? end.weight * S(T(1) / choice) : end.weight;
  for (int c = 0; c < 2; ++c) {  // the reflection first
    if (!(c == 0 ? take_r : take_t)) continue;
    Vec3<S> w = chosen * (c == 0 ? ev.R : ev.T);
    const T level = max_component(w);
    if (!(level >= T(settings.prune_throughput))) {
      const T survive = level / T(settings.prune_throughput);
      if (!settings.roulette || !(T(branch_random(ray_hash, b.path, 1u + std::uint32_t(c))) < survive)) {
        ++local.pruned;
        local.cut_weight += mean_component(w);
        continue;
      }
      w = w * S(T(1) / survive);
    }
    const float side = c == 0 ? incoming_side : -incoming_side;
    Branch<S> next{offset_origin(end.p, end.ng, side), c == 0 ? ev.wr : ev.wt, w, b.depth + 1,
                   (b.path << 1) | std::uint32_t(c)};
    child(next);
  }
}

// One branch's segment: it is sent to the BVH and either leaves the object,
// and light(weight × what it sees) is called, or it meets the surface, where
// its Fresnel children (the reflection first, then the refraction) are made
// and child(branch) is called for each that survives the depth cut, the
// drawn choice and the roulette; a branch that ends (cut, pruned, a
// degenerate triangle) calls neither (arrive(), then depart()). The loop of
// follow(), the queued branches of the device image (cuda/wavefront.hpp) and
// trace_recomputed (render/recomputed_trace.hpp) all take their branches
// through these. ray_hash: the camera ray's (camera_ray_hash); eta: the IoR.
template <class S, class Accel, class Reader, class Escape, class Light, class Child>
DT_HOST_DEVICE DT_FORCEINLINE void interact(const SceneView& scene, const Accel& accel, Reader& reader,
                                            const Branch<S>& b, const S& eta, std::uint64_t ray_hash,
                                            const TraceSettings& settings, TraceStats& local, const Escape& escape,
                                            Light&& light, Child&& child) {
  const SegmentEnd<S> end = arrive<S>(scene, accel, reader, b, settings, local, escape, light);
  if (end.more) depart<S>(b, end, eta, ray_hash, settings, local, child);
}

// The radiance the branch `root` brings to the camera: the branch and every
// branch it spawns, depth first (the tracer's loop over interact()).
// ray_hash: the camera ray's (camera_ray_hash), for the drawn and roulette
// choices; eta: the IoR; collect: SumBranches or StreamBranches.
template <class S, class Accel, class Reader, class Escape, class Collect = SumBranches>
DT_HOST_DEVICE Vec3<S> follow(const SceneView& scene, const Accel& accel, Reader& reader, const Branch<S>& root,
                              const S& eta, std::uint64_t ray_hash, const TraceSettings& settings, TraceStats& local,
                              const Escape& escape, const Collect& collect = Collect{}) {
  Vec3<S> radiance(S(0), S(0), S(0));
  Branch<S> stack[max_trace_depth + 2];
  int top = 0;
  stack[top++] = root;

  while (top > 0) {
    const Branch<S> b = stack[--top];
    collect.taken(b);
    interact<S>(
        scene, accel, reader, b, eta, ray_hash, settings, local, escape,
        [&](const Vec3<S>& light) { collect.add(radiance, light); },
        [&](Branch<S>& next) {  // the reflection is pushed first, the refraction traced first
          if constexpr (ad::is_ad_v<S>) {
            using T = ad::scalar_t<S>;
            if (!carries_derivatives(settings, next.depth, next.path)) {
              // a constant: its whole subtree in plain floating point, off the tape
              ad::ParamReader<T> values(reader.params());
              const Branch<T> plain{value_of(next.origin), value_of(next.direction), value_of(next.weight),
                                    next.depth, next.path};
              collect.add(radiance, lift<S>(follow<T>(scene, accel, values, plain, value_of(eta), ray_hash, settings,
                                                      local, escape)));
              return;
            }
          }
          collect.made(next);
          stack[top++] = next;
        });
  }
  return radiance;
}

// The hash of a camera ray's drawn and roulette choices (camera_ray_hash),
// or 0 when the settings draw nothing.
DT_HOST_DEVICE inline std::uint64_t choice_hash(const TraceSettings& settings, const Vec3f& origin,
                                                const Vec3f& direction) {
  const int max_depth = settings.max_depth < max_trace_depth ? settings.max_depth : max_trace_depth;
  return settings.tree_depth < max_depth || settings.roulette ? camera_ray_hash(origin, direction) : 0u;
}

// The camera ray (origin, direction) as the root branch: the IoR read once,
// the hash of the drawn and roulette choices, the loop, the counts.
// root_direction, when given, is the direction in S (value `direction`) with
// derivatives of its own (the ray differentials of render/footprint.hpp).
template <class S, class Accel, class Reader, class Escape, class Collect>
DT_HOST_DEVICE Vec3<S> trace_camera_ray(const SceneView& scene, const Accel& accel, Reader& reader, const Vec3f& origin,
                                        const Vec3f& direction, const TraceSettings& settings, TraceStats* stats,
                                        const Escape& escape, const Collect& collect,
                                        const Vec3<S>* root_direction = nullptr) {
  TraceStats local;
  const S eta = ad::load<S>(reader, scene.ior, 0);
  const std::uint64_t ray_hash = choice_hash(settings, origin, direction);
  Branch<S> root{lift<S>(origin), root_direction ? *root_direction : lift<S>(direction), Vec3<S>(S(1), S(1), S(1)), 0,
                 1u};
  collect.made(root);
  const Vec3<S> radiance = follow<S>(scene, accel, reader, root, eta, ray_hash, settings, local, escape, collect);
  if (stats) stats->add(local);
  return radiance;
}

}  // namespace detail

// Radiance (RGB) arriving at the camera along the ray (origin, direction).
// Accel: anything with `accel::RayHit intersect(Vec3f o, Vec3f d, float tnear,
// float tfar) const`. Reader: the pass's parameter reader (ad/params.hpp).
// Escape: see above (default: the scene's distant environment).
template <class S, class Accel, class Reader, class Escape = DistantEscape>
DT_HOST_DEVICE Vec3<S> trace(const SceneView& scene, const Accel& accel, Reader& reader, const Vec3f& origin,
                             const Vec3f& direction, const TraceSettings& settings, TraceStats* stats = nullptr,
                             const Escape& escape = Escape{}) {
  return detail::trace_camera_ray<S>(scene, accel, reader, origin, direction, settings, stats, escape,
                                     detail::SumBranches{});
}

// Streamed reverse mode: the gradient of adjoint · L(ray) added into the
// buffers of `reader`'s parameter set as the tree is traced (StreamBranches),
// with a tape bounded by the depth instead of the tree; returns the radiance
// L (values). The adjoint must be known before tracing (a loss gradient given
// per pixel; a loss of the pixel's own value needs a primal trace first).
// Equal to trace<Var<T>> + seed + propagate + scatter up to the order of
// float additions. The tape's peak() says how long it grew; an overflow of
// the tape or the leaf log loses part of the ray's gradient (the caller
// checks overflowed()).
template <class T, class Accel, class Escape = DistantEscape>
DT_HOST_DEVICE Vec3<T> trace_streamed(const SceneView& scene, const Accel& accel, ad::ParamReader<ad::Var<T>>& reader,
                                      const Vec3f& origin, const Vec3f& direction, const Vec3<T>& adjoint,
                                      const TraceSettings& settings, TraceStats* stats = nullptr,
                                      const Escape& escape = Escape{}) {
  ad::Tape<T>* tape = reader.tape();
  tape->reset();
  tape->zero_on_push(true);
  reader.clear();
  const detail::StreamBranches<T> collect{&reader, adjoint};
  const Vec3<ad::Var<T>> radiance =
      detail::trace_camera_ray<ad::Var<T>>(scene, accel, reader, origin, direction, settings, stats, escape, collect);
  collect.settle(1);  // what is left: the root's segment and the IoR
  tape->zero_on_push(false);
  return Vec3<T>(radiance.x.value, radiance.y.value, radiance.z.value);
}

}  // namespace difftrans::render
