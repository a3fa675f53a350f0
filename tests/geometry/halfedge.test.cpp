// Half-edge mesh: building and validation (non-manifold edges and vertices
// reported), hand-checked split / flip / collapse, the link condition, and
// random sequences of operations on an icosphere, a torus and an open patch
// with every invariant re-checked after every step, both through the
// structure and independently through the flat arrays it writes back.
#include "difftrans/geometry/halfedge.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <vector>

#include "support/shapes.hpp"

using difftrans::geometry::HalfEdgeMesh;
using difftrans::geometry::HalfEdgeReport;
using Vec3 = HalfEdgeMesh::Vec3;

namespace dt_test {

// An open n × n grid on the unit square (one boundary loop).
inline Shape make_patch(int n) {
  Shape s;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) s.positions.insert(s.positions.end(), {float(i) / n, float(j) / n, 0.0f});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      for (int k : {a, b, c, a, c, d}) s.triangles.push_back(k);
    }
  return s;
}

}  // namespace dt_test

namespace {

HalfEdgeMesh build(const dt_test::Shape& s) {
  HalfEdgeReport rep;
  HalfEdgeMesh m = HalfEdgeMesh::from_triangles(s.positions, s.triangles, &rep);
  REQUIRE(rep.ok());
  return m;
}

// Invariants read through the public accessors.
int structural_errors(const HalfEdgeMesh& m) {
  int bad = 0;
  for (int h = 0; h < m.num_halfedges(); ++h) {
    if (m.edge_deleted(HalfEdgeMesh::edge(h))) continue;
    bad += HalfEdgeMesh::twin(HalfEdgeMesh::twin(h)) != h;
    bad += m.next(m.prev(h)) != h || m.prev(m.next(h)) != h;
    bad += m.from(m.next(h)) != m.to(h);
    bad += m.to(HalfEdgeMesh::twin(h)) != m.from(h);
    bad += m.face(m.next(h)) != m.face(h);
    if (m.face(h) >= 0) bad += m.next(m.next(m.next(h))) != h || m.face_deleted(m.face(h));
  }
  for (int f = 0; f < m.num_faces(); ++f) {
    if (m.face_deleted(f)) continue;
    const int h = m.face_halfedge(f);
    for (int k = 0, g = h; k < 3; ++k, g = m.next(g)) bad += m.face(g) != f;
  }
  for (int v = 0; v < m.num_vertices(); ++v) {
    if (m.vertex_deleted(v)) continue;
    m.for_each_outgoing(v, [&](int h) { bad += m.from(h) != v; });
  }
  return bad;
}

// Independent of the structure: the flat arrays it writes. Every undirected
// edge has one or two triangles and, with two, opposite orientations; each
// vertex's triangles form one fan. Returns false on any violation; euler
// receives V − E + F and boundary_edges the edges with one triangle.
bool flat_manifold(const std::vector<float>& pos, const std::vector<std::int32_t>& tris, int& euler,
                   int& boundary_edges) {
  std::map<std::pair<int, int>, int> directed;
  for (std::size_t f = 0; f < tris.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = tris[3 * f + k], b = tris[3 * f + (k + 1) % 3];
      if (a == b) return false;
      if (++directed[{a, b}] > 1) return false;
    }
  std::set<std::pair<int, int>> edges;
  boundary_edges = 0;
  for (const auto& [e, n] : directed) {
    edges.insert({std::min(e.first, e.second), std::max(e.first, e.second)});
    if (!directed.count({e.second, e.first})) ++boundary_edges;
  }
  const int nv = int(pos.size() / 3);
  // fans: around each vertex, the map "incoming neighbour -> outgoing neighbour"
  // of its triangles must be one chain or cycle
  std::vector<std::map<int, int>> fan(static_cast<std::size_t>(nv));
  for (std::size_t f = 0; f < tris.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) fan[std::size_t(tris[3 * f + k])][tris[3 * f + (k + 1) % 3]] = tris[3 * f + (k + 2) % 3];
  for (int v = 0; v < nv; ++v) {
    const auto& next = fan[std::size_t(v)];
    if (next.empty()) return false;  // an unused vertex
    int start = next.begin()->first;
    // on a boundary, start where the chain begins (a key nobody maps to)
    std::set<int> targets;
    for (const auto& kv : next) targets.insert(kv.second);
    int starts = 0;
    for (const auto& kv : next)
      if (!targets.count(kv.first)) {
        start = kv.first;
        ++starts;
      }
    if (starts > 1) return false;
    std::size_t steps = 0;
    int w = start;
    while (next.count(w) && steps <= next.size()) {
      w = next.at(w);
      ++steps;
      if (w == start) break;
    }
    if (steps != next.size()) return false;
  }
  euler = nv - int(edges.size()) + int(tris.size() / 3);
  return true;
}

void check_all(const HalfEdgeMesh& m, int euler, const char* what) {
  INFO(what);
  CHECK(m.validate() == "");
  CHECK(structural_errors(m) == 0);
  CHECK(m.euler_characteristic() == euler);
  std::vector<float> p;
  std::vector<std::int32_t> t;
  m.to_arrays(p, t);
  int e = 0, b = 0;
  CHECK(flat_manifold(p, t, e, b));
  CHECK(e == euler);
}

// Random splits, flips and collapses; after each, every invariant.
void random_operations(HalfEdgeMesh& m, unsigned seed, int steps) {
  std::mt19937 rng(seed);
  const int euler = m.euler_characteristic();
  int splits = 0, flips = 0, collapses = 0, refused = 0;
  for (int s = 0; s < steps; ++s) {
    const int e = int(rng() % unsigned(m.num_edges()));
    if (m.edge_deleted(e)) continue;
    const int op = int(rng() % 3);
    const int h = HalfEdgeMesh::halfedge(e, int(rng() % 2));
    if (op == 0) {
      const int nv = m.num_live_vertices(), nf = m.num_live_faces();
      const int v = m.split_edge(e, 0.5f * (m.position(m.from(h)) + m.position(m.to(h))));
      CHECK(m.num_live_vertices() == nv + 1);
      CHECK(m.num_live_faces() == nf + (m.is_boundary_vertex(v) ? 1 : 2));
      CHECK(m.valence(v) == (m.is_boundary_vertex(v) ? 3 : 4));
      ++splits;
    } else if (op == 1) {
      if (!m.can_flip(e)) {
        ++refused;
        continue;
      }
      const int a = m.from(h), b = m.to(h), c = m.to(m.next(h)), d = m.to(m.next(HalfEdgeMesh::twin(h)));
      const int va = m.valence(a), vb = m.valence(b), vc = m.valence(c), vd = m.valence(d);
      m.flip_edge(e);
      CHECK(m.valence(a) == va - 1);
      CHECK(m.valence(b) == vb - 1);
      CHECK(m.valence(c) == vc + 1);
      CHECK(m.valence(d) == vd + 1);
      CHECK(m.find_halfedge(a, b) == -1);
      CHECK(m.find_halfedge(c, d) != -1);
      ++flips;
    } else {
      if (!m.can_collapse(h)) {
        ++refused;
        continue;
      }
      const int a = m.from(h), b = m.to(h);
      const int nv = m.num_live_vertices();
      std::set<int> ring;
      m.for_each_neighbor(a, [&](int w) { ring.insert(w); });
      m.for_each_neighbor(b, [&](int w) { ring.insert(w); });
      ring.erase(a);
      ring.erase(b);
      const Vec3 mid = 0.5f * (m.position(a) + m.position(b));
      CHECK(m.collapse_edge(h, mid) == b);
      CHECK(m.vertex_deleted(a));
      CHECK(m.num_live_vertices() == nv - 1);
      std::set<int> after;
      m.for_each_neighbor(b, [&](int w) { after.insert(w); });
      CHECK(after == ring);  // b's neighbours: the union of both rings
      ++collapses;
    }
    CHECK(m.validate() == "");
    CHECK(structural_errors(m) == 0);
    CHECK(m.euler_characteristic() == euler);
    if (s % 25 == 0) check_all(m, euler, "during the sequence");
  }
  MESSAGE("splits " << splits << ", flips " << flips << ", collapses " << collapses << ", refused " << refused);
  CHECK(splits > 10);
  CHECK(flips > 10);
  CHECK(collapses > 10);
  check_all(m, euler, "after the sequence");
  // compaction keeps the mesh and its numbering agrees with to_arrays
  std::vector<float> p0, p1;
  std::vector<std::int32_t> t0, t1;
  m.to_arrays(p0, t0);
  m.compact();
  check_all(m, euler, "after compact");
  CHECK(m.num_vertices() == m.num_live_vertices());
  CHECK(m.num_faces() == m.num_live_faces());
  m.to_arrays(p1, t1);
  CHECK(p0 == p1);
  CHECK(t0 == t1);
  // and the flat arrays build again
  HalfEdgeReport rep;
  HalfEdgeMesh again = HalfEdgeMesh::from_triangles(p1, t1, &rep);
  CHECK(rep.ok());
  CHECK(again.euler_characteristic() == euler);
}

}  // namespace

