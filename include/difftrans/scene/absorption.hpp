// Absorption inside the object (Beer–Lambert): none, homogeneous RGB, or an RGB
// grid over the object's box; transmittance of straight segments, generic over S.
// Length: the exact and the sampled integrals, the pieces the recomputed
// gradient sweeps apart (the interval, a cell's corners, one sample's share)
// and the corner reads with their softplus table share one cell walk and
// one parameterization, so they stay together.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/math.hpp"
#include "difftrans/ad/param_source.hpp"

namespace difftrans::scene {

// Parameterization: the field stores raw parameters p (any real), and the
// absorption coefficient is sigma = softplus(p) >= 0, applied in S where p is
// read, so an optimizer can never make it negative. Homogeneous: 3 raw values
// (RGB). Grid: res.x * res.y * res.z vertices spanning the box [lo, hi]
// (vertex (i, j, k) at lo + (i, j, k) * (hi - lo) / (res - 1)), RGB each,
// flat: index = ((k * res.y + j) * res.x + i) * 3 + channel.
//
// What is interpolated: sigma = softplus(p) is evaluated at the grid vertices
// and THEN interpolated trilinearly, so sigma is a trilinear polynomial inside
// each cell. Restricted to a line, that is a cubic in the line parameter, and
// 2-point Gauss–Legendre integrates it exactly: the "exact" integration below
// is exact up to rounding. Outside the box the grid's sigma is 0. The
// homogeneous case has no box: it is the same everywhere (the tracer only asks
// for segments inside the object).

enum class AbsorptionKind : int { none, homogeneous, grid };

struct AbsorptionField {
  AbsorptionKind kind = AbsorptionKind::none;
  ad::ParamSource params;  // raw parameters p (sigma = softplus(p))
  Vec3f lo{0.0f}, hi{1.0f};
  Vec3i res{2, 2, 2};  // grid vertices per axis, each >= 2
  // Optional: softplus(p) and its slope sigmoid(p) of every raw parameter,
  // interleaved (entries 2i and 2i + 1 for parameter i), made from
  // params.values by fill_softplus_table. A float pass then reads sigma from
  // it instead of evaluating softplus at each read (24 per grid cell a
  // segment's samples enter), with the same bits; passes in another
  // precision evaluate as without it. nullptr: evaluated at each read.
  const float* softplus_table = nullptr;
};

// How a grid segment is integrated.
struct AbsorptionIntegration {
  int samples = 0;      // 0: exact, cell by cell; K > 0: K stratified samples
  float offset = 0.5f;  // K > 0: where each sample sits in its stratum, in [0, 1): 0.5 is the midpoint
                        // rule; a random offset per ray gives unbiased (shifted-stratified) estimates
};

// Beyond this optical depth the transmittance is taken as exactly 0 with a
// zero derivative (exp underflows there in float and double alike), so huge
// or infinite depths never turn 0 * inf into NaN.
template <class T> inline constexpr T max_optical_depth = T(1000);

// ------------------------------------------------------------ host helpers

// The raw parameter whose softplus is sigma (sigma is floored at 1e-8 so the
// result stays finite; use AbsorptionKind::none for clear glass).
inline float raw_from_sigma(float sigma) {
  const double s = sigma > 1e-8f ? double(sigma) : 1e-8;
  return float(s > 30.0 ? s + std::log(-std::expm1(-s)) : std::log(std::expm1(s)));
}

inline AbsorptionField no_absorption() { return AbsorptionField{}; }

// AbsorptionField::softplus_table of n raw parameters into table (2n floats),
// with the functions the passes evaluate.
inline void fill_softplus_table(const float* raw, std::size_t n, float* table) {
  for (std::size_t i = 0; i < n; ++i) {
    table[2 * i] = ad::softplus(raw[i]);
    table[2 * i + 1] = ad::sigmoid(raw[i]);
  }
}

inline AbsorptionField homogeneous_absorption(const float* raw_rgb, int buffer = -1) {
  AbsorptionField f;
  f.kind = AbsorptionKind::homogeneous;
  f.params = ad::ParamSource{raw_rgb, 3, buffer};
  return f;
}

inline AbsorptionField grid_absorption(const float* raw, const Vec3i& res, const Vec3f& lo, const Vec3f& hi,
                                       int buffer = -1) {
  AbsorptionField f;
  f.kind = AbsorptionKind::grid;
  f.params = ad::ParamSource{raw, std::int32_t(res.x) * res.y * res.z * 3, buffer};
  f.lo = lo;
  f.hi = hi;
  f.res = res;
  return f;
}

DT_HOST_DEVICE constexpr std::int32_t grid_index(const Vec3i& res, int i, int j, int k, int channel) {
  return ((std::int32_t(k) * res.y + j) * res.x + i) * 3 + channel;
}

// ------------------------------------------------------------ generic path

namespace detail {

// sigma = softplus(p) of raw parameter i, from the field's table when it has
// one and the pass is in float.
template <class S, class Reader>
DT_HOST_DEVICE DT_FORCEINLINE S sigma_of_parameter(Reader& reader, const AbsorptionField& f, std::int32_t i) {
  const S p = ad::load<S>(reader, f.params, i);
  if constexpr (std::is_same_v<ad::scalar_t<S>, float>) {
    if (f.softplus_table) return ad::known_unary(p, f.softplus_table[2 * i], f.softplus_table[2 * i + 1]);
  }
  return softplus(p);
}

// The 8 corners' sigma (RGB) of one grid cell, read and mapped through softplus.
template <class S>
struct CellSigma {
  Vec3i cell;
  Vec3<S> corner[8];  // corner c = (c & 1, (c >> 1) & 1, (c >> 2) & 1), the FlexiCubes order
};

template <class S, class Reader>
DT_HOST_DEVICE void read_cell(Reader& reader, const AbsorptionField& f, const Vec3i& cell, CellSigma<S>& out) {
  out.cell = cell;
  for (int c = 0; c < 8; ++c) {
    const int i = cell.x + (c & 1), j = cell.y + ((c >> 1) & 1), k = cell.z + ((c >> 2) & 1);
    const std::int32_t base = grid_index(f.res, i, j, k, 0);
    for (int ch = 0; ch < 3; ++ch) out.corner[c][ch] = sigma_of_parameter<S>(reader, f, base + ch);
  }
}

// The 8 trilinear weights at local coordinates l in [0, 1]^3 of a cell.
template <class S>
DT_HOST_DEVICE void trilinear_weights(const Vec3<S>& l, S w[8]) {
  using T = ad::scalar_t<S>;
  const S mx = T(1) - l.x, my = T(1) - l.y, mz = T(1) - l.z;
  const S xy[4] = {mx * my, l.x * my, mx * l.y, l.x * l.y};
  for (int c = 0; c < 4; ++c) {
    w[c] = xy[c] * mz;
    w[c + 4] = xy[c] * l.z;
  }
}

// Grid coordinates (in cells) of a world point, and the cell containing a
// value-level point (clamped to the grid).
template <class T>
struct GridFrame {
  Vec3<T> lo;
  Vec3<T> inv_cell;  // cells per unit length
  Vec3i cells;       // res - 1
};

template <class T>
DT_HOST_DEVICE GridFrame<T> grid_frame(const AbsorptionField& f) {
  GridFrame<T> g;
  g.cells = f.res - Vec3i(1);
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = T(f.lo[a]);
    g.inv_cell[a] = T(g.cells[a]) / (T(f.hi[a]) - T(f.lo[a]));
  }
  return g;
}

template <class T>
DT_HOST_DEVICE Vec3i cell_of(const GridFrame<T>& g, const Vec3<T>& grid_coord) {
  Vec3i c;
  for (int a = 0; a < 3; ++a) {
    const T fl = floor(grid_coord[a]);
    c[a] = fl < T(0) ? 0 : (fl > T(g.cells[a] - 1) ? g.cells[a] - 1 : int(fl));
  }
  return c;
}

// sum_c corner[c] * w[c], RGB
template <class S>
DT_HOST_DEVICE Vec3<S> blend(const CellSigma<S>& cs, const S w[8]) {
  Vec3<S> r;
  for (int ch = 0; ch < 3; ++ch) {
    S acc = cs.corner[0][ch] * w[0];
    for (int c = 1; c < 8; ++c) acc = acc + cs.corner[c][ch] * w[c];
    r[ch] = acc;
  }
  return r;
}

// The part [t_in, t_out] of the segment a + t (b - a), t in [0, 1], inside
// the box, decided on values. Each end remembers the axis (0-2) of the box
// face that cut it, or -1 when it is the segment's own end.
template <class T>
struct Clip {
  T t_in, t_out;
  int axis_in, axis_out;
  bool hit;
};

template <class T>
DT_HOST_DEVICE Clip<T> clip_segment(const Vec3<T>& a, const Vec3<T>& b, const Vec3f& lo, const Vec3f& hi) {
  Clip<T> c{T(0), T(1), -1, -1, true};
  for (int ax = 0; ax < 3; ++ax) {
    const T d = b[ax] - a[ax];
    if (d == T(0)) {
      if (a[ax] < T(lo[ax]) || a[ax] > T(hi[ax])) c.hit = false;
      continue;
    }
    T t0 = (T(lo[ax]) - a[ax]) / d, t1 = (T(hi[ax]) - a[ax]) / d;
    if (t0 > t1) {
      const T s = t0;
      t0 = t1;
      t1 = s;
    }
    if (t0 > c.t_in) {
      c.t_in = t0;
      c.axis_in = ax;
    }
    if (t1 < c.t_out) {
      c.t_out = t1;
      c.axis_out = ax;
    }
  }
  if (!(c.t_in < c.t_out)) c.hit = false;
  return c;
}

// The clipped end in S: where the segment crosses the box face of `axis`, so
// that the integral's derivative carries the boundary term of the moving end.
template <class S>
DT_HOST_DEVICE S clip_end(const Vec3<S>& a, const Vec3<S>& b, int axis, ad::scalar_t<S> t_value,
                          const Vec3f& lo, const Vec3f& hi) {
  using T = ad::scalar_t<S>;
  if (axis < 0) return S(t_value);
  // the face (lo or hi) whose crossing parameter is t_value: the nearer one
  const T av = ad::value_of(a[axis]), d = ad::value_of(b[axis]) - av;
  const T tl = (T(lo[axis]) - av) / d, th = (T(hi[axis]) - av) / d;
  const T face = abs(tl - t_value) <= abs(th - t_value) ? T(lo[axis]) : T(hi[axis]);
  return (face - a[axis]) / (b[axis] - a[axis]);
}

template <class S>
DT_HOST_DEVICE Vec3<S> grid_point(const GridFrame<ad::scalar_t<S>>& g, const Vec3<S>& a, const Vec3<S>& ab, const S& t) {
  Vec3<S> p;
  for (int ax = 0; ax < 3; ++ax) p[ax] = (a[ax] + t * ab[ax] - g.lo[ax]) * g.inv_cell[ax];
  return p;
}

// Exact integral of sigma over the parameter interval of the clipped segment,
// per unit of t (multiply by |b - a| for the optical depth): a walk over the
// cells the segment crosses (3D DDA), 2-point Gauss–Legendre in each. The
// interior cell boundaries are taken on values: the integrand is continuous,
// so their derivative terms cancel pairwise and leaving them out is exact.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> integrate_grid_exact(Reader& reader, const AbsorptionField& f, const Vec3<S>& a,
                                            const Vec3<S>& b, const Clip<ad::scalar_t<S>>& clip) {
  using T = ad::scalar_t<S>;
  const GridFrame<T> g = grid_frame<T>(f);
  const Vec3<S> ab = b - a;
  const Vec3<T> av = ad::value_of(a), abv = ad::value_of(b) - av;
  Vec3<T> ga, dg;  // grid coordinates of a, and their rate per unit t
  for (int ax = 0; ax < 3; ++ax) {
    ga[ax] = (av[ax] - g.lo[ax]) * g.inv_cell[ax];
    dg[ax] = abv[ax] * g.inv_cell[ax];
  }
  // next plane crossing per axis
  Vec3<T> t_next;
  int plane[3], step[3];
  for (int ax = 0; ax < 3; ++ax) {
    const T g0 = ga[ax] + clip.t_in * dg[ax];
    if (dg[ax] > T(0)) {
      step[ax] = 1;
      plane[ax] = int(floor(g0)) + 1;
    } else if (dg[ax] < T(0)) {
      step[ax] = -1;
      plane[ax] = int(ceil(g0)) - 1;
    } else {
      step[ax] = 0;
      plane[ax] = 0;
    }
    t_next[ax] = step[ax] != 0 ? (T(plane[ax]) - ga[ax]) / dg[ax] : T(2);
  }
  const S t_first = clip_end(a, b, clip.axis_in, clip.t_in, f.lo, f.hi);
  const S t_last = clip_end(a, b, clip.axis_out, clip.t_out, f.lo, f.hi);
  const T gl = T(0.28867513459481288225);  // 1 / (2 sqrt 3): Gauss–Legendre nodes at mid ± gl * h
  Vec3<S> sum(S(0), S(0), S(0));
  CellSigma<S> cs;
  T t = clip.t_in;
  bool first = true;
  // every step crosses at least one plane; the margin absorbs rounding at the ends
  const int max_steps = g.cells.x + g.cells.y + g.cells.z + 8;
  for (int it = 0; it < max_steps; ++it) {
    T tn = clip.t_out;
    for (int ax = 0; ax < 3; ++ax) tn = t_next[ax] < tn ? t_next[ax] : tn;
    if (tn > t) {
      const T tm = T(0.5) * (t + tn);
      const Vec3i cell = cell_of(g, Vec3<T>(ga + tm * dg));
      read_cell(reader, f, cell, cs);
      const S t0 = first ? t_first : S(t);
      first = false;
      const S t1 = tn == clip.t_out ? t_last : S(tn);
      const S h = t1 - t0, mid = T(0.5) * (t0 + t1);
      const S nodes[2] = {mid - gl * h, mid + gl * h};
      S wsum[8];
      for (int q = 0; q < 2; ++q) {
        const Vec3<S> p = grid_point(g, a, ab, nodes[q]);
        const Vec3<S> l(p.x - T(cell.x), p.y - T(cell.y), p.z - T(cell.z));
        S w[8];
        trilinear_weights(l, w);
        for (int c = 0; c < 8; ++c) wsum[c] = q == 0 ? w[c] : wsum[c] + w[c];
      }
      const S half = T(0.5) * h;
      for (int c = 0; c < 8; ++c) wsum[c] = wsum[c] * half;
      sum += blend(cs, wsum);
    }
    if (!(tn < clip.t_out)) break;
    for (int ax = 0; ax < 3; ++ax) {
      if (step[ax] != 0 && t_next[ax] <= tn) {
        plane[ax] += step[ax];
        t_next[ax] = (T(plane[ax]) - ga[ax]) / dg[ax];
      }
    }
    t = tn;
  }
  return sum;
}

