// Surface quality of a triangle mesh, beside Chamfer / F1 (docs/metrics.md,
// "Mesh quality"): the mean dihedral angle between the normals of the two
// faces at each interior edge (a speckled or noisy surface raises it), the
// genus and components, and the number of self-intersecting triangle pairs
// (an edge of one triangle crossing another triangle that shares no vertex
// with it; found by sweeping the triangles' bounding boxes along x).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include "difftrans/core/constants.hpp"
#include "difftrans/core/vec.hpp"
#include "difftrans/geometry/topology.hpp"

namespace difftrans::metrics {

struct MeshQuality {
  double mean_dihedral_degrees = 0.0;  // over the edges shared by exactly two faces
  double max_dihedral_degrees = 0.0;
  std::int64_t interior_edges = 0;
  std::int64_t self_intersections = 0;  // triangle pairs (sharing no vertex) that cross
  int genus = 0, components = 0;
  bool closed = false;
};

namespace detail {

inline Vec3d mesh_vertex(const std::vector<float>& p, std::int32_t v) {
  return Vec3d(p[3 * std::size_t(v)], p[3 * std::size_t(v) + 1], p[3 * std::size_t(v) + 2]);
}

// Whether the segment [a, b] crosses the triangle (p0, p1, p2): Möller–Trumbore
// with the parameter inside (0, 1) and the barycentrics inside the triangle;
// a segment in the triangle's plane does not count.
inline bool segment_crosses_triangle(const Vec3d& a, const Vec3d& b, const Vec3d& p0, const Vec3d& p1, const Vec3d& p2) {
  const Vec3d d = b - a, e1 = p1 - p0, e2 = p2 - p0;
  const Vec3d q = glm::cross(d, e2);
  const double det = glm::dot(e1, q);
  const double scale = glm::length(d) * glm::length(e1) * glm::length(e2);
  if (!(std::abs(det) > 1e-12 * scale)) return false;
  const double inv = 1.0 / det;
  const Vec3d s = a - p0;
  const double u = glm::dot(s, q) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const Vec3d r = glm::cross(s, e1);
  const double v = glm::dot(d, r) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  const double t = glm::dot(e2, r) * inv;
  return t > 0.0 && t < 1.0;
}

}  // namespace detail

// Triangle pairs that share no vertex and of which one has an edge crossing
// the other.
inline std::int64_t self_intersections(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles) {
  using detail::mesh_vertex;
  const std::size_t nt = triangles.size() / 3;
  std::vector<std::array<Vec3d, 3>> tri(nt);
  std::vector<Vec3d> lo(nt), hi(nt);
  for (std::size_t f = 0; f < nt; ++f) {
    for (int k = 0; k < 3; ++k) tri[f][std::size_t(k)] = mesh_vertex(positions, triangles[3 * f + std::size_t(k)]);
    lo[f] = glm::min(glm::min(tri[f][0], tri[f][1]), tri[f][2]);
    hi[f] = glm::max(glm::max(tri[f][0], tri[f][1]), tri[f][2]);
  }
  std::vector<std::size_t> order(nt);
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return lo[a].x < lo[b].x; });
  const auto crosses = [&](std::size_t f, std::size_t g) {
    for (int k = 0; k < 3; ++k)
      if (detail::segment_crosses_triangle(tri[f][std::size_t(k)], tri[f][std::size_t((k + 1) % 3)], tri[g][0],
                                           tri[g][1], tri[g][2]))
        return true;
    return false;
  };
  std::int64_t count = 0;
  for (std::size_t i = 0; i < nt; ++i) {
    const std::size_t f = order[i];
    for (std::size_t j = i + 1; j < nt && lo[order[j]].x <= hi[f].x; ++j) {
      const std::size_t g = order[j];
      if (lo[g].y > hi[f].y || hi[g].y < lo[f].y || lo[g].z > hi[f].z || hi[g].z < lo[f].z) continue;
      bool shared = false;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) shared = shared || triangles[3 * f + std::size_t(a)] == triangles[3 * g + std::size_t(b)];
      if (shared) continue;
      if (crosses(f, g) || crosses(g, f)) ++count;
    }
  }
  return count;
}

inline MeshQuality mesh_quality(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles) {
  using detail::mesh_vertex;
  MeshQuality q;
  const std::int32_t nv = std::int32_t(positions.size() / 3);
  const std::size_t nt = triangles.size() / 3;
  std::vector<Vec3d> normal(nt);
  for (std::size_t f = 0; f < nt; ++f) {
    const Vec3d a = mesh_vertex(positions, triangles[3 * f]), b = mesh_vertex(positions, triangles[3 * f + 1]),
                c = mesh_vertex(positions, triangles[3 * f + 2]);
    const Vec3d n = glm::cross(b - a, c - a);
    const double l = glm::length(n);
    normal[f] = l > 0.0 ? n / l : Vec3d(0.0);
  }
  // the edges with exactly two faces (topology.hpp's edge walk)
  double sum = 0.0;
  geometry::for_each_edge(triangles.data(), std::int32_t(nt),
                          [&](std::int32_t, std::int32_t, const std::int32_t* corners, int count) {
                            if (count != 2) return;
                            const double c = std::clamp(
                                glm::dot(normal[std::size_t(corners[0] / 3)], normal[std::size_t(corners[1] / 3)]), -1.0, 1.0);
                            const double angle = std::acos(c) * 180.0 / pi_v<double>;
                            sum += angle;
                            q.max_dihedral_degrees = std::max(q.max_dihedral_degrees, angle);
                            ++q.interior_edges;
                          });
  q.mean_dihedral_degrees = q.interior_edges > 0 ? sum / double(q.interior_edges) : 0.0;
  const geometry::MeshGenus g = geometry::mesh_genus(triangles, nv);
  q.genus = int(g.genus);
  q.components = g.components;
  q.closed = g.closed && !triangles.empty();
  q.self_intersections = self_intersections(positions, triangles);
  return q;
}

}  // namespace difftrans::metrics
