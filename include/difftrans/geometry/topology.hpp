// The combinatorics of triangle meshes, on index arrays only (3 vertex
// indices per triangle): union-find, the vertex -> faces index, undirected
// edges with their faces, the triangle across each edge, vertex one-rings,
// connected components, the Euler characteristic and genus, and dropping
// small components. Every mesh type of the library (scene::TriangleMesh, the
// FlexiCubes output, the remesher's input) builds its adjacency here.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

namespace difftrans::geometry {

// Disjoint sets over 0 .. n−1 with path halving; unite() makes the second
// root the parent of the first.
class UnionFind {
 public:
  explicit UnionFind(std::int32_t n) : parent_(std::size_t(std::max<std::int32_t>(n, 0))) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  std::int32_t find(std::int32_t v) {
    while (parent_[std::size_t(v)] != v) v = parent_[std::size_t(v)] = parent_[std::size_t(parent_[std::size_t(v)])];
    return v;
  }
  void unite(std::int32_t a, std::int32_t b) {
    a = find(a), b = find(b);
    if (a != b) parent_[std::size_t(a)] = b;
  }

 private:
  std::vector<std::int32_t> parent_;
};

// Vertex -> faces in compressed rows: the faces around vertex v are
// faces[offsets[v] .. offsets[v + 1]), in increasing face order, each with
// the corner (0, 1, 2) at which it names v. A face that names a vertex twice
// (collapsed) is listed once for it, at the first such corner.
struct VertexFaces {
  std::vector<std::int32_t> offsets;  // num_vertices + 1
  std::vector<std::int32_t> faces;
  std::vector<std::int8_t> corners;
};

inline VertexFaces vertex_faces(const std::int32_t* triangles, std::int32_t num_triangles, std::int32_t num_vertices) {
  VertexFaces vf;
  const std::size_t nv = std::size_t(std::max<std::int32_t>(num_vertices, 0));
  const auto listed = [&](std::int32_t f, int k) {  // the first corner of f naming this vertex
    const std::int32_t v = triangles[3 * std::size_t(f) + std::size_t(k)];
    return !(k > 0 && triangles[3 * std::size_t(f)] == v) && !(k > 1 && triangles[3 * std::size_t(f) + 1] == v);
  };
  vf.offsets.assign(nv + 1, 0);
  for (std::int32_t f = 0; f < num_triangles; ++f)
    for (int k = 0; k < 3; ++k)
      if (listed(f, k)) ++vf.offsets[std::size_t(triangles[3 * std::size_t(f) + std::size_t(k)]) + 1];
  for (std::size_t v = 0; v < nv; ++v) vf.offsets[v + 1] += vf.offsets[v];
  vf.faces.resize(std::size_t(vf.offsets[nv]));
  vf.corners.resize(vf.faces.size());
  std::vector<std::int32_t> fill(vf.offsets.begin(), vf.offsets.end() - 1);
  for (std::int32_t f = 0; f < num_triangles; ++f)
    for (int k = 0; k < 3; ++k) {
      if (!listed(f, k)) continue;
      const std::int32_t at = fill[std::size_t(triangles[3 * std::size_t(f) + std::size_t(k)])]++;
      vf.faces[std::size_t(at)] = f;
      vf.corners[std::size_t(at)] = std::int8_t(k);
    }
  return vf;
}

// Calls visit(a, b, slots, count) once per undirected edge {a, b} (a < b) in
// increasing (a, b) order, with the `count` triangle slots 3·face + k whose
// edge k (corners k and k + 1 mod 3) it is, in increasing order. Collapsed
// edges (a == b) are skipped.
template <class Visit>
void for_each_edge(const std::int32_t* triangles, std::int32_t num_triangles, Visit&& visit) {
  std::vector<std::pair<std::uint64_t, std::int32_t>> half;  // (key, slot)
  half.reserve(3 * std::size_t(std::max<std::int32_t>(num_triangles, 0)));
  for (std::int32_t t = 0; t < num_triangles; ++t)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = std::uint32_t(triangles[3 * std::size_t(t) + std::size_t(k)]);
      const std::uint32_t b = std::uint32_t(triangles[3 * std::size_t(t) + std::size_t((k + 1) % 3)]);
      if (a == b) continue;
      half.push_back({(std::uint64_t(std::min(a, b)) << 32) | std::uint64_t(std::max(a, b)), 3 * t + k});
    }
  std::sort(half.begin(), half.end());
  std::vector<std::int32_t> slots;
  for (std::size_t i = 0; i < half.size();) {
    std::size_t j = i;
    slots.clear();
    while (j < half.size() && half[j].first == half[i].first) slots.push_back(half[j++].second);
    visit(std::int32_t(half[i].first >> 32), std::int32_t(half[i].first & 0xffffffffu), slots.data(), int(slots.size()));
    i = j;
  }
}

