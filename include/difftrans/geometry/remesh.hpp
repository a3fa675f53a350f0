// Isotropic remeshing (Botsch & Kobbelt 2004) to a target edge length on the
// half-edge mesh, and exact closest points on a triangle mesh (a small BVH).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "difftrans/core/parallel.hpp"
#include "difftrans/geometry/halfedge.hpp"

namespace difftrans::geometry {

// ------------------------------------------------------------ closest points

// The point of triangle (a, b, c) closest to p, by the Voronoi region of p:
// a vertex, an edge, or the interior (barycentric projection).
inline glm::vec3 closest_point_on_triangle(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b,
                                           const glm::vec3& c) {
  const glm::vec3 ab = b - a, ac = c - a, ap = p - a;
  const float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0.0f && d2 <= 0.0f) return a;
  const glm::vec3 bp = p - b;
  const float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0.0f && d4 <= d3) return b;
  const glm::vec3 cp = p - c;
  const float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0.0f && d5 <= d6) return c;
  // edge regions: the barycentric coordinate opposite the edge is ≤ 0
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) return a + ab * (d1 / (d1 - d3));
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) return a + ac * (d2 / (d2 - d6));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0.0f && d4 - d3 >= 0.0f && d5 - d6 >= 0.0f) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const float sum = va + vb + vc;
  if (!(sum > 0.0f)) return a;  // degenerate triangle whose regions all failed
  return a + ab * (vb / sum) + ac * (vc / sum);
}

// Closest-point queries on a fixed triangle mesh: a bounding-volume
// hierarchy (median splits on the longest axis, up to 4 triangles a leaf),
// searched nearest box first with the best distance so far as the bound.
class ClosestPointTree {
 public:
  struct Result {
    glm::vec3 point{0.0f};
    float distance2 = std::numeric_limits<float>::infinity();
    std::int32_t triangle = -1;
  };

  ClosestPointTree() = default;
  ClosestPointTree(std::vector<float> positions, std::vector<std::int32_t> triangles)
      : pos_(std::move(positions)), tri_(std::move(triangles)) {
    build();
  }

  std::int32_t num_triangles() const { return std::int32_t(tri_.size() / 3); }
  // Vertex k (0..2) of triangle t, as an index into the positions given.
  std::int32_t triangle_vertex(std::int32_t t, int k) const { return tri_[3 * std::size_t(t) + std::size_t(k)]; }

