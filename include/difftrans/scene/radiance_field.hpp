// Near-field environment: a dense voxel grid of density and RGB colour over an
// axis-aligned box, rendered by alpha compositing along rays. The query is
// written once over the float type, device-copyable and allocation-free (the
// tracer calls it for rays that leave the object); the training gradient is a
// hand-written backward pass (host), checked against central differences in
// tests/scene/radiance_field.test.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/core/parallel.hpp"

namespace difftrans::scene {

// Layout. res = (nx, ny, nz) grid vertices, each ≥ 2; vertex (i, j, k) lies at
// lo + (i, j, k)·(hi − lo)/(res − 1) and its four raw values start at
// ((k·ny + j)·nx + i)·4: density, red, green, blue. The raw values are
// interpolated trilinearly, then activated (sharper than activating first):
//   σ = density_scale · softplus(raw density)   per unit length,
//   c = softplus(raw colour)                    linear radiance, unbounded.
// Rendering: samples at t = t0 + (k + offset)·step from where the ray enters
// the box (t0 = 0 when it starts inside), α = 1 − exp(−σ·step),
//   C = Σ_k T_k α_k c_k + T_end · background,  T_{k+1} = T_k (1 − α_k);
// marching stops once T falls below min_transmittance (T_end is then that
// small remainder). A cell (the box between 8 vertices) whose occupancy byte
// is 0 is known to be empty (σ below the pruning threshold at all its
// corners, so everywhere inside it): its samples are skipped.
struct RadianceFieldView {
  const float* values = nullptr;
  const std::uint8_t* occupancy = nullptr;  // (nx−1)(ny−1)(nz−1) cells, x fastest; null: every cell is visited
  Vec3i res{0, 0, 0};
  Vec3f lo{0.0f}, hi{0.0f};
  float step = 0.05f;                // world units between samples
  float density_scale = 10.0f;
  float min_transmittance = 1e-3f;   // 0: never stop early
  Vec3f background{0.0f};            // radiance beyond the box
};

namespace detail {

// Trilinear footprint of a point: the offset of the (0,0,0) corner's values,
// the cell index and the fractions along x, y, z. false outside the box.
template <class T>
struct FieldCell {
  std::int32_t base;   // ((k·ny + j)·nx + i)·4
  std::int32_t cell;   // (k·(ny−1) + j)·(nx−1) + i
  T fx, fy, fz;
};

template <class T>
DT_HOST_DEVICE bool field_cell(const RadianceFieldView& f, const Vec3<T>& p, FieldCell<T>& out) {
  T g[3];
  int idx[3];
  for (int a = 0; a < 3; ++a) {
    const T span = T(f.hi[a]) - T(f.lo[a]);
    g[a] = (p[a] - T(f.lo[a])) / span * T(f.res[a] - 1);
    if (!(g[a] >= T(0) && g[a] <= T(f.res[a] - 1))) return false;  // also rejects NaN
    int i = int(floor(g[a]));
    if (i > f.res[a] - 2) i = f.res[a] - 2;
    idx[a] = i;
    g[a] -= T(i);
  }
  out.base = ((std::int32_t(idx[2]) * f.res.y + idx[1]) * f.res.x + idx[0]) * 4;
  out.cell = (std::int32_t(idx[2]) * (f.res.y - 1) + idx[1]) * (f.res.x - 1) + idx[0];
  out.fx = g[0];
  out.fy = g[1];
  out.fz = g[2];
  return true;
}

// Offsets (in floats) of the 8 corners from base, corner c = x + 2y + 4z.
DT_HOST_DEVICE inline std::int32_t corner_offset(const RadianceFieldView& f, int c) {
  return ((std::int32_t((c >> 2) & 1) * f.res.y + ((c >> 1) & 1)) * f.res.x + (c & 1)) * 4;
}

template <class T>
DT_HOST_DEVICE T corner_weight(const FieldCell<T>& q, int c) {
  return ((c & 1) ? q.fx : T(1) - q.fx) * ((c & 2) ? q.fy : T(1) - q.fy) * ((c & 4) ? q.fz : T(1) - q.fz);
}

// The four raw values at a point of the cell (trilinear).
template <class T, class V>
DT_HOST_DEVICE void interpolate_raw(const RadianceFieldView& f, const V* values, const FieldCell<T>& q, T raw[4]) {
  for (int ch = 0; ch < 4; ++ch) raw[ch] = T(0);
  for (int c = 0; c < 8; ++c) {
    const T w = corner_weight(q, c);
    const V* v = values + q.base + corner_offset(f, c);
    for (int ch = 0; ch < 4; ++ch) raw[ch] += w * T(v[ch]);
  }
}

// Entry and exit distances of the ray o + t·d with the box, t clamped at 0;
// false when it misses (or the box lies behind).
template <class T>
DT_HOST_DEVICE bool box_span(const Vec3f& lo, const Vec3f& hi, const Vec3<T>& o, const Vec3<T>& d, T& t0, T& t1) {
  t0 = T(0);
  t1 = T(3.0e38);
  for (int a = 0; a < 3; ++a) {
    if (abs(d[a]) < T(1e-30)) {
      if (o[a] < T(lo[a]) || o[a] > T(hi[a])) return false;
      continue;
    }
    const T inv = T(1) / d[a];
    T ta = (T(lo[a]) - o[a]) * inv, tb = (T(hi[a]) - o[a]) * inv;
    if (ta > tb) {
      const T s = ta;
      ta = tb;
      tb = s;
    }
    t0 = ta > t0 ? ta : t0;
    t1 = tb < t1 ? tb : t1;
  }
  return t0 < t1;
}

}  // namespace detail

// σ (per unit length) and colour at a point; zeros outside the box.
template <class T>
DT_HOST_DEVICE void field_sample(const RadianceFieldView& f, const Vec3<T>& p, T& sigma, Vec3<T>& colour) {
  detail::FieldCell<T> q;
  sigma = T(0);
  colour = Vec3<T>(T(0));
  if (!detail::field_cell(f, p, q)) return;
  T raw[4];
  detail::interpolate_raw(f, f.values, q, raw);
  sigma = T(f.density_scale) * softplus(raw[0]);
  colour = Vec3<T>(softplus(raw[1]), softplus(raw[2]), softplus(raw[3]));
}

// Radiance arriving at o from direction d (need not be unit) through the
// field: the forward pass of the volume renderer. offset ∈ [0, 1) places the
// samples within their steps (0.5 for rendering; random while training).
template <class T>
DT_HOST_DEVICE Vec3<T> field_radiance(const RadianceFieldView& f, const Vec3<T>& o, const Vec3<T>& d_in,
                                      T offset = T(0.5)) {
  const T len = sqrt(glm::dot(d_in, d_in));
  const Vec3<T> bg(T(f.background.x), T(f.background.y), T(f.background.z));
  if (!(len > T(0))) return bg;
  const Vec3<T> d = d_in / len;
  T t0, t1;
  if (!detail::box_span(f.lo, f.hi, o, d, t0, t1)) return bg;
  const T step = T(f.step), scale = T(f.density_scale), min_t = T(f.min_transmittance);
  T trans = T(1);
  Vec3<T> c(T(0));
  for (int k = 0;; ++k) {
    const T t = t0 + (T(k) + offset) * step;
    if (t >= t1) break;
    detail::FieldCell<T> q;
    if (!detail::field_cell(f, Vec3<T>(o + d * t), q)) continue;
    if (f.occupancy && !f.occupancy[q.cell]) continue;
    T raw[4];
    detail::interpolate_raw(f, f.values, q, raw);
    const T alpha = T(1) - exp(-scale * softplus(raw[0]) * step);
    const T w = trans * alpha;
    c += w * Vec3<T>(softplus(raw[1]), softplus(raw[2]), softplus(raw[3]));
    trans -= w;
    if (trans < min_t) break;
  }
  return c + trans * bg;
}

// The field as a near-field environment: radiance(origin, direction), for
// render::FixedEscape and the environment views.
struct FieldRadiance {
  RadianceFieldView field;
  DT_HOST_DEVICE Vec3f operator()(const Vec3f& o, const Vec3f& d) const { return field_radiance<float>(field, o, d); }
};

// What the backward pass keeps of one visited sample.
template <class T>
struct FieldSampleRecord {
  detail::FieldCell<T> cell;
  T trans;           // T_k, before the sample
  T alpha;
  T dalpha_draw;     // dα / d(raw density)
  Vec3<T> colour;
  Vec3<T> dcolour_draw;  // d c / d(raw colour), per channel
};

// The forward pass of field_radiance, recording every visited sample, then
// the reverse pass: given the colour C, `adjoint(C)` returns dLoss/dC and the
// gradient is added to grad (the values' layout) and grad_background (3).
// Returns C. Equal to field_radiance in value.
template <class T, class Adjoint, class G>
Vec3<T> field_radiance_backward(const RadianceFieldView& f, const Vec3<T>& o, const Vec3<T>& d_in, T offset,
                                Adjoint&& adjoint, G* grad, G* grad_background,
                                std::vector<FieldSampleRecord<T>>& scratch) {
  scratch.clear();
  const Vec3<T> bg(T(f.background.x), T(f.background.y), T(f.background.z));
  const T len = std::sqrt(glm::dot(d_in, d_in));
  T trans = T(1);
  Vec3<T> c(T(0));
  if (len > T(0)) {
    const Vec3<T> d = d_in / len;
    T t0, t1;
    if (detail::box_span(f.lo, f.hi, o, d, t0, t1)) {
      const T step = T(f.step), scale = T(f.density_scale), min_t = T(f.min_transmittance);
      for (int k = 0;; ++k) {
        const T t = t0 + (T(k) + offset) * step;
        if (t >= t1) break;
        FieldSampleRecord<T> r;
        if (!detail::field_cell(f, Vec3<T>(o + d * t), r.cell)) continue;
        if (f.occupancy && !f.occupancy[r.cell.cell]) continue;
        T raw[4];
        detail::interpolate_raw(f, f.values, r.cell, raw);
        const T tau = scale * softplus(raw[0]) * step;
        const T keep = std::exp(-tau);
        r.trans = trans;
        r.alpha = T(1) - keep;
        r.dalpha_draw = keep * scale * step * sigmoid(raw[0]);
        for (int ch = 0; ch < 3; ++ch) {
          r.colour[ch] = softplus(raw[1 + ch]);
          r.dcolour_draw[ch] = sigmoid(raw[1 + ch]);
        }
        const T w = trans * r.alpha;
        c += w * r.colour;
        trans -= w;
        scratch.push_back(r);
        if (trans < min_t) break;
      }
    }
  }
  const Vec3<T> C = c + trans * bg;
  const Vec3<T> g = adjoint(C);
  for (int ch = 0; ch < 3; ++ch) grad_background[ch] += G(trans * g[ch]);
  // reverse: Q = radiance seen just after sample k, normalized by T_{k+1}
  Vec3<T> Q = bg;
  for (std::size_t n = scratch.size(); n-- > 0;) {
    const FieldSampleRecord<T>& r = scratch[n];
    const T d_alpha = r.trans * glm::dot(g, r.colour - Q);  // dC/dα_k = T_k (c_k − Q_{k+1})
    T d_raw[4];
    d_raw[0] = d_alpha * r.dalpha_draw;
    const T wt = r.trans * r.alpha;
    for (int ch = 0; ch < 3; ++ch) d_raw[1 + ch] = wt * g[ch] * r.dcolour_draw[ch];
    Q = r.alpha * r.colour + (T(1) - r.alpha) * Q;
    for (int corner = 0; corner < 8; ++corner) {
      const T w = detail::corner_weight(r.cell, corner);
      G* dst = grad + r.cell.base + detail::corner_offset(f, corner);
      for (int ch = 0; ch < 4; ++ch) dst[ch] += G(w * d_raw[ch]);
    }
  }
  return C;
}

// The field, owned on the host.
class RadianceField {
 public:
  Vec3i res{2, 2, 2};
  Vec3f lo{-1.0f}, hi{1.0f};
  float density_scale = 10.0f;
  float step_voxels = 0.5f;          // sample spacing in units of the smallest vertex spacing
  float min_transmittance = 1e-3f;
  Vec3f background{0.0f};
  std::vector<float> values;          // res.x·res.y·res.z·4 raw values (layout above)
  std::vector<std::uint8_t> occupancy;  // empty: every cell visited

