// Half-edge triangle mesh for remeshing: built from flat arrays with manifold
// validation; edge split, collapse (link condition), flip; compaction back.
//
// Length: the three local operations rewrite the same half-edge records and
// keep one set of invariants (checked by validate()); they are kept together
// with them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

namespace difftrans::geometry {

// Layout. Half-edges come in pairs: the twin of h is h ^ 1 and edge e owns
// half-edges 2e and 2e + 1. A half-edge stores its head vertex (to), the next
// and previous half-edge around its face and its face; a half-edge on the
// boundary has face −1 and next/prev link the boundary loop it lies on, so
// every half-edge has a twin and next/prev everywhere. The origin of h is the
// head of its twin. Each vertex keeps one outgoing half-edge, a boundary one
// when the vertex is on the boundary; each face keeps one of its half-edges.
// Deleted elements are flagged and left in place until compact().
//
// Orientation: faces are counter-clockwise seen from outside, so face f's
// half-edges run a → b → c → a for the triangle (a, b, c).

// Problems found while building: each non-manifold edge (as its directed
// vertex pair that occurs again, or an edge with more than two faces), each
// non-manifold vertex (more than one fan of faces), and each degenerate
// triangle (a repeated vertex) or index out of range.
struct HalfEdgeReport {
  std::vector<std::pair<std::int32_t, std::int32_t>> nonmanifold_edges;
  std::vector<std::int32_t> nonmanifold_vertices;
  std::vector<std::int32_t> bad_triangles;
  bool ok() const { return nonmanifold_edges.empty() && nonmanifold_vertices.empty() && bad_triangles.empty(); }
};

class HalfEdgeMesh {
 public:
  using Vec3 = glm::vec3;
  static constexpr std::int32_t invalid = -1;

  HalfEdgeMesh() = default;

  // Builds from 3 floats per vertex and 3 indices per triangle. On failure
  // (see the report) the mesh is left empty.
  static HalfEdgeMesh from_triangles(const float* positions, std::int32_t num_vertices,
                                     const std::int32_t* triangles, std::int32_t num_triangles,
                                     HalfEdgeReport* report = nullptr) {
    HalfEdgeReport local;
    HalfEdgeReport& rep = report ? *report : local;
    rep = HalfEdgeReport{};
    HalfEdgeMesh m;
    m.pos_.resize(std::size_t(num_vertices));
    for (std::int32_t v = 0; v < num_vertices; ++v)
      m.pos_[v] = Vec3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
    m.v_he_.assign(std::size_t(num_vertices), invalid);
    m.v_dead_.assign(std::size_t(num_vertices), 0);

    std::unordered_map<std::uint64_t, std::int32_t> directed;  // (a, b) -> half-edge a→b
    directed.reserve(std::size_t(num_triangles) * 4);
    const auto key = [](std::int32_t a, std::int32_t b) { return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b); };
    for (std::int32_t f = 0; f < num_triangles; ++f) {
      const std::int32_t* t = triangles + 3 * f;
      bool bad = false;
      for (int k = 0; k < 3; ++k) bad |= t[k] < 0 || t[k] >= num_vertices;
      if (!bad) bad = t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
      if (bad) {
        rep.bad_triangles.push_back(f);
        continue;
      }
      bool dup = false;
      for (int k = 0; k < 3; ++k) {
        const std::int32_t a = t[k], b = t[(k + 1) % 3];
        if (directed.count(key(a, b))) {
          rep.nonmanifold_edges.emplace_back(a, b);
          dup = true;
        }
      }
      if (dup) continue;
      const std::int32_t face = std::int32_t(m.f_he_.size());
      m.f_he_.push_back(invalid);
      m.f_dead_.push_back(0);
      std::int32_t hs[3];
      for (int k = 0; k < 3; ++k) {
        const std::int32_t a = t[k], b = t[(k + 1) % 3];
        const auto twin = directed.find(key(b, a));
        std::int32_t h;
        if (twin != directed.end()) {
          h = twin->second ^ 1;  // the other half of an existing pair, so far a boundary placeholder
        } else {
          h = m.new_edge(a, b);
        }
        directed[key(a, b)] = h;
        hs[k] = h;
      }
      m.link_face(face, hs[0], hs[1], hs[2]);
    }
    if (!rep.nonmanifold_edges.empty() || !rep.bad_triangles.empty()) return HalfEdgeMesh{};