  Result closest(const glm::vec3& p) const {
    Result best;
    if (nodes_.empty()) return best;
    std::int32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& n = nodes_[stack[--top]];
      if (box_distance2(n, p) >= best.distance2) continue;
      if (n.count > 0) {
        for (std::int32_t k = n.first; k < n.first + n.count; ++k) {
          const std::int32_t t = order_[k];
          const glm::vec3 q = closest_point_on_triangle(p, vertex(t, 0), vertex(t, 1), vertex(t, 2));
          const glm::vec3 d = q - p;
          const float d2 = glm::dot(d, d);
          if (d2 < best.distance2) best = Result{q, d2, t};
        }
        continue;
      }
      const std::int32_t l = n.first, r = n.first + 1;
      const float dl = box_distance2(nodes_[l], p), dr = box_distance2(nodes_[r], p);
      // the nearer child is searched first (pushed last)
      if (dl < dr) {
        if (dr < best.distance2) stack[top++] = r;
        if (dl < best.distance2) stack[top++] = l;
      } else {
        if (dl < best.distance2) stack[top++] = l;
        if (dr < best.distance2) stack[top++] = r;
      }
    }
    return best;
  }

 private:
  struct Node {
    glm::vec3 lo, hi;
    std::int32_t first;  // leaf: first index into order_; inner: left child (right = first + 1)
    std::int32_t count;  // > 0: leaf
  };

  glm::vec3 vertex(std::int32_t t, int k) const {
    const float* q = pos_.data() + 3 * std::size_t(tri_[3 * std::size_t(t) + k]);
    return glm::vec3(q[0], q[1], q[2]);
  }

  static float box_distance2(const Node& n, const glm::vec3& p) {
    const glm::vec3 d = glm::max(glm::max(n.lo - p, p - n.hi), glm::vec3(0.0f));
    return glm::dot(d, d);
  }

  void build() {
    const std::int32_t nt = num_triangles();
    nodes_.clear();
    if (nt == 0) return;
    order_.resize(std::size_t(nt));
    std::iota(order_.begin(), order_.end(), 0);
    centroid_.resize(std::size_t(nt));
    for (std::int32_t t = 0; t < nt; ++t) centroid_[t] = (vertex(t, 0) + vertex(t, 1) + vertex(t, 2)) / 3.0f;
    nodes_.reserve(std::size_t(2 * nt));
    nodes_.push_back(Node{});
    split(0, 0, nt, 0);
  }

  void split(std::int32_t node, std::int32_t begin, std::int32_t end, int depth) {
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    glm::vec3 clo = lo, chi = hi;
    for (std::int32_t k = begin; k < end; ++k) {
      const std::int32_t t = order_[k];
      for (int j = 0; j < 3; ++j) {
        lo = glm::min(lo, vertex(t, j));
        hi = glm::max(hi, vertex(t, j));
      }
      clo = glm::min(clo, centroid_[t]);
      chi = glm::max(chi, centroid_[t]);
    }
    nodes_[node].lo = lo;
    nodes_[node].hi = hi;
    const glm::vec3 ext = chi - clo;
    if (end - begin <= 4 || depth >= 60 || !(glm::max(ext.x, glm::max(ext.y, ext.z)) > 0.0f)) {
      nodes_[node].first = begin;
      nodes_[node].count = end - begin;
      return;
    }
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const std::int32_t mid = begin + (end - begin) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](std::int32_t x, std::int32_t y) { return centroid_[x][axis] < centroid_[y][axis]; });
    const std::int32_t left = std::int32_t(nodes_.size());
    nodes_.push_back(Node{});
    nodes_.push_back(Node{});
    nodes_[node].first = left;
    nodes_[node].count = 0;
    split(left, begin, mid, depth + 1);
    split(left + 1, mid, end, depth + 1);
  }

  std::vector<float> pos_;
  std::vector<std::int32_t> tri_;
  std::vector<std::int32_t> order_;
  std::vector<glm::vec3> centroid_;
  std::vector<Node> nodes_;
};

// ------------------------------------------------------------ remeshing steps

struct RemeshOptions {
  float target_length = 0.0f;  // L; <= 0: the input's mean edge length
  int iterations = 10;
  bool project = true;          // back onto the input surface after each relaxation
  float relaxation = 1.0f;      // fraction of the tangential move toward the centroid
  float collapse_min_cos = 0.5f;  // a collapse may turn a face's normal by at most acos of this
  // Optional target length per vertex of the surface projected onto (e.g.
  // geometry/curvature_sizing.hpp's); it then replaces target_length: an edge's target
  // is the smaller of its ends', each end's that of the surface triangle
  // closest to it (the smallest of the triangle's three). Needs a surface.
  const std::vector<float>* sizing = nullptr;
};

struct RemeshStats {
  int splits = 0, collapses = 0, flips = 0;
};

// Mean length of the live edges.
inline float mean_edge_length(const HalfEdgeMesh& m) {
  double sum = 0.0;
  std::int64_t n = 0;
  for (std::int32_t e = 0; e < m.num_edges(); ++e)
    if (!m.edge_deleted(e)) {
      sum += m.edge_length(e);
      ++n;
    }
  return n ? float(sum / double(n)) : 0.0f;
}

// Splits every edge longer than `high` at its midpoint, until none is.
inline int split_long_edges(HalfEdgeMesh& m, float high) {
  int n = 0;
  for (std::int32_t e = 0; e < m.num_edges(); ++e) {  // also visits the edges splits add
    if (m.edge_deleted(e)) continue;
    while (m.edge_length(e) > high) {
      const std::int32_t h = HalfEdgeMesh::halfedge(e);
      m.split_edge(e, 0.5f * (m.position(m.from(h)) + m.position(m.to(h))));
      ++n;
    }
  }
  return n;
}