TEST_CASE("building: counts, boundary, one-rings") {
  const dt_test::Shape ico = dt_test::make_icosphere(1.0f, 1);
  HalfEdgeMesh m = build(ico);
  CHECK(m.num_live_vertices() == 42);
  CHECK(m.num_live_edges() == 120);
  CHECK(m.num_live_faces() == 80);
  CHECK(m.euler_characteristic() == 2);
  int v5 = 0, v6 = 0;
  for (int v = 0; v < m.num_vertices(); ++v) {
    CHECK_FALSE(m.is_boundary_vertex(v));
    v5 += m.valence(v) == 5;
    v6 += m.valence(v) == 6;
  }
  CHECK(v5 == 12);
  CHECK(v6 == 30);
  check_all(m, 2, "icosphere");

  const dt_test::Shape patch = dt_test::make_patch(4);
  HalfEdgeMesh p = build(patch);
  CHECK(p.euler_characteristic() == 1);
  int boundary_vertices = 0, boundary_edges = 0;
  for (int v = 0; v < p.num_vertices(); ++v) boundary_vertices += p.is_boundary_vertex(v);
  for (int e = 0; e < p.num_edges(); ++e) boundary_edges += p.is_boundary_edge(e);
  CHECK(boundary_vertices == 16);
  CHECK(boundary_edges == 16);
  CHECK(p.valence(0) == 3);   // corner with the diagonal
  CHECK(p.valence(4) == 2);   // corner without
  CHECK(p.valence(12) == 6);  // interior
  check_all(p, 1, "patch");

  HalfEdgeMesh t = build(dt_test::make_torus(12, 8));
  CHECK(t.euler_characteristic() == 0);
  check_all(t, 0, "torus");
}