    // Boundary half-edges: the halves no face claimed. Each goes b→a where a→b
    // is an interior half-edge; link them into loops through their vertices.
    std::vector<std::int32_t> boundary_out(std::size_t(num_vertices), invalid);
    for (std::int32_t h = 0; h < m.num_halfedges(); ++h) {
      if (m.he_face_[h] != invalid) continue;
      const std::int32_t from = m.from(h);
      if (boundary_out[from] != invalid) rep.nonmanifold_vertices.push_back(from);
      boundary_out[from] = h;
    }
    if (!rep.nonmanifold_vertices.empty()) {
      std::sort(rep.nonmanifold_vertices.begin(), rep.nonmanifold_vertices.end());
      rep.nonmanifold_vertices.erase(std::unique(rep.nonmanifold_vertices.begin(), rep.nonmanifold_vertices.end()),
                                     rep.nonmanifold_vertices.end());
      return HalfEdgeMesh{};
    }
    for (std::int32_t h = 0; h < m.num_halfedges(); ++h) {
      if (m.he_face_[h] != invalid) continue;
      const std::int32_t n = boundary_out[m.he_to_[h]];
      m.he_next_[h] = n;
      m.he_prev_[n] = h;
    }
    // outgoing half-edges: a boundary one where there is one
    for (std::int32_t h = 0; h < m.num_halfedges(); ++h) {
      const std::int32_t v = m.from(h);
      if (m.v_he_[v] == invalid || m.he_face_[h] == invalid) m.v_he_[v] = h;
    }
    // each vertex's fan must be one: count its outgoing half-edges two ways
    std::vector<std::int32_t> out_count(std::size_t(num_vertices), 0);
    for (std::int32_t h = 0; h < m.num_halfedges(); ++h) ++out_count[m.from(h)];
    for (std::int32_t v = 0; v < num_vertices; ++v) {
      if (m.v_he_[v] == invalid) {
        m.delete_vertex(v);  // isolated vertex: not part of the surface
        continue;
      }
      if (m.valence(v) != out_count[v]) rep.nonmanifold_vertices.push_back(v);
    }
    if (!rep.nonmanifold_vertices.empty()) return HalfEdgeMesh{};
    return m;
  }
  static HalfEdgeMesh from_triangles(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles,
                                     HalfEdgeReport* report = nullptr) {
    return from_triangles(positions.data(), std::int32_t(positions.size() / 3), triangles.data(),
                          std::int32_t(triangles.size() / 3), report);
  }

  // ---------------------------------------------------------------- access
  // Sizes count deleted slots too; the num_live_* functions do not.
  std::int32_t num_vertices() const { return std::int32_t(pos_.size()); }
  std::int32_t num_halfedges() const { return std::int32_t(he_to_.size()); }
  std::int32_t num_edges() const { return num_halfedges() / 2; }
  std::int32_t num_faces() const { return std::int32_t(f_he_.size()); }
  std::int32_t num_live_vertices() const { return num_vertices() - dead_v_; }
  std::int32_t num_live_edges() const { return num_edges() - dead_e_; }
  std::int32_t num_live_faces() const { return num_faces() - dead_f_; }
  // V − E + F over live elements (2 − 2g − b for a connected surface).
  std::int32_t euler_characteristic() const { return num_live_vertices() - num_live_edges() + num_live_faces(); }

  bool vertex_deleted(std::int32_t v) const { return v_dead_[v] != 0; }
  bool edge_deleted(std::int32_t e) const { return e_dead_[e] != 0; }
  bool face_deleted(std::int32_t f) const { return f_dead_[f] != 0; }

  static std::int32_t twin(std::int32_t h) { return h ^ 1; }
  static std::int32_t edge(std::int32_t h) { return h >> 1; }
  static std::int32_t halfedge(std::int32_t e, int side = 0) { return 2 * e + side; }
  std::int32_t next(std::int32_t h) const { return he_next_[h]; }
  std::int32_t prev(std::int32_t h) const { return he_prev_[h]; }
  std::int32_t to(std::int32_t h) const { return he_to_[h]; }
  std::int32_t from(std::int32_t h) const { return he_to_[h ^ 1]; }
  std::int32_t face(std::int32_t h) const { return he_face_[h]; }
  std::int32_t face_halfedge(std::int32_t f) const { return f_he_[f]; }
  std::int32_t outgoing(std::int32_t v) const { return v_he_[v]; }