  RadianceField() = default;
  // A field of constant raw values over the box [lo, hi].
  RadianceField(const Vec3i& r, const Vec3f& box_lo, const Vec3f& box_hi, float density_raw, float colour_raw)
      : res(r), lo(box_lo), hi(box_hi) {
    check();
    values.resize(vertex_count() * 4);
    for (std::size_t v = 0; v < vertex_count(); ++v) {
      values[v * 4] = density_raw;
      for (int ch = 1; ch < 4; ++ch) values[v * 4 + ch] = colour_raw;
    }
  }

  std::size_t vertex_count() const { return std::size_t(res.x) * std::size_t(res.y) * std::size_t(res.z); }
  std::size_t cell_count() const { return std::size_t(res.x - 1) * std::size_t(res.y - 1) * std::size_t(res.z - 1); }
  Vec3f spacing() const { return (hi - lo) / Vec3f(res - 1); }
  float step() const {
    const Vec3f s = spacing();
    return step_voxels * std::min(s.x, std::min(s.y, s.z));
  }

  // Throws std::invalid_argument naming what is wrong.
  void check() const {
    if (res.x < 2 || res.y < 2 || res.z < 2) throw std::invalid_argument("radiance field: every resolution must be >= 2");
    if (double(res.x) * res.y * res.z > 1024.0 * 1024.0 * 1024.0)
      throw std::invalid_argument("radiance field: resolution too large");
    for (int a = 0; a < 3; ++a)
      if (!(hi[a] > lo[a]) || !std::isfinite(lo[a]) || !std::isfinite(hi[a]))
        throw std::invalid_argument("radiance field: the box must have hi > lo, finite");
    if (!(density_scale > 0.0f) || !(step_voxels > 0.0f) || !std::isfinite(density_scale) || !std::isfinite(step_voxels))
      throw std::invalid_argument("radiance field: density_scale and step_voxels must be positive");
    if (!values.empty() && values.size() != vertex_count() * 4)
      throw std::invalid_argument("radiance field: " + std::to_string(values.size()) + " values, expected " +
                                  std::to_string(vertex_count() * 4));
  }