// The stratified samples' interval: where the segment [a, b] enters and
// leaves the grid's box, in its parameter t, in S.
template <class S>
struct SampledSpan {
  Vec3<S> ab;
  S t_first, span;
};
template <class S>
DT_HOST_DEVICE SampledSpan<S> sampled_span(const AbsorptionField& f, const Vec3<S>& a, const Vec3<S>& b,
                                           const Clip<ad::scalar_t<S>>& clip) {
  SampledSpan<S> r;
  r.ab = b - a;
  r.t_first = clip_end(a, b, clip.axis_in, clip.t_in, f.lo, f.hi);
  r.span = clip_end(a, b, clip.axis_out, clip.t_out, f.lo, f.hi) - r.t_first;
  return r;
}

// Sigma (RGB) at sample k of K over the interval: the cell's corners read
// into cs unless `have` says cs already holds that cell. `known`: the
// sample's cell as the caller chose it (sample_cell), used as given.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> sigma_at_sample(Reader& reader, const AbsorptionField& f, const GridFrame<ad::scalar_t<S>>& g,
                                       const Vec3<S>& a, const SampledSpan<S>& in, int k, int samples, float offset,
                                       CellSigma<S>& cs, bool& have, const Vec3i* known = nullptr) {
  using T = ad::scalar_t<S>;
  const S t = in.t_first + in.span * ((T(k) + T(offset)) / T(samples));
  const Vec3<S> p = grid_point(g, a, in.ab, t);
  const Vec3i cell = known ? *known : cell_of(g, ad::value_of(p));
  if (!have || cell != cs.cell) {
    read_cell(reader, f, cell, cs);
    have = true;
  }
  const Vec3<S> l(p.x - T(cell.x), p.y - T(cell.y), p.z - T(cell.z));
  S w[8];
  trilinear_weights(l, w);
  return blend(cs, w);
}

