// The FlexiCubes grid terms of stage 1, generic over the scalar S: SDF
// dilation, BCE on sign-changing grid edges, FlexiCubes' L_dev and the L1 on
// the raw weights, each read through a parameter reader like the extraction
// (see the note on readers in mesh_terms.hpp), with tape-free backward
// versions where the term is linear in its unknowns.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/core/constants.hpp"
#include "difftrans/ad/param_source.hpp"
#include "difftrans/geometry/flexicubes.hpp"
#include "difftrans/losses/mesh_terms.hpp"

namespace difftrans::losses {

// Binary cross-entropy with logits, BCE(x, t) = −t log σ(x) − (1 − t) log(1 − σ(x)),
// evaluated as softplus(x) − x t = max(x, 0) − x t + log1p(e^−|x|) (stable for
// any x); d/dx = σ(x) − t, exact also at x = 0 (softplus' rule).
template <class S>
DT_HOST_DEVICE S bce_with_logits(const S& x, double target) {
  using T = ad::scalar_t<S>;
  return S(softplus(x) - x * T(target));
}

// ------------------------------------------------------------- FlexiCubes grid terms

// SDF dilation: the mean raw SDF value over all grid vertices (pushes the
// surface outward when minimized). One read per grid vertex.
template <class S, class Reader>
S sdf_dilation_loss(const geometry::FlexiCubesGrid& grid, const ad::ParamSource& sdf, Reader& reader) {
  using T = ad::scalar_t<S>;
  const std::int32_t n = grid.num_vertices();
  S sum(0);
  for (std::int32_t v = 0; v < n; ++v) sum += geometry::detail::fc_read<S>(reader, sdf, v);
  return S(sum / T(double(n)));
}

// BCE-with-logits on the sign-changing grid edges (the SDF regularizer of
// FlexiCubes / nvdiffrec): for every grid edge (a, b) whose ends lie on
// different sides, (s_a < 0) != (s_b < 0) as in the extraction's case ids,
//   BCE(s_a, [s_b > 0]) + BCE(s_b, [s_a > 0]),
// averaged over those edges (0 when there are none). Removes floaters and
// sharpens the zero crossing. One read per grid vertex on a changing edge.
template <class S, class Reader>
S sdf_sign_change_bce_loss(const geometry::FlexiCubesGrid& grid, const ad::ParamSource& sdf, Reader& reader) {
  using T = ad::scalar_t<S>;
  const float* s = sdf.values;
  const int R = grid.res, V = R + 1;
  const std::int32_t step[3] = {1, V, V * V};
  std::vector<S> cache(std::size_t(grid.num_vertices()));
  std::vector<std::uint8_t> loaded(cache.size(), 0);
  auto get = [&](std::int32_t v) -> const S& {
    if (!loaded[std::size_t(v)]) {
      cache[std::size_t(v)] = geometry::detail::fc_read<S>(reader, sdf, v);
      loaded[std::size_t(v)] = 1;
    }
    return cache[std::size_t(v)];
  };
  S sum(0);
  std::int64_t count = 0;
  for (int k = 0; k < V; ++k)
    for (int j = 0; j < V; ++j)
      for (int i = 0; i < V; ++i) {
        const int x[3] = {i, j, k};
        const std::int32_t a = grid.vertex_index(i, j, k);
        for (int axis = 0; axis < 3; ++axis) {
          if (x[axis] >= R) continue;
          const std::int32_t b = a + step[axis];
          if ((s[a] < 0.0f) == (s[b] < 0.0f)) continue;
          const S sa = get(a), sb = get(b);
          sum += bce_with_logits(sa, s[b] > 0.0f ? 1.0 : 0.0) + bce_with_logits(sb, s[a] > 0.0f ? 1.0 : 0.0);
          ++count;
        }
      }
  return count > 0 ? S(sum / T(double(count))) : S(0);
}

// L1 on the FlexiCubes weights: the mean of |raw| over every α, β and γ entry
// of the sources that have values or a buffer (raw, not squashed: raw 0 is the
// neutral weight α = β = 1, γ = 0.505, so this pulls every weight towards its
// neutral value; d|x| = sign(x) dx with sign(0) = 0). One read per entry.
template <class S, class Reader>
S flexicubes_weight_l1(const geometry::FlexiCubesInputs& in, Reader& reader) {
  using T = ad::scalar_t<S>;
  S sum(0);
  std::int64_t count = 0;
  for (const ad::ParamSource* src : {&in.alpha, &in.beta, &in.gamma}) {
    if (!src->values && src->buffer < 0) continue;
    for (std::int32_t i = 0; i < src->size; ++i) sum += abs(geometry::detail::fc_read<S>(reader, *src, i));
    count += src->size;
  }
  return count > 0 ? S(sum / T(double(count))) : S(0);
}

// The two elementwise terms without a tape: their value (in double) and their
// gradient, times `weight`, added straight into the gradient arrays of `set`
// for the sources that are differentiable (buffer >= 0). Same values and
// gradients as the reader versions with Var, at no tape or log cost (the L1
// over all weights of a 64³ grid is 5.5 M reads: 530 MB of tape in double).
inline double sdf_dilation_backward(const geometry::FlexiCubesGrid& grid, const ad::ParamSource& sdf, const ad::ParamSet& set,
                                    double weight = 1.0) {
  const std::int32_t n = grid.num_vertices();
  double sum = 0.0;
  for (std::int32_t v = 0; v < n; ++v) sum += double(sdf.values[v]);
  float* g = sdf.buffer >= 0 ? set.buffers[sdf.buffer].gradient : nullptr;
  const float dv = float(weight / double(n));  // d mean / d s_v = 1 / n
  if (g)
    for (std::int32_t v = 0; v < n; ++v) g[v] += dv;
  return sum / double(n);
}

inline double flexicubes_weight_l1_backward(const geometry::FlexiCubesInputs& in, const ad::ParamSet& set, double weight = 1.0) {
  std::int64_t count = 0;
  for (const ad::ParamSource* src : {&in.alpha, &in.beta, &in.gamma})
    if (src->values || src->buffer >= 0) count += src->size;
  if (count == 0) return 0.0;
  double sum = 0.0;
  const double scale = weight / double(count);
  for (const ad::ParamSource* src : {&in.alpha, &in.beta, &in.gamma}) {
    if (!src->values && src->buffer < 0) continue;
    float* g = src->buffer >= 0 ? set.buffers[src->buffer].gradient : nullptr;
    for (std::int32_t i = 0; i < src->size; ++i) {
      const float x = src->values ? src->values[i] : 0.0f;
      sum += std::fabs(double(x));
      if (g) g[i] += float(x > 0.0f ? scale : (x < 0.0f ? -scale : 0.0));  // d|x| = sign(x), sign(0) = 0
    }
  }
  return sum / double(count);
}

// FlexiCubes' L_dev: for each dual vertex v of `mesh` (extracted from the same
// grid, inputs and options), the distances d_e = |u_e − v| to the crossing
// points u_e of the sign-changing edges of its group; the term is the mean
// over dual vertices of the mean absolute deviation (1/n) Σ_e |d_e − mean d|.
// (The reference implementation averages |d_e − mean d| over all (vertex, edge)
// pairs instead, which weights vertices by their edge count.) The crossings
// are recomputed from the unknowns exactly as the extraction does: the sdf,
// deformation and α of each used grid vertex / corner are read again through
// `reader` (new leaves for Var, whose adjoints scatter like the others).
template <class S, class Reader>
S flexicubes_dev_loss(const geometry::FlexiCubesGrid& grid, const geometry::FlexiCubesInputs& in, Reader& reader,
                      const geometry::FlexiCubesMesh<S>& mesh, const geometry::FlexiCubesOptions& options = {}) {
  using T = ad::scalar_t<S>;
  const geometry::FlexiCubesTables& tab = geometry::flexicubes_tables;
  const geometry::FlexiCubesTopology top = geometry::flexicubes_topology(grid, in.sdf.values, options);
  const std::int32_t nd = mesh.num_dual_vertices;
  if (nd == 0 || std::int32_t(top.vertex_cube.size()) != nd) return S(0);
  const int R = grid.res, V = R + 1;
  const std::int32_t corner_step[8] = {0, 1, V, V + 1, V * V, V * V + 1, V * V + V, V * V + V + 1};
  const Vec3<T> reach = Vec3<T>(grid.cell()) * geometry::flexicubes_deform_bound<T>;
  const bool has_deform = in.deform.values || in.deform.buffer >= 0;
  const bool has_alpha = in.alpha.values || in.alpha.buffer >= 0;

  // sdf value and deformed position of each used grid vertex, read once
  std::vector<std::int32_t> slot(std::size_t(grid.num_vertices()), -1);
  std::vector<S> s_slot;
  std::vector<Vec3<S>> x_slot;
  auto vertex_slot = [&](std::int32_t v) {
    std::int32_t& sl = slot[std::size_t(v)];
    if (sl >= 0) return sl;
    sl = std::int32_t(s_slot.size());
    s_slot.push_back(geometry::detail::fc_read<S>(reader, in.sdf, v));
    const Vec3f g = grid.vertex_position(v % V, (v / V) % V, v / (V * V));
    Vec3<S> x;
    for (int a = 0; a < 3; ++a)  // x = grid + reach ⊙ tanh(δ), as in the extraction
      x[a] = has_deform ? S(T(g[a]) + reach[a] * tanh(geometry::detail::fc_read<S>(reader, in.deform, 3 * v + a))) : S(g[a]);
    x_slot.push_back(x);
    return sl;
  };

  S sum(0);
  std::int32_t cube = -1;
  S alpha[8];
  bool alpha_read[8] = {};
  for (std::int32_t d = 0; d < nd; ++d) {
    const std::int32_t c = mesh.dual_vertex_cube[std::size_t(d)];
    if (c != cube) {  // dual vertices of one cube are consecutive: α read once per cube corner
      cube = c;
      for (bool& r : alpha_read) r = false;
    }
    const geometry::FlexiCubesCase& cs = tab.configs[top.config[std::size_t(c)]];
    const std::uint16_t edges = cs.group_edges[d - top.first_vertex[std::size_t(c)]];
    const std::int32_t base = grid.vertex_index(c % R, (c / R) % R, c / (R * R));
    S dist[12];
    int n = 0;
    S mean(0);
    for (int e = 0; e < 12; ++e) {
      if (!(edges >> e & 1)) continue;
      const int ca = geometry::flexicubes_edge_corners[e][0], cb = geometry::flexicubes_edge_corners[e][1];
      for (int corner : {ca, cb})
        if (!alpha_read[corner]) {
          alpha[corner] = has_alpha ? geometry::flexicubes_squash_weight(geometry::detail::fc_read<S>(reader, in.alpha, 8 * c + corner)) : S(1);
          alpha_read[corner] = true;
        }
      const std::int32_t ia = vertex_slot(base + corner_step[ca]), ib = vertex_slot(base + corner_step[cb]);
      const Vec3<S> u = geometry::flexicubes_crossing(x_slot[std::size_t(ia)], s_slot[std::size_t(ia)], alpha[ca],
                                            x_slot[std::size_t(ib)], s_slot[std::size_t(ib)], alpha[cb]);
      dist[n] = detail::reg_norm(Vec3<S>(u - mesh.vertices[std::size_t(d)]));
      mean += dist[n];
      ++n;
    }
    if (n == 0) continue;
    mean = S(mean / T(n));
    S mad(0);
    for (int m = 0; m < n; ++m) mad += abs(S(dist[m] - mean));
    sum += mad / T(n);
  }
  return S(sum / T(double(nd)));
}

}  // namespace difftrans::losses