  RadianceFieldView view() const {
    RadianceFieldView v;
    v.values = values.data();
    v.occupancy = occupancy.empty() ? nullptr : occupancy.data();
    v.res = res;
    v.lo = lo;
    v.hi = hi;
    v.step = step();
    v.density_scale = density_scale;
    v.min_transmittance = min_transmittance;
    v.background = background;
    return v;
  }

  // Marks as empty the cells whose 8 corners all have σ below sigma_threshold
  // (σ is monotone in the raw density, so the whole cell is below it).
  void update_occupancy(float sigma_threshold) {
    const float raw_threshold = sigma_threshold <= 0.0f ? -1e30f : raw_for_sigma(sigma_threshold);
    occupancy.assign(cell_count(), 0);
    const int cx = res.x - 1, cy = res.y - 1, cz = res.z - 1;
    parallel_for(cz, 1, [&](std::int64_t k0, std::int64_t k1, int) {
      for (std::int64_t k = k0; k < k1; ++k)
        for (int j = 0; j < cy; ++j)
          for (int i = 0; i < cx; ++i) {
            bool occ = false;
            for (int c = 0; c < 8 && !occ; ++c) {
              const std::size_t v = (std::size_t(k + ((c >> 2) & 1)) * res.y + std::size_t(j + ((c >> 1) & 1))) * res.x +
                                    std::size_t(i + (c & 1));
              occ = values[v * 4] >= raw_threshold;
            }
            occupancy[(std::size_t(k) * cy + j) * cx + i] = occ ? 1 : 0;
          }
    });
  }

