// How a refined mesh moved away from the mesh it was refined from, read
// against the true surface: did each part of the surface move to correct the
// reference's error there, move by an offset common to the whole object
// (an inflation or a shrinking, the trade a fit can make between thickness
// and absorption), or wander? For each vertex of the moved mesh:
//   before  the signed distance to the truth of the reference's nearest point
//           (positive outside the true object),
//   after   the vertex's own signed distance to the truth,
//   moved   its signed distance from the reference surface (positive along
//           the reference's outward normal),
// so that after ≈ before + moved. The fit of moved ≈ gain · (−before) +
// offset over the vertices says which: gain 1 is a full correction, 0 none;
// the offset is the common shift; what the line leaves (residual_rms) is
// the wandering. Signs come from the nearest triangle's normal (outward for
// a closed mesh wound counter-clockwise seen from outside), which is right
// wherever the distance is small against the surface's features. Lengths
// are in the truth's unit box, the frame of evaluate_geometry.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <vector>

#include "difftrans/core/vec.hpp"
#include "difftrans/geometry/remesh.hpp"
#include "difftrans/io/mesh.hpp"

namespace difftrans::metrics {

struct SurfaceMovement {
  // per vertex of the moved mesh (see above)
  std::vector<double> before, after, moved;
  double mean_before = 0.0, mean_after = 0.0, mean_moved = 0.0;
  double rms_before = 0.0, rms_after = 0.0, rms_moved = 0.0;
  // moved ≈ gain · (−before) + offset, least squares; residual_rms what it leaves
  double gain = 0.0, offset = 0.0, residual_rms = 0.0;
  double correlation = 0.0;          // of moved with −before
  double improved_fraction = 0.0;    // vertices with |after| < |before|
  // of the squared error added (Σ max(0, after² − before²)), the share in the
  // tenth of the vertices that added most: near 0.1 an even spread, near 1
  // a few regions
  double worst_tenth_share = 0.0;
};

namespace detail {

// Signed distance of p to the mesh of `tree` (positive on the side its
// triangles' normals face); `nearest`, when given, gets the nearest point.
inline double signed_distance(const geometry::ClosestPointTree& tree, const std::vector<float>& positions,
                              const glm::vec3& p, glm::vec3* nearest = nullptr) {
  const geometry::ClosestPointTree::Result r = tree.closest(p);
  if (nearest) *nearest = r.point;
  if (r.triangle < 0) throw std::invalid_argument("signed_distance: the mesh has no triangles");
  const auto corner = [&](int k) {
    const std::size_t v = 3 * std::size_t(tree.triangle_vertex(r.triangle, k));
    return glm::vec3(positions[v], positions[v + 1], positions[v + 2]);
  };
  const glm::vec3 a = corner(0), b = corner(1), c = corner(2);
  glm::vec3 n = glm::cross(b - a, c - a);
  const float len = glm::length(n);
  n = len > 0.0f ? n / len : glm::vec3(0.0f);
  const double d = std::sqrt(double(r.distance2));
  return glm::dot(p - r.point, n) < 0.0f ? -d : d;
}

}  // namespace detail

inline SurfaceMovement surface_movement(const io::Mesh& moved, const io::Mesh& reference, const io::Mesh& truth) {
  if (moved.positions.empty() || reference.triangles.empty() || truth.triangles.empty())
    throw std::invalid_argument("surface_movement: the moved mesh has no vertices or a surface has no triangles");
  const io::UnitBoxTransform frame = io::unit_box_transform(truth);
  io::Mesh m = moved, r = reference, t = truth;
  io::apply_transform(frame, m);
  io::apply_transform(frame, r);
  io::apply_transform(frame, t);
  const std::vector<float> rp = io::flat_positions(r), tp = io::flat_positions(t);
  const geometry::ClosestPointTree ref_tree(rp, io::flat_triangles(r)), truth_tree(tp, io::flat_triangles(t));

  SurfaceMovement s;
  const std::size_t n = m.positions.size();
  s.before.resize(n);
  s.after.resize(n);
  s.moved.resize(n);
  for (std::size_t v = 0; v < n; ++v) {
    const glm::vec3 p(m.positions[v]);
    s.after[v] = detail::signed_distance(truth_tree, tp, p);
    glm::vec3 on_reference;
    s.moved[v] = detail::signed_distance(ref_tree, rp, p, &on_reference);
    s.before[v] = detail::signed_distance(truth_tree, tp, on_reference);
  }
  const double inv = 1.0 / double(n);
  double sb = 0.0, sa = 0.0, sm = 0.0, sbb = 0.0, saa = 0.0, smm = 0.0, sbm = 0.0;
  std::size_t improved = 0;
  std::vector<double> added(n);
  for (std::size_t v = 0; v < n; ++v) {
    const double b = s.before[v], a = s.after[v], d = s.moved[v];
    sb += b, sa += a, sm += d, sbb += b * b, saa += a * a, smm += d * d, sbm += b * d;
    improved += std::abs(a) < std::abs(b);
    added[v] = std::max(0.0, a * a - b * b);
  }
  s.mean_before = sb * inv, s.mean_after = sa * inv, s.mean_moved = sm * inv;
  s.rms_before = std::sqrt(sbb * inv), s.rms_after = std::sqrt(saa * inv), s.rms_moved = std::sqrt(smm * inv);
  const double var_b = sbb * inv - s.mean_before * s.mean_before;
  const double var_m = smm * inv - s.mean_moved * s.mean_moved;
  const double cov = sbm * inv - s.mean_before * s.mean_moved;  // of before and moved
  if (var_b > 0.0) {
    s.gain = -cov / var_b;
    s.offset = s.mean_moved + s.gain * s.mean_before;  // moved = gain·(−before) + offset at the means
    s.residual_rms = std::sqrt(std::max(0.0, var_m - cov * cov / var_b));
  } else {
    s.offset = s.mean_moved;
    s.residual_rms = std::sqrt(std::max(0.0, var_m));
  }
  if (var_b > 0.0 && var_m > 0.0) s.correlation = -cov / std::sqrt(var_b * var_m);
  s.improved_fraction = double(improved) * inv;
  double total = 0.0;
  for (double x : added) total += x;
  if (total > 0.0) {
    const std::size_t tenth = std::max<std::size_t>(1, n / 10);
    std::nth_element(added.begin(), added.begin() + std::ptrdiff_t(tenth - 1), added.end(), std::greater<double>());
    double top = 0.0;
    for (std::size_t k = 0; k < tenth; ++k) top += added[k];
    s.worst_tenth_share = top / total;
  }
  return s;
}

}  // namespace difftrans::metrics