// For every triangle edge k (vertices k and k+1 mod 3) the triangle across it:
// >= 0 the one other triangle sharing that (undirected) edge, -1 none (a
// boundary edge), -2 more than one (non-manifold: always a silhouette edge).
struct TriangleNeighbors {
  static constexpr std::int32_t boundary = -1, non_manifold = -2;
  std::vector<std::int32_t> across;  // 3 per triangle

  static TriangleNeighbors build(const std::int32_t* triangles, std::int32_t num_triangles) {
    TriangleNeighbors n;
    n.across.assign(std::size_t(3) * std::size_t(std::max<std::int32_t>(num_triangles, 0)), boundary);
    for_each_edge(triangles, num_triangles, [&](std::int32_t, std::int32_t, const std::int32_t* s, int count) {
      if (count == 2) {
        n.across[std::size_t(s[0])] = s[1] / 3;
        n.across[std::size_t(s[1])] = s[0] / 3;
      } else if (count > 2) {
        for (int k = 0; k < count; ++k) n.across[std::size_t(s[k])] = non_manifold;
      }
    });
    return n;
  }
  // Any mesh with `triangles` (3 indices each) and num_triangles().
  template <class Mesh>
  static TriangleNeighbors build(const Mesh& m) {
    return build(m.triangles.data(), m.num_triangles());
  }
};

// The adjacency the mesh regularizers and the genus need in one pass.
struct MeshAdjacency {
  std::int32_t num_vertices = 0;
  std::vector<std::int32_t> vf_offsets;    // vertex -> faces (VertexFaces), num_vertices + 1
  std::vector<std::int32_t> vf_faces;
  std::vector<std::int8_t> vf_corner;      // the vertex's corner (0, 1, 2) in that face
  std::vector<std::int32_t> edges;         // 2 per undirected edge, smaller index first
  std::vector<std::int32_t> edge_faces;    // 2 per edge: the two faces of an interior edge, else (first, -1)
  std::vector<std::int32_t> vv_offsets;    // vertex -> neighbours (CSR), num_vertices + 1
  std::vector<std::int32_t> vv_neighbors;
  std::vector<std::uint8_t> boundary;      // per vertex: 1 on a boundary or non-manifold edge

  std::int32_t num_edges() const { return std::int32_t(edges.size() / 2); }
};

inline MeshAdjacency mesh_adjacency(const std::vector<std::int32_t>& triangles, std::int32_t num_vertices) {
  MeshAdjacency adj;
  adj.num_vertices = num_vertices;
  const std::int32_t nt = std::int32_t(triangles.size() / 3);
  const std::size_t nv = std::size_t(num_vertices);
  VertexFaces vf = vertex_faces(triangles.data(), nt, num_vertices);
  adj.vf_offsets = std::move(vf.offsets);
  adj.vf_faces = std::move(vf.faces);
  adj.vf_corner = std::move(vf.corners);

  adj.boundary.assign(nv, 0);
  for_each_edge(triangles.data(), nt, [&](std::int32_t a, std::int32_t b, const std::int32_t* s, int count) {
    adj.edges.insert(adj.edges.end(), {a, b});
    const bool interior = count == 2;
    adj.edge_faces.insert(adj.edge_faces.end(), {s[0] / 3, interior ? s[1] / 3 : -1});
    if (!interior) adj.boundary[std::size_t(a)] = adj.boundary[std::size_t(b)] = 1;
  });

  // vertex -> neighbours from the edges
  adj.vv_offsets.assign(nv + 1, 0);
  for (std::int32_t v : adj.edges) ++adj.vv_offsets[std::size_t(v) + 1];
  for (std::size_t v = 0; v < nv; ++v) adj.vv_offsets[v + 1] += adj.vv_offsets[v];
  adj.vv_neighbors.resize(adj.edges.size());
  std::vector<std::int32_t> fill(adj.vv_offsets.begin(), adj.vv_offsets.end() - 1);
  for (std::size_t e = 0; e < adj.edges.size(); e += 2) {
    const std::int32_t a = adj.edges[e], b = adj.edges[e + 1];
    adj.vv_neighbors[std::size_t(fill[std::size_t(a)]++)] = b;
    adj.vv_neighbors[std::size_t(fill[std::size_t(b)]++)] = a;
  }
  return adj;
}