// K stratified samples over the clipped parameter interval, per unit of t.
// Consecutive samples in the same cell share one read of its corners.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> integrate_grid_samples(Reader& reader, const AbsorptionField& f, const Vec3<S>& a,
                                              const Vec3<S>& b, const Clip<ad::scalar_t<S>>& clip, int samples,
                                              float offset) {
  using T = ad::scalar_t<S>;
  const GridFrame<T> g = grid_frame<T>(f);
  const SampledSpan<S> in = sampled_span(f, a, b, clip);
  Vec3<S> sum(S(0), S(0), S(0));
  CellSigma<S> cs;
  bool have = false;
  for (int k = 0; k < samples; ++k) sum += sigma_at_sample(reader, f, g, a, in, k, samples, offset, cs, have);
  const S scale = in.span / T(samples > 0 ? samples : 1);
  return sum * scale;
}

}  // namespace detail

// sigma (RGB) at world point x, generic over S: zero for none, and for the
// grid outside its box.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> sigma_at(Reader& reader, const AbsorptionField& f, const Vec3<S>& x) {
  using T = ad::scalar_t<S>;
  if (f.kind == AbsorptionKind::none) return Vec3<S>(S(0), S(0), S(0));
  if (f.kind == AbsorptionKind::homogeneous) {
    return Vec3<S>(detail::sigma_of_parameter<S>(reader, f, 0), detail::sigma_of_parameter<S>(reader, f, 1),
                   detail::sigma_of_parameter<S>(reader, f, 2));
  }
  const Vec3<T> xv = ad::value_of(x);
  for (int ax = 0; ax < 3; ++ax)
    if (!(xv[ax] >= T(f.lo[ax]) && xv[ax] <= T(f.hi[ax]))) return Vec3<S>(S(0), S(0), S(0));
  const detail::GridFrame<T> g = detail::grid_frame<T>(f);
  Vec3<S> p;
  for (int ax = 0; ax < 3; ++ax) p[ax] = (x[ax] - g.lo[ax]) * g.inv_cell[ax];
  const Vec3i cell = detail::cell_of(g, ad::value_of(p));
  detail::CellSigma<S> cs;
  detail::read_cell(reader, f, cell, cs);
  S w[8];
  detail::trilinear_weights(Vec3<S>(p.x - T(cell.x), p.y - T(cell.y), p.z - T(cell.z)), w);
  return detail::blend(cs, w);
}