  // The raw density whose σ is `sigma`.
  float raw_for_sigma(float sigma) const {
    const double s = double(sigma) / double(density_scale);
    return float(s > 30.0 ? s : std::log(std::expm1(std::max(s, 1e-30))));
  }

  // The same field on a grid of resolution r (raw values resampled
  // trilinearly; occupancy cleared).
  RadianceField resampled(const Vec3i& r) const {
    RadianceField out;
    out.res = r;
    out.lo = lo;
    out.hi = hi;
    out.density_scale = density_scale;
    out.step_voxels = step_voxels;
    out.min_transmittance = min_transmittance;
    out.background = background;
    out.check();
    out.values.assign(out.vertex_count() * 4, 0.0f);
    const RadianceFieldView src = view();
    parallel_for(r.z, 1, [&](std::int64_t k0, std::int64_t k1, int) {
      for (std::int64_t k = k0; k < k1; ++k)
        for (int j = 0; j < r.y; ++j)
          for (int i = 0; i < r.x; ++i) {
            // the same point in the old grid's coordinates, clamped inside it
            const Vec3d gn(double(i) / (r.x - 1), double(j) / (r.y - 1), double(k) / (r.z - 1));
            Vec3<double> p;
            for (int a = 0; a < 3; ++a)
              p[a] = double(lo[a]) + std::min(std::max(gn[a], 0.0), 1.0) * (double(hi[a]) - double(lo[a]));
            detail::FieldCell<double> q;
            if (!detail::field_cell(src, p, q)) continue;  // cannot happen: p lies in the box
            double raw[4];
            detail::interpolate_raw(src, values.data(), q, raw);
            float* dst = out.values.data() + ((std::size_t(k) * r.y + j) * r.x + i) * 4;
            for (int ch = 0; ch < 4; ++ch) dst[ch] = float(raw[ch]);
          }
    });
    return out;
  }
};

// Adds to grad the gradient of the smoothness prior
//   Σ over grid edges (a, b) of w_ch · (raw_a,ch − raw_b,ch)²
// (w_0 = density weight, w_1..3 = colour weight), gathered per vertex so
// the threads write disjoint entries. Returns the prior's value.
inline double add_smoothness_gradient(const RadianceField& f, float w_density, float w_colour, float* grad) {
  const int nx = f.res.x, ny = f.res.y, nz = f.res.z;
  const float w[4] = {w_density, w_colour, w_colour, w_colour};
  const std::int64_t sx = 4, sy = std::int64_t(nx) * 4, sz = std::int64_t(nx) * ny * 4;
  ThreadPool& pool = ThreadPool::global();
  std::vector<double> energy(std::size_t(pool.size()), 0.0);
  pool.parallel_for(nz, 1, [&](std::int64_t k0, std::int64_t k1, int worker) {
    double e = 0;
    for (std::int64_t k = k0; k < k1; ++k)
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const std::int64_t v = ((k * ny + j) * nx + i) * 4;
          const float* x = f.values.data() + v;
          float* g = grad + v;
          const auto edge = [&](bool exists, std::int64_t stride, bool count) {
            if (!exists) return;
            const float* y = x + stride;
            for (int ch = 0; ch < 4; ++ch) {
              const float diff = x[ch] - y[ch];
              g[ch] += 2.0f * w[ch] * diff;
              if (count) e += double(w[ch]) * double(diff) * double(diff);
            }
          };
          edge(i + 1 < nx, sx, true);
          edge(i > 0, -sx, false);
          edge(j + 1 < ny, sy, true);
          edge(j > 0, -sy, false);
          edge(k + 1 < nz, sz, true);
          edge(k > 0, -sz, false);
        }
    energy[std::size_t(worker)] += e;
  });
  double total = 0;
  for (double e : energy) total += e;
  return total;
}

}  // namespace difftrans::scene