  const Vec3& position(std::int32_t v) const { return pos_[v]; }
  Vec3& position(std::int32_t v) { return pos_[v]; }
  const std::vector<Vec3>& positions() const { return pos_; }

  bool is_boundary_halfedge(std::int32_t h) const { return he_face_[h] == invalid; }
  bool is_boundary_edge(std::int32_t e) const { return he_face_[2 * e] == invalid || he_face_[2 * e + 1] == invalid; }
  bool is_boundary_vertex(std::int32_t v) const { return v_he_[v] != invalid && he_face_[v_he_[v]] == invalid; }

  // The three vertices of face f in order.
  void face_vertices(std::int32_t f, std::int32_t out[3]) const {
    const std::int32_t h = f_he_[f];
    out[0] = from(h);
    out[1] = he_to_[h];
    out[2] = he_to_[he_next_[h]];
  }

  // Calls fn(h) for every half-edge leaving v, turning around v; the
  // boundary one (if any) comes first.
  template <class Fn>
  void for_each_outgoing(std::int32_t v, Fn&& fn) const {
    const std::int32_t start = v_he_[v];
    if (start == invalid) return;
    std::int32_t h = start, steps = 0;
    do {
      fn(h);
      h = he_next_[h ^ 1];
    } while (h != start && ++steps < num_halfedges());  // the bound only guards a corrupted structure
  }
  // Calls fn(w) for each neighbour w of v.
  template <class Fn>
  void for_each_neighbor(std::int32_t v, Fn&& fn) const {
    for_each_outgoing(v, [&](std::int32_t h) { fn(he_to_[h]); });
  }
  // Calls fn(f) for each face around v.
  template <class Fn>
  void for_each_face(std::int32_t v, Fn&& fn) const {
    for_each_outgoing(v, [&](std::int32_t h) {
      if (he_face_[h] != invalid) fn(he_face_[h]);
    });
  }

  // Number of edges at v.
  int valence(std::int32_t v) const {
    int n = 0;
    for_each_outgoing(v, [&](std::int32_t) { ++n; });
    return n;
  }

  // The half-edge a→b, or invalid.
  std::int32_t find_halfedge(std::int32_t a, std::int32_t b) const {
    std::int32_t found = invalid;
    for_each_outgoing(a, [&](std::int32_t h) {
      if (he_to_[h] == b) found = h;
    });
    return found;
  }

  float edge_length(std::int32_t e) const { return glm::length(pos_[he_to_[2 * e]] - pos_[he_to_[2 * e + 1]]); }
  // cross(b − a, c − a) of face f: twice its area times its unit normal.
  Vec3 face_area_normal(std::int32_t f) const {
    std::int32_t v[3];
    face_vertices(f, v);
    return glm::cross(pos_[v[1]] - pos_[v[0]], pos_[v[2]] - pos_[v[0]]);
  }

  // ---------------------------------------------------------------- operations

  // Splits edge e at point p: a new vertex, the one or two faces beside the
  // edge each cut in two. Returns the new vertex. Keeps V − E + F.
  std::int32_t split_edge(std::int32_t e, const Vec3& p) {
    const std::int32_t h = 2 * e, t = h + 1;
    const std::int32_t b = he_to_[h];
    const std::int32_t f0 = he_face_[h], f1 = he_face_[t];
    const std::int32_t h1 = he_next_[h], h2 = he_prev_[h];  // b→c, c→a (or the boundary loop)
    const std::int32_t t1 = he_next_[t], t2 = he_prev_[t];  // a→d, d→b
    const std::int32_t m = new_vertex(p);
    const std::int32_t g = new_edge(m, b);  // g: m→b, g^1: b→m
    he_to_[h] = m;                           // h: a→m; t (its twin) now m→a
    if (f0 != invalid) {
      const std::int32_t c = he_to_[h1];
      const std::int32_t x = new_edge(m, c);
      link_face(f0, h, x, h2);
      link_face(new_face(), g, h1, x ^ 1);
    } else {
      he_face_[g] = invalid;
      link(h, g);
      link(g, h1);
    }
    if (f1 != invalid) {
      const std::int32_t d = he_to_[t1];
      const std::int32_t y = new_edge(m, d);
      link_face(f1, t, t1, y ^ 1);
      link_face(new_face(), g ^ 1, y, t2);
    } else {
      he_face_[g ^ 1] = invalid;
      link(t2, g ^ 1);
      link(g ^ 1, t);
    }
    if (v_he_[b] == t) v_he_[b] = g ^ 1;
    v_he_[m] = f1 == invalid ? t : g;  // a boundary half-edge if there is one (f0 boundary: g)
    return m;
  }