// Optical depth (RGB) of the straight segment [a, b]: the integral of sigma
// along it. Generic over S, differentiable with respect to the raw
// parameters (through the reader) and to both ends. The loop is bounded by
// the grid size (exact) or by integration.samples.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> optical_depth(Reader& reader, const AbsorptionField& f, const Vec3<S>& a, const Vec3<S>& b,
                                     const AbsorptionIntegration& integration = {}) {
  using T = ad::scalar_t<S>;
  const Vec3<S> zero(S(0), S(0), S(0));
  if (f.kind == AbsorptionKind::none) return zero;
  const Vec3<S> ab = b - a;
  // safe_sqrt: a zero-length segment has length 0 and a zero (not NaN) derivative
  const S length = safe_sqrt(glm::dot(ab, ab));
  if (f.kind == AbsorptionKind::homogeneous) return sigma_at(reader, f, a) * length;
  if (!(ad::value_of(length) > T(0))) return zero;
  const detail::Clip<T> clip = detail::clip_segment(ad::value_of(a), ad::value_of(b), f.lo, f.hi);
  if (!clip.hit) return zero;
  const Vec3<S> per_t = integration.samples > 0
                            ? detail::integrate_grid_samples(reader, f, a, b, clip, integration.samples,
                                                             integration.offset)
                            : detail::integrate_grid_exact(reader, f, a, b, clip);
  return per_t * length;
}

