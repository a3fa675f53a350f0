// Mesh regularizers, generic over the scalar S (float, double, Dual, Var):
// mean face area, developability (Stein et al. 2018), edge-normal consistency
// and the uniform Laplacian, with the vector helpers and reductions the grid
// terms (flexicubes_terms.hpp) share. Each term's formula and source is in the
// comment above it; gradients come from evaluating the term in Var or Dual.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/core/constants.hpp"
#include "difftrans/geometry/topology.hpp"

namespace difftrans::losses {

// How the terms evaluated here are used.
//
// Every term returns one scalar S. With S = Var<T> every operation is
// recorded on one tape: the tape of the reader (grid terms) or the tape the
// mesh vertices already live on (e.g. a FlexiCubesMesh<Var<T>> extracted with
// the same reader), so a weighted sum of terms needs one backward pass. With
// S = Dual<T, N> the tangents come from the reader / the vertices. Discrete
// decisions (signs, adjacency, degeneracy guards) are taken on values only.
//
// Terms that read FlexiCubes unknowns (dilation, BCE, L_dev, weight L1) read
// them through `reader.read(buffer, index)` like flexicubes_extract: a
// ad::ParamSource with buffer >= 0 is differentiable, otherwise constant;
// a source without values reads raw 0. With ad::ParamReader<Var<T>> every read
// is a new leaf with a log entry: size the log for the reads stated per term.

enum class Reduction : int { sum, mean };

namespace detail {

template <class S>
DT_HOST_DEVICE S reg_dot(const Vec3<S>& a, const Vec3<S>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

template <class S>
DT_HOST_DEVICE Vec3<S> reg_cross(const Vec3<S>& a, const Vec3<S>& b) {
  return Vec3<S>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

// |v| with a finite derivative at v = 0: d|v| = v·dv / |v| there evaluated with
// |v|² clamped at safe_sqrt_eps, times v = 0, i.e. 0.
template <class S>
DT_HOST_DEVICE S reg_norm(const Vec3<S>& v) {
  return safe_sqrt(reg_dot(v, v));
}

// Unit normal of a triangle and its |cross| (twice the area). A zero-area
// face has no normal: n = 0 with zero derivative (decided on the value).
template <class S>
DT_HOST_DEVICE Vec3<S> reg_unit_normal(const Vec3<S>& a, const Vec3<S>& b, const Vec3<S>& c, S* twice_area = nullptr) {
  const Vec3<S> n = reg_cross(b - a, c - a);
  const S len = reg_norm(n);
  if (twice_area) *twice_area = len;
  if (!(value_of(len) > 0)) return Vec3<S>(S(0));
  return n / len;  // d(n/|n|) = (I − n̂ n̂ᵀ) dn / |n|
}

template <class S>
S reg_reduce(const S& sum, std::int64_t count, Reduction reduction) {
  using T = ad::scalar_t<S>;
  if (reduction == Reduction::sum) return sum;
  return count > 0 ? S(sum / T(double(count))) : S(0);
}

}  // namespace detail

// ------------------------------------------------------------- small pieces

// Area of the triangle (a, b, c): |(b − a) × (c − a)| / 2. The derivative is
// finite (zero) at a zero-area triangle (reg_norm).
template <class S>
DT_HOST_DEVICE S triangle_area(const Vec3<S>& a, const Vec3<S>& b, const Vec3<S>& c) {
  using T = ad::scalar_t<S>;
  return S(T(0.5) * detail::reg_norm(detail::reg_cross(b - a, c - a)));
}

// Smallest eigenvalue of the symmetric matrix [[a00 a01 a02] [a01 a11 a12] [a02 a12 a22]]
// in closed form (trigonometric solution of the characteristic polynomial):
//   q = tr A / 3, B = A − q I, p = sqrt(tr(B²) / 6), r = det(B) / (2 p³) ∈ [−1, 1],
//   λ_min = q + 2 p cos(acos(r) / 3 + 2π / 3).
// Guards, all decided on values, so that the derivative stays finite:
//   - triple eigenvalue (p² ≤ (ε_T q)², rounding noise, or p² below the
//     smallest normal): λ = q, derivative dλ = tr(dA) / 3 (one subgradient);
//   - |r| ≥ 1 by rounding: r is clamped (no derivative through r);
//   - a double eigenvalue (r = ±1): acos' derivative is evaluated with 1 − r²
//     clamped at safe_sqrt_eps (ad/math.hpp), finite; there dr = 0 to first
//     order (r is at its extreme) or sin(acos(r)/3 + 2π/3) = 0 (r = −1), so
//     the clamp changes nothing but the 0 · ∞ that would otherwise be NaN.
// Accuracy: near a double smallest eigenvalue (r → 1) acos amplifies the
// rounding of r, so λ_min carries an absolute error ~ sqrt(ε_T) ‖A‖ (measured
// 5e-9 in double, 2e-4 in float on a flat patch). smallest_eigenvalue_sym3
// below does not have this problem and is the one developability uses.
template <class S>
DT_HOST_DEVICE S smallest_eigenvalue_sym3_closed_form(const S& a00, const S& a11, const S& a22, const S& a01,
                                                      const S& a02, const S& a12) {
  using T = ad::scalar_t<S>;
  const S q = (a00 + a11 + a22) / T(3);
  const S b00 = a00 - q, b11 = a11 - q, b22 = a22 - q;
  const S p2 = (b00 * b00 + b11 * b11 + b22 * b22 + T(2) * (a01 * a01 + a02 * a02 + a12 * a12)) / T(6);
  const T qv = value_of(q), p2v = value_of(p2), eps = std::numeric_limits<T>::epsilon();
  if (!(p2v > eps * eps * qv * qv) || !(p2v > std::numeric_limits<T>::min())) return q;
  const S p = sqrt(p2);
  // det B by cofactors along the first row
  const S det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02);
  const S r = clamp(S(det / (T(2) * p2 * p)), S(T(-1)), S(T(1)));
  const S phi = acos(r) / T(3);
  return S(q + T(2) * p * cos(S(phi + T(2) * pi_v<T> / T(3))));
}

// Unit eigenvector of the smallest eigenvalue of a symmetric 3×3 matrix of
// plain values (m[0..5] = a00 a11 a22 a01 a02 a12), by cyclic Jacobi rotations
// in double: accurate to rounding also at repeated eigenvalues (then some unit
// vector of the eigenspace). Returns the eigenvalue; the vector goes to v.
DT_HOST_DEVICE inline double smallest_eigenvector_sym3(const double m[6], double v[3]) {
  double a[3][3] = {{m[0], m[3], m[4]}, {m[3], m[1], m[5]}, {m[4], m[5], m[2]}};
  double w[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};  // columns: eigenvectors
  static constexpr int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (int sweep = 0; sweep < 16; ++sweep) {
    bool rotated = false;
    for (const auto& pq : pairs) {
      const int p = pq[0], q = pq[1];
      const double apq = a[p][q];
      // negligible against the diagonal: already zero to rounding
      if (!(std::fabs(apq) > 1e-18 * (std::fabs(a[p][p]) + std::fabs(a[q][q]))) || apq == 0.0) continue;
      rotated = true;
      // rotation J (J_pp = J_qq = c, J_pq = s, J_qp = −s) with (JᵀAJ)_pq = 0:
      // t = tan of the angle, the smaller root of t² + 2θt − 1 = 0, θ = (a_qq − a_pp) / (2 a_pq)
      const double theta = (a[q][q] - a[p][p]) / (2.0 * apq);
      const double t = theta >= 0.0 ? 1.0 / (theta + std::sqrt(theta * theta + 1.0))
                                     : -1.0 / (-theta + std::sqrt(theta * theta + 1.0));
      const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
      for (int k = 0; k < 3; ++k) {  // A ← A J (columns p, q), W ← W J
        const double akp = a[k][p], akq = a[k][q];
        a[k][p] = c * akp - s * akq;
        a[k][q] = s * akp + c * akq;
        const double wkp = w[k][p], wkq = w[k][q];
        w[k][p] = c * wkp - s * wkq;
        w[k][q] = s * wkp + c * wkq;
      }
      for (int k = 0; k < 3; ++k) {  // A ← Jᵀ A (rows p, q)
        const double apk = a[p][k], aqk = a[q][k];
        a[p][k] = c * apk - s * aqk;
        a[q][k] = s * apk + c * aqk;
      }
      a[p][q] = a[q][p] = 0.0;
    }
    if (!rotated) break;
  }
  int best = 0;
  for (int k = 1; k < 3; ++k)
    if (a[k][k] < a[best][best]) best = k;
  for (int k = 0; k < 3; ++k) v[k] = w[k][best];
  return a[best][best];
}

// Smallest eigenvalue of the symmetric matrix [[a00 a01 a02] [a01 a11 a12] [a02 a12 a22]],
// as the Rayleigh quotient λ = vᵀ A v at the unit eigenvector v of the
// smallest eigenvalue, found on values (smallest_eigenvector_sym3) and held
// constant: dλ = vᵀ dA v, which is the eigenvalue's derivative where it is
// simple (Hellmann–Feynman) and, at a repeated smallest eigenvalue, the
// directional derivative of λ_min along the chosen v: always finite, between
// the one-sided derivatives. Value accurate to O(ε ‖A‖) also at repeated
// eigenvalues (a flat vertex has a double eigenvalue 0).
template <class S>
DT_HOST_DEVICE S smallest_eigenvalue_sym3(const S& a00, const S& a11, const S& a22, const S& a01, const S& a02,
                                          const S& a12) {
  using T = ad::scalar_t<S>;
  const double m[6] = {double(value_of(a00)), double(value_of(a11)), double(value_of(a22)),
                       double(value_of(a01)), double(value_of(a02)), double(value_of(a12))};
  double v[3];
  smallest_eigenvector_sym3(m, v);
  const T v0 = T(v[0]), v1 = T(v[1]), v2 = T(v[2]);
  // vᵀ A v = Σ_i v_i² a_ii + 2 Σ_{i<j} v_i v_j a_ij
  return S(v0 * v0 * a00 + v1 * v1 * a11 + v2 * v2 * a22 + T(2) * (v0 * v1 * a01 + v0 * v2 * a02 + v1 * v2 * a12));
}

// ------------------------------------------------------------- mesh terms

// Mean face area over the triangles (3 indices each). 0 for no triangles.
template <class S>
S mean_face_area(const std::vector<Vec3<S>>& vertices, const std::vector<std::int32_t>& triangles) {
  S sum(0);
  const std::size_t nt = triangles.size() / 3;
  for (std::size_t f = 0; f < nt; ++f)
    sum += triangle_area(vertices[std::size_t(triangles[3 * f])], vertices[std::size_t(triangles[3 * f + 1])],
                         vertices[std::size_t(triangles[3 * f + 2])]);
  return detail::reg_reduce(sum, std::int64_t(nt), Reduction::mean);
}

// Developability (Stein, Grinspun, Crane 2018), the covariance energy: at each
// vertex i, λ_min(A_i) with A_i = Σ_f θ_f n_f n_fᵀ over the faces f around i,
// θ_f the face's interior angle at i and n_f its unit normal. λ_min is 0
// exactly when the normals around i lie on a great circle (the surface is
// developable there, e.g. flat or cylindrical) and grows with the spread of
// the normals (e.g. on a sphere). Summed or averaged over the vertices; by
// default boundary vertices are skipped (the energy is defined at interior
// vertices). Angles are atan2(|e1 × e2|, e1 · e2): finite derivatives, also at
// zero-area faces (their n = 0, see detail::reg_unit_normal).
template <class S>
S developability_loss(const std::vector<Vec3<S>>& vertices, const std::vector<std::int32_t>& triangles,
                      const geometry::MeshAdjacency& adj, Reduction reduction = Reduction::mean, bool skip_boundary = true) {
  const std::size_t nt = triangles.size() / 3;
  std::vector<Vec3<S>> normal(nt);
  std::vector<S> angle(3 * nt);
  for (std::size_t f = 0; f < nt; ++f) {
    const Vec3<S> p[3] = {vertices[std::size_t(triangles[3 * f])], vertices[std::size_t(triangles[3 * f + 1])],
                          vertices[std::size_t(triangles[3 * f + 2])]};
    S twice_area;
    normal[f] = detail::reg_unit_normal(p[0], p[1], p[2], &twice_area);
    for (int k = 0; k < 3; ++k)  // θ_k = atan2(|e1 × e2|, e1 · e2), |e1 × e2| = twice the area at every corner
      angle[3 * f + std::size_t(k)] = atan2(twice_area, detail::reg_dot(Vec3<S>(p[(k + 1) % 3] - p[k]), Vec3<S>(p[(k + 2) % 3] - p[k])));
  }
  S sum(0);
  std::int64_t count = 0;
  for (std::int32_t v = 0; v < adj.num_vertices; ++v) {
    const std::int32_t b = adj.vf_offsets[std::size_t(v)], e = adj.vf_offsets[std::size_t(v) + 1];
    if (b == e || (skip_boundary && adj.boundary[std::size_t(v)])) continue;
    S a00(0), a11(0), a22(0), a01(0), a02(0), a12(0);
    for (std::int32_t k = b; k < e; ++k) {
      const std::size_t f = std::size_t(adj.vf_faces[std::size_t(k)]);
      const Vec3<S>& n = normal[f];
      const S& th = angle[3 * f + std::size_t(adj.vf_corner[std::size_t(k)])];
      const Vec3<S> tn = th * n;  // A += θ n nᵀ
      a00 += tn.x * n.x;
      a11 += tn.y * n.y;
      a22 += tn.z * n.z;
      a01 += tn.x * n.y;
      a02 += tn.x * n.z;
      a12 += tn.y * n.z;
    }
    sum += smallest_eigenvalue_sym3(a00, a11, a22, a01, a02, a12);
    ++count;
  }
  return detail::reg_reduce(sum, count, reduction);
}

// The per-edge penalty of edge_normal_loss, with c = n_i · n_j = cos θ:
// squared (1 − c)², about θ⁴/4, or linear 1 − c, about θ²/2. The squared form
// hardly pulls at small angles (a 5° crease: 1.4e-5 against 3.8e-3, and a
// gradient cubic in θ), so it leaves a surface that is rough at a few
// degrees as it is; the linear one pulls in proportion to the angle.
enum class EdgeNormalForm : int { squared, linear };

// Edge-normal smoothness: Σ over interior edges of (1 − n_i · n_j)² (or of
// 1 − n_i · n_j, `form` linear), n_i, n_j the unit normals of the edge's two
// faces (consistently oriented meshes). 0 on a plane; a zero-area face has
// n = 0 and gives its edges 1 each, with zero derivative. Sum (default) or
// mean over interior edges.
template <class S>
S edge_normal_loss(const std::vector<Vec3<S>>& vertices, const std::vector<std::int32_t>& triangles,
                   const geometry::MeshAdjacency& adj, Reduction reduction = Reduction::sum,
                   EdgeNormalForm form = EdgeNormalForm::squared) {
  const std::size_t nt = triangles.size() / 3;
  std::vector<Vec3<S>> normal(nt);
  for (std::size_t f = 0; f < nt; ++f)
    normal[f] = detail::reg_unit_normal(vertices[std::size_t(triangles[3 * f])], vertices[std::size_t(triangles[3 * f + 1])],
                                        vertices[std::size_t(triangles[3 * f + 2])]);
  S sum(0);
  std::int64_t count = 0;
  for (std::int32_t e = 0; e < adj.num_edges(); ++e) {
    const std::int32_t f0 = adj.edge_faces[std::size_t(2 * e)], f1 = adj.edge_faces[std::size_t(2 * e + 1)];
    if (f1 < 0) continue;
    const S gap = S(1 - detail::reg_dot(normal[std::size_t(f0)], normal[std::size_t(f1)]));
    sum += form == EdgeNormalForm::squared ? square(gap) : gap;
    ++count;
  }
  return detail::reg_reduce(sum, count, reduction);
}

// Uniform Laplacian smoothness: the mean over vertices of ‖v − mean of its
// neighbours‖² (the rows of the combinatorial Laplacian, divided by degree).
// 0 wherever a vertex is the centroid of its neighbours (a regular flat grid's
// interior). Boundary vertices skipped by default; isolated vertices always.
template <class S>
S laplacian_loss(const std::vector<Vec3<S>>& vertices, const geometry::MeshAdjacency& adj, Reduction reduction = Reduction::mean,
                 bool skip_boundary = true) {
  using T = ad::scalar_t<S>;
  S sum(0);
  std::int64_t count = 0;
  for (std::int32_t v = 0; v < adj.num_vertices; ++v) {
    const std::int32_t b = adj.vv_offsets[std::size_t(v)], e = adj.vv_offsets[std::size_t(v) + 1];
    if (b == e || (skip_boundary && adj.boundary[std::size_t(v)])) continue;
    Vec3<S> m(S(0));
    for (std::int32_t k = b; k < e; ++k) m += vertices[std::size_t(adj.vv_neighbors[std::size_t(k)])];
    const Vec3<S> d = vertices[std::size_t(v)] - m / S(T(e - b));
    sum += detail::reg_dot(d, d);  // d‖d‖² = 2 d · dd
    ++count;
  }
  return detail::reg_reduce(sum, count, reduction);
}

}  // namespace difftrans::losses