  // Whether flipping edge e keeps the mesh a manifold: both sides are faces,
  // the opposite vertices differ and are not joined yet, and both ends keep
  // valence ≥ 3 (≥ 2 on the boundary).
  bool can_flip(std::int32_t e) const {
    if (e_dead_[e] || is_boundary_edge(e)) return false;
    const std::int32_t h = 2 * e, t = h + 1;
    const std::int32_t a = from(h), b = he_to_[h];
    const std::int32_t c = he_to_[he_next_[h]], d = he_to_[he_next_[t]];
    if (c == d || find_halfedge(c, d) != invalid) return false;
    const auto min_after = [&](std::int32_t v) { return is_boundary_vertex(v) ? 3 : 4; };
    return valence(a) >= min_after(a) && valence(b) >= min_after(b);
  }

  // Replaces edge a-b, between faces (a, b, c) and (b, a, d), by c-d. The
  // caller checks can_flip(e) first.
  void flip_edge(std::int32_t e) {
    const std::int32_t h = 2 * e, t = h + 1;
    const std::int32_t a = from(h), b = he_to_[h];
    const std::int32_t h1 = he_next_[h], h2 = he_prev_[h];  // b→c, c→a
    const std::int32_t t1 = he_next_[t], t2 = he_prev_[t];  // a→d, d→b
    const std::int32_t f0 = he_face_[h], f1 = he_face_[t];
    const std::int32_t c = he_to_[h1], d = he_to_[t1];
    he_to_[h] = d;  // h: c→d
    he_to_[t] = c;  // t: d→c
    link_face(f0, h, t2, h1);
    link_face(f1, t, h2, t1);
    if (v_he_[a] == h) v_he_[a] = t1;
    if (v_he_[b] == t) v_he_[b] = h1;
  }

  // Whether collapsing half-edge h (its origin a merged into its head b)
  // keeps the mesh a manifold: the link condition (the common neighbours of
  // a and b are exactly the vertices opposite the edge), an interior edge
  // does not join two boundary vertices, opposite vertices keep enough
  // edges, and the mesh does not shrink below a tetrahedron.
  bool can_collapse(std::int32_t h) const {
    if (e_dead_[h >> 1]) return false;
    const std::int32_t t = h ^ 1;
    const std::int32_t a = from(h), b = he_to_[h];
    const bool interior_edge = he_face_[h] != invalid && he_face_[t] != invalid;
    if (interior_edge && is_boundary_vertex(a) && is_boundary_vertex(b)) return false;
    std::int32_t opposite[2] = {invalid, invalid};
    int n_opposite = 0;
    if (he_face_[h] != invalid) opposite[n_opposite++] = he_to_[he_next_[h]];
    if (he_face_[t] != invalid) opposite[n_opposite++] = he_to_[he_next_[t]];
    if (n_opposite == 2 && opposite[0] == opposite[1]) return false;
    // link condition on vertices
    mark_.resize(pos_.size(), 0);
    ++stamp_;
    if (stamp_ == 0) {
      std::fill(mark_.begin(), mark_.end(), 0);
      stamp_ = 1;
    }
    for_each_neighbor(a, [&](std::int32_t w) { mark_[w] = stamp_; });
    int common = 0;
    bool ok = true;
    for_each_neighbor(b, [&](std::int32_t w) {
      if (mark_[w] != stamp_) return;
      ++common;
      if (w != opposite[0] && w != opposite[1]) ok = false;
    });
    if (!ok || common != n_opposite) return false;
    for (int k = 0; k < n_opposite; ++k) {
      const std::int32_t c = opposite[k];
      if (valence(c) < (is_boundary_vertex(c) ? 3 : 4)) return false;
    }
    // a and b's faces alone: a closed tetrahedron, or a lone triangle / strip end
    if (!interior_edge && valence(a) + valence(b) <= 4) return false;
    if (interior_edge && num_live_faces() <= 4) return false;
    return true;
  }