// The same with a target length per vertex (`length`, grown as vertices are
// added: a new vertex takes its edge's target): each edge there was at the
// start that is longer than 4/3 of the smaller target of its ends is split
// once. Not the edges the splits make: a new vertex carries a shorter target
// into a region of longer ones, and around a vertex of such a region the
// edges to the new vertices can stay just above the threshold split after
// split without end (seen on a FlexiCubes bunny). remesh() calls this once per
// iteration, so an edge many times too long is halved on each.
inline int split_long_edges(HalfEdgeMesh& m, std::vector<float>& length) {
  int n = 0;
  const std::int32_t edges = m.num_edges();
  for (std::int32_t e = 0; e < edges; ++e) {
    if (m.edge_deleted(e)) continue;
    const std::int32_t h = HalfEdgeMesh::halfedge(e);
    const std::int32_t a = m.from(h), b = m.to(h);
    const float target = std::min(length[std::size_t(a)], length[std::size_t(b)]);
    if (!(m.edge_length(e) > 4.0f / 3.0f * target)) continue;
    const std::int32_t v = m.split_edge(e, 0.5f * (m.position(a) + m.position(b)));
    if (length.size() <= std::size_t(v)) length.resize(std::size_t(v) + 1, target);
    length[std::size_t(v)] = target;
    ++n;
  }
  return n;
}

namespace detail {

// Whether every edge at a or b would stay within `high` once both sit at p.
inline bool collapse_keeps_short(const HalfEdgeMesh& m, std::int32_t a, std::int32_t b, const glm::vec3& p,
                                 float high) {
  const float high2 = high * high;
  bool ok = true;
  const auto test = [&](std::int32_t v) {
    m.for_each_neighbor(v, [&](std::int32_t w) {
      if (w == a || w == b) return;
      const glm::vec3 d = m.position(w) - p;
      if (glm::dot(d, d) > high2) ok = false;
    });
  };
  test(a);
  test(b);
  return ok;
}

// Collapse pass with the thresholds (low, high) of each edge from bounds(a, b).
template <class Bounds>
inline int collapse_short_edges_by(HalfEdgeMesh& m, Bounds&& bounds, float min_cos) {
  int n = 0;
  for (std::int32_t e = 0; e < m.num_edges(); ++e) {
    if (m.edge_deleted(e)) continue;
    const std::int32_t h0 = HalfEdgeMesh::halfedge(e);
    const auto [low, high] = bounds(m.from(h0), m.to(h0));
    if (!(m.edge_length(e) < low)) continue;
    for (int side = 0; side < 2; ++side) {
      const std::int32_t h = HalfEdgeMesh::halfedge(e, side);  // from(h) is removed, to(h) kept
      const std::int32_t a = m.from(h), b = m.to(h);
      const bool ba = m.is_boundary_vertex(a), bb = m.is_boundary_vertex(b);
      if (ba && !bb) continue;  // keep the boundary vertex: the other direction
      const glm::vec3 p = (ba == bb) ? 0.5f * (m.position(a) + m.position(b)) : m.position(b);
      if (!detail::collapse_keeps_short(m, a, b, p, high)) continue;
      if (!m.can_collapse(h) || m.collapse_flips_normals(h, p, min_cos)) continue;
      m.collapse_edge(h, p);
      ++n;
      break;
    }
  }
  return n;
}

}  // namespace detail

// Collapses edges shorter than `low` (to their midpoint; a boundary vertex
// stays where it is and an interior one joins it), unless that would make an
// edge longer than `high`, break the link condition or turn a face by more
// than acos(min_cos).
inline int collapse_short_edges(HalfEdgeMesh& m, float low, float high, float min_cos = 0.5f) {
  return detail::collapse_short_edges_by(m, [low, high](std::int32_t, std::int32_t) { return std::pair(low, high); },
                                         min_cos);
}