TEST_CASE("validation reports non-manifold input") {
  HalfEdgeReport rep;
  // three triangles on the edge 0-1
  const std::vector<float> p(3 * 5, 0.0f);
  HalfEdgeMesh::from_triangles(p, {0, 1, 2, 1, 0, 3, 0, 1, 4}, &rep);
  CHECK_FALSE(rep.ok());
  REQUIRE(rep.nonmanifold_edges.size() == 1);
  CHECK(rep.nonmanifold_edges[0] == std::make_pair(0, 1));
  // inconsistent orientation: two faces run 0→1
  HalfEdgeMesh::from_triangles(p, {0, 1, 2, 0, 1, 3}, &rep);
  CHECK(rep.nonmanifold_edges.size() == 1);
  // a bow tie: two triangles sharing only vertex 0
  HalfEdgeMesh::from_triangles(p, {0, 1, 2, 0, 3, 4}, &rep);
  CHECK(rep.nonmanifold_edges.empty());
  CHECK(rep.nonmanifold_vertices == std::vector<std::int32_t>{0});
  // two closed tetrahedra sharing one vertex: a pinch with no boundary
  std::vector<float> q(3 * 7, 0.0f);
  const std::vector<std::int32_t> two = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3, 0, 5, 4, 0, 4, 6, 0, 6, 5, 4, 5, 6};
  HalfEdgeMesh::from_triangles(q, two, &rep);
  CHECK(rep.nonmanifold_vertices == std::vector<std::int32_t>{0});
  // degenerate and out-of-range triangles
  HalfEdgeMesh::from_triangles(p, {0, 1, 1, 0, 1, 9}, &rep);
  CHECK(rep.bad_triangles == std::vector<std::int32_t>{0, 1});
  // and a good closed mesh passes
  const dt_test::Shape box = dt_test::make_box(1, 1, 1);
  HalfEdgeMesh::from_triangles(box.positions, box.triangles, &rep);
  CHECK(rep.ok());
}

TEST_CASE("split, flip and collapse by hand") {
  const dt_test::Shape box = dt_test::make_box(1, 1, 1);
  HalfEdgeMesh m = build(box);
  const int e = HalfEdgeMesh::edge(m.find_halfedge(0, 2));
  const int v = m.split_edge(e, Vec3(-1, 0, -1));
  CHECK(m.num_live_vertices() == 9);
  CHECK(m.num_live_edges() == 21);
  CHECK(m.num_live_faces() == 14);
  CHECK(m.valence(v) == 4);
  CHECK(m.find_halfedge(0, 2) == -1);
  CHECK(m.find_halfedge(v, 0) != -1);
  CHECK(m.find_halfedge(2, v) != -1);
  check_all(m, 2, "box after a split");
  // the new triangles keep the outward orientation: normals point away from the centre
  for (int f = 0; f < m.num_faces(); ++f) {
    int vs[3];
    m.face_vertices(f, vs);
    const Vec3 c = (m.position(vs[0]) + m.position(vs[1]) + m.position(vs[2])) / 3.0f;
    CHECK(glm::dot(m.face_area_normal(f), c) > 0.0f);
  }

  // flip the diagonal of the box face 0 2 3 1: 0-3 becomes 2-1
  HalfEdgeMesh b = build(box);
  const int d = HalfEdgeMesh::edge(b.find_halfedge(0, 3));
  REQUIRE(b.can_flip(d));
  b.flip_edge(d);
  CHECK(b.find_halfedge(0, 3) == -1);
  CHECK(b.find_halfedge(1, 2) != -1);
  check_all(b, 2, "box after a flip");
  for (int f = 0; f < b.num_faces(); ++f) CHECK(glm::dot(b.face_area_normal(f), b.position(b.to(b.face_halfedge(f)))) > 0.0f);
  // a boundary edge cannot flip
  HalfEdgeMesh p = build(dt_test::make_patch(2));
  CHECK_FALSE(p.can_flip(HalfEdgeMesh::edge(p.find_halfedge(0, 1))));
}