  // Whether moving h's origin and head together to p turns any surviving
  // face around them by more than the angle whose cosine is min_cos (0: no
  // normal may flip), or makes one degenerate.
  bool collapse_flips_normals(std::int32_t h, const Vec3& p, float min_cos = 0.0f) const {
    const std::int32_t a = from(h), b = he_to_[h];
    const std::int32_t fa = he_face_[h], fb = he_face_[h ^ 1];
    bool flips = false;
    const auto test = [&](std::int32_t v) {
      for_each_face(v, [&](std::int32_t f) {
        if (flips || f == fa || f == fb) return;
        std::int32_t vs[3];
        face_vertices(f, vs);
        Vec3 q[3];
        for (int k = 0; k < 3; ++k) q[k] = (vs[k] == a || vs[k] == b) ? p : pos_[vs[k]];
        const Vec3 n0 = face_area_normal(f);
        const Vec3 n1 = glm::cross(q[1] - q[0], q[2] - q[0]);
        const float l0 = glm::length(n0), l1 = glm::length(n1);
        if (!(l1 > 0.0f) || glm::dot(n0, n1) <= min_cos * l0 * l1) flips = true;
      });
    };
    test(a);
    test(b);
    return flips;
  }

  // Collapses half-edge h: its origin a is removed, its head b moves to p and
  // takes over a's edges; the faces beside the edge vanish. Check
  // can_collapse(h) first. Returns b.
  std::int32_t collapse_edge(std::int32_t h, const Vec3& p) {
    const std::int32_t t = h ^ 1;
    const std::int32_t a = from(h), b = he_to_[h];
    const std::int32_t f0 = he_face_[h], f1 = he_face_[t];
    const std::int32_t h1 = he_next_[h], h2 = he_prev_[h];  // b→c, c→a
    const std::int32_t t1 = he_next_[t], t2 = he_prev_[t];  // a→d, d→b
    // a's incoming half-edges now end at b
    for_each_outgoing(a, [&](std::int32_t o) { he_to_[o ^ 1] = b; });
    std::int32_t keep_b = invalid, keep_c = invalid, keep_d = invalid;
    if (f0 != invalid) {
      // edges b-c (h1) and c-a (h2) become one: h2 takes the place of h1's twin
      const std::int32_t c = he_to_[h1];
      const std::int32_t o1 = h1 ^ 1;  // c→b
      replace(o1, h2);
      delete_edge(h1 >> 1);
      delete_face(f0);
      keep_b = h2 ^ 1;  // b→c
      if (v_he_[c] == o1) v_he_[c] = h2;
      keep_c = c;
    } else {
      link(he_prev_[h], he_next_[h]);  // the boundary loop skips h
    }
    if (f1 != invalid) {
      // edges a-d (t1) and d-b (t2) become one: t1 takes the place of t2's twin
      const std::int32_t d = he_to_[t1];
      const std::int32_t o4 = t2 ^ 1;  // b→d
      replace(o4, t1);
      delete_edge(t2 >> 1);
      delete_face(f1);
      if (keep_b == invalid) keep_b = t1;
      if (v_he_[d] == t2) v_he_[d] = t1 ^ 1;
      keep_d = d;
    } else {
      // the boundary loop skips t (read afresh: t's prev may have been replaced above)
      link(he_prev_[t], he_next_[t]);
      if (keep_b == invalid) keep_b = t1;
    }
    delete_edge(h >> 1);
    delete_vertex(a);
    pos_[b] = p;
    v_he_[b] = keep_b;
    prefer_boundary(b);
    if (keep_c != invalid) prefer_boundary(keep_c);
    if (keep_d != invalid) prefer_boundary(keep_d);
    return b;
  }

  // ---------------------------------------------------------------- checks