// The same with a target length per vertex: an edge is collapsed when it is
// shorter than 4/5 of the smaller target of its ends, unless an edge would
// grow beyond 4/3 of it.
inline int collapse_short_edges(HalfEdgeMesh& m, const std::vector<float>& length, float min_cos = 0.5f) {
  return detail::collapse_short_edges_by(
      m,
      [&length](std::int32_t a, std::int32_t b) {
        const float target = std::min(length[std::size_t(a)], length[std::size_t(b)]);
        return std::pair(4.0f / 5.0f * target, 4.0f / 3.0f * target);
      },
      min_cos);
}

// Flips interior edges where that brings the valences of the four vertices
// involved closer to 6 (4 on the boundary), and the flip folds nothing.
inline int equalize_valences(HalfEdgeMesh& m) {
  int n = 0;
  const auto target = [&](std::int32_t v) { return m.is_boundary_vertex(v) ? 4 : 6; };
  for (std::int32_t e = 0; e < m.num_edges(); ++e) {
    if (m.edge_deleted(e) || m.is_boundary_edge(e)) continue;
    const std::int32_t h = HalfEdgeMesh::halfedge(e), t = h ^ 1;
    const std::int32_t a = m.from(h), b = m.to(h), c = m.to(m.next(h)), d = m.to(m.next(t));
    const int da = m.valence(a) - target(a), db = m.valence(b) - target(b), dc = m.valence(c) - target(c),
              dd = m.valence(d) - target(d);
    const int before = std::abs(da) + std::abs(db) + std::abs(dc) + std::abs(dd);
    const int after = std::abs(da - 1) + std::abs(db - 1) + std::abs(dc + 1) + std::abs(dd + 1);
    if (after >= before || !m.can_flip(e)) continue;
    // geometry: the new faces (c, d, b) and (d, c, a) must face the way the old ones do
    const glm::vec3 pa = m.position(a), pb = m.position(b), pc = m.position(c), pd = m.position(d);
    const glm::vec3 n_old = glm::cross(pb - pa, pc - pa) + glm::cross(pa - pb, pd - pb);
    const glm::vec3 n1 = glm::cross(pd - pc, pb - pc), n2 = glm::cross(pc - pd, pa - pd);
    if (!(glm::dot(n1, n_old) > 0.0f) || !(glm::dot(n2, n_old) > 0.0f) || !(glm::dot(n1, n2) > 0.0f)) continue;
    m.flip_edge(e);
    ++n;
  }
  return n;
}

// Moves every interior vertex toward the area-weighted centroid of its
// one-ring (the triangle centroids weighted by area), within its tangent
// plane (normal: the area-weighted face normals). Boundary vertices stay.
inline void tangential_relaxation(HalfEdgeMesh& m, float amount = 1.0f) {
  const std::int32_t nv = m.num_vertices();
  std::vector<glm::vec3> moved(static_cast<std::size_t>(nv));
  parallel_for(nv, 512, [&](std::int64_t begin, std::int64_t end, int) {
    for (std::int64_t i = begin; i < end; ++i) {
      const std::int32_t v = std::int32_t(i);
      if (m.vertex_deleted(v)) continue;
      const glm::vec3 p = m.position(v);
      moved[v] = p;
      if (m.is_boundary_vertex(v)) continue;
      glm::vec3 normal(0.0f), centroid(0.0f);
      float area = 0.0f;
      m.for_each_face(v, [&](std::int32_t f) {
        std::int32_t vs[3];
        m.face_vertices(f, vs);
        const glm::vec3 an = m.face_area_normal(f);
        const float w = glm::length(an);
        normal += an;
        centroid += w * (m.position(vs[0]) + m.position(vs[1]) + m.position(vs[2])) / 3.0f;
        area += w;
      });
      const float nl = glm::length(normal);
      if (!(area > 0.0f) || !(nl > 0.0f)) continue;
      normal /= nl;
      const glm::vec3 d = centroid / area - p;
      moved[v] = p + amount * (d - glm::dot(d, normal) * normal);
    }
  });
  for (std::int32_t v = 0; v < nv; ++v)
    if (!m.vertex_deleted(v)) m.position(v) = moved[v];
}