TEST_CASE("collapse: the link condition") {
  // a triangular bipyramid: apexes 3 (top) and 4, equator 0 1 2
  const std::vector<float> p = {1, 0, 0, -0.5f, 0.87f, 0, -0.5f, -0.87f, 0, 0, 0, 1, 0, 0, -1};
  const std::vector<std::int32_t> t = {0, 1, 3, 1, 2, 3, 2, 0, 3, 1, 0, 4, 2, 1, 4, 0, 2, 4};
  HalfEdgeMesh m = HalfEdgeMesh::from_triangles(p, t);
  check_all(m, 2, "bipyramid");
  // an equator edge: 0 and 1 share 2, which is not opposite the edge -> refused
  CHECK_FALSE(m.can_collapse(m.find_halfedge(0, 1)));
  CHECK_FALSE(m.can_collapse(m.find_halfedge(1, 0)));
  // apex to equator: allowed, leaves a tetrahedron
  const int h = m.find_halfedge(3, 0);
  REQUIRE(m.can_collapse(h));
  m.collapse_edge(h, m.position(0));
  check_all(m, 2, "tetrahedron");
  CHECK(m.num_live_vertices() == 4);
  // a tetrahedron collapses no further
  for (int g = 0; g < m.num_halfedges(); ++g)
    if (!m.edge_deleted(HalfEdgeMesh::edge(g))) CHECK_FALSE(m.can_collapse(g));

  // on a patch, an interior edge between two boundary vertices is refused
  HalfEdgeMesh q = build(dt_test::make_patch(2));
  // vertices 1 (bottom middle) and 3 (left middle): not joined; 1-4 joins boundary 1 and interior 4
  CHECK(q.can_collapse(q.find_halfedge(4, 1)));
  const int across = q.find_halfedge(0, 4);  // diagonal from corner 0 (boundary) to 4 (interior): fine
  CHECK(q.can_collapse(across));
  // vertex 1 and 5 are both on the boundary? 5 is the right middle: not joined to 1; use 1-2? boundary edge: fine
  CHECK(q.can_collapse(q.find_halfedge(1, 2)));
  // the normal check: moving 4 far off the plane flips faces
  CHECK_FALSE(q.collapse_flips_normals(q.find_halfedge(4, 1), q.position(1)));
  CHECK(q.collapse_flips_normals(q.find_halfedge(4, 1), Vec3(3, 3, 0)));
}

TEST_CASE("random operations keep every invariant: icosphere") {
  HalfEdgeMesh m = build(dt_test::make_icosphere(1.0f, 2));
  random_operations(m, 1, 600);
}

TEST_CASE("random operations keep every invariant: torus (genus 1)") {
  HalfEdgeMesh m = build(dt_test::make_torus(16, 10));
  random_operations(m, 2, 600);
  CHECK(m.euler_characteristic() == 0);
}

TEST_CASE("random operations keep every invariant: open patch (boundary)") {
  HalfEdgeMesh m = build(dt_test::make_patch(8));
  random_operations(m, 3, 600);
  CHECK(m.euler_characteristic() == 1);
}

TEST_CASE("collapsing as far as possible stays manifold") {
  for (unsigned seed : {4u, 5u}) {
    HalfEdgeMesh m = build(seed == 4 ? dt_test::make_icosphere(1.0f, 2) : dt_test::make_torus(10, 8));
    const int euler = m.euler_characteristic();
    std::mt19937 rng(seed);
    for (int round = 0; round < 20; ++round)
      for (int h = 0; h < m.num_halfedges(); ++h) {
        const int g = int(rng() % unsigned(m.num_halfedges()));
        if (m.can_collapse(g)) m.collapse_edge(g, m.position(m.to(g)));
      }
    check_all(m, euler, "collapsed");
    MESSAGE("collapsed down to " << m.num_live_vertices() << " vertices");
    CHECK(m.num_live_vertices() < 12);
  }
}