  // Every invariant of the structure, or the first violation in words:
  // twins, next/prev inverse, faces of three half-edges, boundary loops of
  // face −1, outgoing half-edges (a boundary one on the boundary), one fan
  // per vertex, no two edges between the same vertices, nothing live
  // pointing at something deleted.
  std::string validate() const {
    std::ostringstream err;
    std::vector<std::int32_t> out_count(pos_.size(), 0);
    std::unordered_map<std::uint64_t, std::int32_t> seen;
    for (std::int32_t h = 0; h < num_halfedges(); ++h) {
      if (e_dead_[h >> 1]) continue;
      const std::int32_t n = he_next_[h], p = he_prev_[h];
      if (n < 0 || p < 0 || e_dead_[n >> 1] || e_dead_[p >> 1]) return err << "half-edge " << h << ": next/prev deleted", err.str();
      if (he_prev_[n] != h || he_next_[p] != h) return err << "half-edge " << h << ": next/prev not inverse", err.str();
      if (he_to_[p] != from(h)) return err << "half-edge " << h << ": prev does not end at its origin", err.str();
      const std::int32_t f = he_face_[h];
      if (he_face_[n] != f) return err << "half-edge " << h << ": next in another face", err.str();
      if (f != invalid) {
        if (f_dead_[f]) return err << "half-edge " << h << ": deleted face", err.str();
        if (he_next_[he_next_[n]] != h) return err << "face " << f << ": not a triangle", err.str();
      }
      const std::int32_t a = from(h), b = he_to_[h];
      if (a == b) return err << "half-edge " << h << ": a loop", err.str();
      if (v_dead_[a] || v_dead_[b]) return err << "half-edge " << h << ": deleted vertex", err.str();
      const std::uint64_t k = (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
      if (!seen.emplace(k, h).second) return err << "two half-edges " << a << "->" << b, err.str();
      ++out_count[a];
    }
    for (std::int32_t f = 0; f < num_faces(); ++f) {
      if (f_dead_[f]) continue;
      const std::int32_t h = f_he_[f];
      if (h < 0 || e_dead_[h >> 1] || he_face_[h] != f) return err << "face " << f << ": bad half-edge", err.str();
    }
    for (std::int32_t v = 0; v < num_vertices(); ++v) {
      if (v_dead_[v]) continue;
      const std::int32_t h = v_he_[v];
      if (h < 0 || e_dead_[h >> 1] || from(h) != v) return err << "vertex " << v << ": bad outgoing half-edge", err.str();
      int n = 0, boundary = 0;
      std::int32_t g = h;
      do {
        ++n;
        boundary += he_face_[g] == invalid;
        g = he_next_[g ^ 1];
      } while (g != h && n <= out_count[v]);
      if (n != out_count[v]) return err << "vertex " << v << ": more than one fan", err.str();
      if (boundary > 1) return err << "vertex " << v << ": more than one boundary gap", err.str();
      if (boundary == 1 && he_face_[h] != invalid) return err << "vertex " << v << ": outgoing not on the boundary", err.str();
      if (n < 2) return err << "vertex " << v << ": valence " << n, err.str();
    }
    return {};
  }

  // ---------------------------------------------------------------- output

  // Drops deleted elements and renumbers in place; vertex_map (if given)
  // receives the new index of every old vertex (−1 when deleted).
  void compact(std::vector<std::int32_t>* vertex_map = nullptr) {
    std::vector<std::int32_t> vmap(pos_.size(), invalid), emap(e_dead_.size(), invalid), fmap(f_he_.size(), invalid);
    std::int32_t nv = 0, ne = 0, nf = 0;
    for (std::size_t v = 0; v < pos_.size(); ++v)
      if (!v_dead_[v]) vmap[v] = nv++;
    for (std::size_t e = 0; e < e_dead_.size(); ++e)
      if (!e_dead_[e]) emap[e] = ne++;
    for (std::size_t f = 0; f < f_he_.size(); ++f)
      if (!f_dead_[f]) fmap[f] = nf++;
    const auto mh = [&](std::int32_t h) { return h < 0 ? h : 2 * emap[h >> 1] + (h & 1); };
    HalfEdgeMesh m;
    m.pos_.resize(std::size_t(nv));
    m.v_he_.resize(std::size_t(nv));
    m.v_dead_.assign(std::size_t(nv), 0);
    for (std::size_t v = 0; v < pos_.size(); ++v)
      if (vmap[v] >= 0) {
        m.pos_[vmap[v]] = pos_[v];
        m.v_he_[vmap[v]] = mh(v_he_[v]);
      }
    m.he_to_.resize(std::size_t(2 * ne));
    m.he_next_.resize(std::size_t(2 * ne));
    m.he_prev_.resize(std::size_t(2 * ne));
    m.he_face_.resize(std::size_t(2 * ne));
    m.e_dead_.assign(std::size_t(ne), 0);
    for (std::int32_t h = 0; h < num_halfedges(); ++h) {
      if (e_dead_[h >> 1]) continue;
      const std::int32_t g = mh(h);
      m.he_to_[g] = vmap[he_to_[h]];
      m.he_next_[g] = mh(he_next_[h]);
      m.he_prev_[g] = mh(he_prev_[h]);
      m.he_face_[g] = he_face_[h] < 0 ? invalid : fmap[he_face_[h]];
    }
    m.f_he_.resize(std::size_t(nf));
    m.f_dead_.assign(std::size_t(nf), 0);
    for (std::size_t f = 0; f < f_he_.size(); ++f)
      if (fmap[f] >= 0) m.f_he_[fmap[f]] = mh(f_he_[f]);
    if (vertex_map) *vertex_map = vmap;
    *this = std::move(m);
  }

  // The live mesh as flat arrays (3 floats per vertex, 3 indices per
  // triangle), vertices numbered as compact() would number them.
  void to_arrays(std::vector<float>& positions, std::vector<std::int32_t>& triangles) const {
    std::vector<std::int32_t> vmap(pos_.size(), invalid);
    positions.clear();
    triangles.clear();
    std::int32_t nv = 0;
    for (std::size_t v = 0; v < pos_.size(); ++v)
      if (!v_dead_[v]) {
        vmap[v] = nv++;
        positions.insert(positions.end(), {pos_[v].x, pos_[v].y, pos_[v].z});
      }
    for (std::int32_t f = 0; f < num_faces(); ++f) {
      if (f_dead_[f]) continue;
      std::int32_t vs[3];
      face_vertices(f, vs);
      for (int k = 0; k < 3; ++k) triangles.push_back(vmap[vs[k]]);
    }
  }

 private:
  std::int32_t new_vertex(const Vec3& p) {
    pos_.push_back(p);
    v_he_.push_back(invalid);
    v_dead_.push_back(0);
    return std::int32_t(pos_.size()) - 1;
  }
  // A new edge pair: returns h = a→b (h ^ 1 = b→a), both unlinked and faceless.
  std::int32_t new_edge(std::int32_t a, std::int32_t b) {
    const std::int32_t h = num_halfedges();
    he_to_.insert(he_to_.end(), {b, a});
    he_next_.insert(he_next_.end(), {invalid, invalid});
    he_prev_.insert(he_prev_.end(), {invalid, invalid});
    he_face_.insert(he_face_.end(), {invalid, invalid});
    e_dead_.push_back(0);
    return h;
  }
  std::int32_t new_face() {
    f_he_.push_back(invalid);
    f_dead_.push_back(0);
    return std::int32_t(f_he_.size()) - 1;
  }
  void link(std::int32_t h, std::int32_t n) {
    he_next_[h] = n;
    he_prev_[n] = h;
  }
  void link_face(std::int32_t f, std::int32_t h0, std::int32_t h1, std::int32_t h2) {
    link(h0, h1);
    link(h1, h2);
    link(h2, h0);
    he_face_[h0] = he_face_[h1] = he_face_[h2] = f;
    f_he_[f] = h0;
  }
  // Half-edge g takes the place of half-edge o (same head, next, prev, face).
  void replace(std::int32_t o, std::int32_t g) {
    he_to_[g] = he_to_[o];
    he_face_[g] = he_face_[o];
    const std::int32_t n = he_next_[o], p = he_prev_[o];
    link(p, g);
    link(g, n);
    if (he_face_[g] != invalid && f_he_[he_face_[g]] == o) f_he_[he_face_[g]] = g;
  }
  void delete_edge(std::int32_t e) {
    e_dead_[e] = 1;
    ++dead_e_;
  }
  void delete_face(std::int32_t f) {
    f_dead_[f] = 1;
    ++dead_f_;
  }
  void delete_vertex(std::int32_t v) {
    v_dead_[v] = 1;
    v_he_[v] = invalid;
    ++dead_v_;
  }
  // Points v's outgoing half-edge at a boundary one when v has one.
  void prefer_boundary(std::int32_t v) {
    std::int32_t b = invalid;
    for_each_outgoing(v, [&](std::int32_t h) {
      if (he_face_[h] == invalid) b = h;
    });
    if (b != invalid) v_he_[v] = b;
  }

  std::vector<Vec3> pos_;
  std::vector<std::int32_t> v_he_;
  std::vector<std::uint8_t> v_dead_;
  std::vector<std::int32_t> he_to_, he_next_, he_prev_, he_face_;
  std::vector<std::uint8_t> e_dead_;
  std::vector<std::int32_t> f_he_;
  std::vector<std::uint8_t> f_dead_;
  std::int32_t dead_v_ = 0, dead_e_ = 0, dead_f_ = 0;
  mutable std::vector<std::uint32_t> mark_;  // scratch of can_collapse
  mutable std::uint32_t stamp_ = 0;
};

}  // namespace difftrans::geometry