// The vertices joined by edges, as a union-find over all num_vertices.
inline UnionFind vertex_components(const std::vector<std::int32_t>& triangles, std::int32_t num_vertices) {
  UnionFind uf(num_vertices);
  for (std::size_t f = 0; f + 2 < triangles.size(); f += 3) {
    uf.unite(triangles[f], triangles[f + 1]);
    uf.unite(triangles[f + 1], triangles[f + 2]);
  }
  return uf;
}

struct MeshGenus {
  std::int32_t vertices = 0, edges = 0, faces = 0;  // vertices: those used by some face
  std::int32_t components = 0;
  std::int64_t euler = 0;                            // V − E + F
  std::int64_t genus = 0;                            // (2 C − χ) / 2: the total genus of closed components
  bool closed = true;                                // every edge shared by exactly two faces
};

inline MeshGenus mesh_genus(const std::vector<std::int32_t>& triangles, std::int32_t num_vertices) {
  MeshGenus g;
  const MeshAdjacency adj = mesh_adjacency(triangles, num_vertices);
  UnionFind uf = vertex_components(triangles, num_vertices);
  std::vector<std::uint8_t> used(static_cast<std::size_t>(num_vertices), 0);
  for (std::int32_t v : triangles) used[std::size_t(v)] = 1;
  for (std::int32_t v = 0; v < num_vertices; ++v)
    if (used[std::size_t(v)]) {
      ++g.vertices;
      if (uf.find(v) == v) ++g.components;
    }
  g.edges = adj.num_edges();
  g.faces = std::int32_t(triangles.size() / 3);
  for (std::int32_t e = 0; e < adj.num_edges(); ++e)
    if (adj.edge_faces[std::size_t(2 * e + 1)] < 0) g.closed = false;
  g.euler = std::int64_t(g.vertices) - g.edges + g.faces;
  g.genus = (2 * std::int64_t(g.components) - g.euler) / 2;
  return g;
}

// Drops the connected components with fewer than `min_fraction` of the
// largest component's triangles (floaters, bubbles the masks cannot see) and
// the vertices no triangle uses. Returns the number of components dropped.
inline int drop_small_components(std::vector<float>& positions, std::vector<std::int32_t>& triangles,
                                 float min_fraction = 0.05f) {
  const std::int32_t nv = std::int32_t(positions.size() / 3);
  UnionFind uf = vertex_components(triangles, nv);
  std::vector<std::int64_t> count(static_cast<std::size_t>(nv), 0);
  for (std::size_t f = 0; f + 2 < triangles.size(); f += 3) ++count[std::size_t(uf.find(triangles[f]))];
  const std::int64_t largest = count.empty() ? 0 : *std::max_element(count.begin(), count.end());
  const auto small = [&](std::int64_t c) { return double(c) < double(min_fraction) * double(largest); };
  int dropped = 0;
  for (std::int32_t v = 0; v < nv; ++v)
    if (uf.find(v) == v && count[std::size_t(v)] > 0 && small(count[std::size_t(v)])) ++dropped;
  std::vector<std::int32_t> remap(static_cast<std::size_t>(nv), -1), kept;
  std::vector<float> pos;
  for (std::size_t f = 0; f + 2 < triangles.size(); f += 3) {
    if (small(count[std::size_t(uf.find(triangles[f]))])) continue;
    for (int k = 0; k < 3; ++k) {
      const std::int32_t v = triangles[f + std::size_t(k)];
      if (remap[std::size_t(v)] < 0) {
        remap[std::size_t(v)] = std::int32_t(pos.size() / 3);
        pos.insert(pos.end(), positions.begin() + 3 * std::ptrdiff_t(v), positions.begin() + 3 * std::ptrdiff_t(v) + 3);
      }
      kept.push_back(remap[std::size_t(v)]);
    }
  }
  positions.swap(pos);
  triangles.swap(kept);
  return dropped;
}

}  // namespace difftrans::geometry