// Moves every vertex to its closest point on the tree's surface.
inline void project_to_surface(HalfEdgeMesh& m, const ClosestPointTree& surface) {
  parallel_for(m.num_vertices(), 256, [&](std::int64_t begin, std::int64_t end, int) {
    for (std::int64_t i = begin; i < end; ++i) {
      const std::int32_t v = std::int32_t(i);
      if (m.vertex_deleted(v)) continue;
      const ClosestPointTree::Result r = surface.closest(m.position(v));
      if (r.triangle >= 0) m.position(v) = r.point;
    }
  });
}

// The target length of each vertex of m: that of the surface triangle
// closest to it (the smallest of its vertices' `sizing`).
inline std::vector<float> target_lengths(const HalfEdgeMesh& m, const ClosestPointTree& surface,
                                         const std::vector<float>& sizing) {
  std::vector<float> length(std::size_t(m.num_vertices()), 0.0f);
  parallel_for(m.num_vertices(), 256, [&](std::int64_t begin, std::int64_t end, int) {
    for (std::int64_t i = begin; i < end; ++i) {
      const std::int32_t v = std::int32_t(i);
      if (m.vertex_deleted(v)) continue;
      const ClosestPointTree::Result r = surface.closest(m.position(v));
      if (r.triangle < 0) continue;
      float l = std::numeric_limits<float>::infinity();
      for (int k = 0; k < 3; ++k) l = std::min(l, sizing[std::size_t(surface.triangle_vertex(r.triangle, k))]);
      length[std::size_t(v)] = l;
    }
  });
  return length;
}

// The whole loop on a half-edge mesh: `iterations` rounds of split, collapse,
// flip, relax and project onto `surface` (when given). Compacts at the end.
inline RemeshStats remesh(HalfEdgeMesh& m, const ClosestPointTree* surface, const RemeshOptions& o) {
  RemeshStats stats;
  const float L = o.target_length > 0.0f ? o.target_length : mean_edge_length(m);
  const float high = 4.0f / 3.0f * L, low = 4.0f / 5.0f * L;
  const bool adaptive = o.sizing != nullptr && surface != nullptr;
  for (int it = 0; it < o.iterations; ++it) {
    if (adaptive) {
      std::vector<float> length = target_lengths(m, *surface, *o.sizing);
      stats.splits += split_long_edges(m, length);
      stats.collapses += collapse_short_edges(m, length, o.collapse_min_cos);
    } else {
      stats.splits += split_long_edges(m, high);
      stats.collapses += collapse_short_edges(m, low, high, o.collapse_min_cos);
    }
    stats.flips += equalize_valences(m);
    tangential_relaxation(m, o.relaxation);
    if (surface && o.project) project_to_surface(m, *surface);
  }
  m.compact();
  return stats;
}

struct RemeshResult {
  std::vector<float> positions;         // 3 per vertex
  std::vector<std::int32_t> triangles;  // 3 per triangle
  RemeshStats stats;
  float target_length = 0.0f;
  HalfEdgeReport report;  // problems of the input; when !report.ok() nothing was remeshed
};

// Remeshes flat arrays to edge length options.target_length (default: the
// input's mean), projecting onto the input surface.
inline RemeshResult remesh(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles,
                           const RemeshOptions& options = {}) {
  RemeshResult r;
  HalfEdgeMesh m = HalfEdgeMesh::from_triangles(positions, triangles, &r.report);
  if (!r.report.ok()) return r;
  RemeshOptions o = options;
  if (!(o.target_length > 0.0f)) o.target_length = mean_edge_length(m);
  r.target_length = o.target_length;
  const ClosestPointTree surface(positions, triangles);
  r.stats = remesh(m, &surface, o);
  m.to_arrays(r.positions, r.triangles);
  return r;
}

}  // namespace difftrans::geometry