// A grid segment [a, b] integrated by samples (integration.samples = K >
// 0), in pieces, as a reverse pass that records, sweeps and cuts them one at
// a time takes them: the interval inside the box and each sample's weight
// (that interval's length / K, in S), computed once; the cell a sample lies
// in (sample_cell, on values); sigma at a sample from the corners of that
// cell, read beforehand (detail::read_cell), so that a sample's share reads
// no parameter. sample_share(k) is sample k's share of optical_depth —
// sigma × weight — and the K shares add up to it (up to the order of the
// float sums). hit is false (nothing to integrate) for a segment of zero
// length or missing the box, and for any other field or integration.
template <class S>
struct SampledSegment {
  bool hit = false;
  int samples = 0;
  float offset = 0.5f;
  detail::GridFrame<ad::scalar_t<S>> grid;
  Vec3<S> a;
  detail::SampledSpan<S> span;
  S weight;
};
template <class S>
DT_HOST_DEVICE SampledSegment<S> sampled_segment(const AbsorptionField& f, const Vec3<S>& a, const Vec3<S>& b,
                                                 const AbsorptionIntegration& integration) {
  using T = ad::scalar_t<S>;
  SampledSegment<S> r;
  if (f.kind != AbsorptionKind::grid || integration.samples <= 0) return r;
  const Vec3<S> ab = b - a;
  const S length = safe_sqrt(glm::dot(ab, ab));
  if (!(ad::value_of(length) > T(0))) return r;
  const detail::Clip<T> clip = detail::clip_segment(ad::value_of(a), ad::value_of(b), f.lo, f.hi);
  if (!clip.hit) return r;
  r.hit = true;
  r.samples = integration.samples;
  r.offset = integration.offset;
  r.grid = detail::grid_frame<T>(f);
  r.a = a;
  r.span = detail::sampled_span(f, a, b, clip);
  r.weight = r.span.span / T(integration.samples) * length;
  return r;
}
// The cell of sample k (values).
template <class S>
DT_HOST_DEVICE Vec3i sample_cell(const SampledSegment<S>& s, int k) {
  using T = ad::scalar_t<S>;
  const T t = ad::value_of(s.span.t_first) + ad::value_of(s.span.span) * ((T(k) + T(s.offset)) / T(s.samples));
  return detail::cell_of(s.grid, detail::grid_point(s.grid, ad::value_of(s.a), ad::value_of(s.span.ab), t));
}
// Sample k's share; `corners` must hold sample_cell(s, k)'s corners.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> sample_share(Reader& reader, const AbsorptionField& f, const SampledSegment<S>& s, int k,
                                    const detail::CellSigma<S>& corners) {
  detail::CellSigma<S> cs = corners;
  bool have = true;
  const Vec3i cell = corners.cell;
  return detail::sigma_at_sample(reader, f, s.grid, s.a, s.span, k, s.samples, s.offset, cs, have, &cell) * s.weight;
}

// The shares of the samples [first, end) summed: zero for an empty or
// out-of-range interval.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> optical_depth_share(Reader& reader, const AbsorptionField& f, const Vec3<S>& a,
                                           const Vec3<S>& b, const AbsorptionIntegration& integration, int first,
                                           int end) {
  Vec3<S> sum(S(0), S(0), S(0));
  const SampledSegment<S> s = sampled_segment(f, a, b, integration);
  if (!s.hit || first < 0 || end > s.samples) return sum;
  detail::CellSigma<S> cs;
  bool have = false;
  for (int k = first; k < end; ++k) {
    const Vec3i cell = sample_cell(s, k);
    if (!have || cell != cs.cell) detail::read_cell(reader, f, cell, cs);
    have = true;
    sum += sample_share(reader, f, s, k, cs);
  }
  return sum;
}

// exp(-tau) per channel, with tau clamped at max_optical_depth (value 0 and
// derivative 0 beyond it).
template <class S>
DT_HOST_DEVICE Vec3<S> transmittance_from_depth(const Vec3<S>& tau) {
  using T = ad::scalar_t<S>;
  Vec3<S> r;
  for (int ch = 0; ch < 3; ++ch) r[ch] = exp(-min(tau[ch], S(max_optical_depth<T>)));
  return r;
}

// Beer–Lambert transmittance (RGB) of the segment [a, b].
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> transmittance(Reader& reader, const AbsorptionField& f, const Vec3<S>& a, const Vec3<S>& b,
                                     const AbsorptionIntegration& integration = {}) {
  if (f.kind == AbsorptionKind::none) return Vec3<S>(S(1), S(1), S(1));
  return transmittance_from_depth(optical_depth(reader, f, a, b, integration));
}

}  // namespace difftrans::scene
