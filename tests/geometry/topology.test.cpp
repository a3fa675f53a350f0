// Mesh topology: vertex -> faces, edges with their faces, triangles across
// edges, components and genus, dropping small components.
#include <doctest/doctest.h>

#include <cstdint>
#include <vector>

#include "difftrans/geometry/topology.hpp"

namespace dg = difftrans::geometry;

namespace {
// A tetrahedron (closed, genus 0) and, apart from it, one lone triangle.
const std::vector<std::int32_t> tetra = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
}  // namespace

TEST_CASE("topology: vertex -> faces lists each face once per vertex, collapsed faces once") {
  const std::vector<std::int32_t> tris = {0, 1, 2, 2, 1, 2};  // the second face names vertex 2 twice
  const dg::VertexFaces vf = dg::vertex_faces(tris.data(), 2, 3);
  CHECK(vf.offsets == std::vector<std::int32_t>{0, 1, 3, 5});
  CHECK(vf.faces == std::vector<std::int32_t>{0, 0, 1, 0, 1});
  CHECK(vf.corners[4] == 0);  // vertex 2 in face 1: its first corner
}

TEST_CASE("topology: neighbours, adjacency, genus of a closed tetrahedron") {
  const dg::TriangleNeighbors nb = dg::TriangleNeighbors::build(tetra.data(), 4);
  for (std::int32_t a : nb.across) CHECK(a >= 0);
  const dg::MeshAdjacency adj = dg::mesh_adjacency(tetra, 4);
  CHECK(adj.num_edges() == 6);
  for (std::uint8_t b : adj.boundary) CHECK(b == 0);
  const dg::MeshGenus g = dg::mesh_genus(tetra, 4);
  CHECK(g.closed);
  CHECK(g.euler == 2);
  CHECK(g.genus == 0);
  CHECK(g.components == 1);
}

TEST_CASE("topology: a lone small triangle is dropped, the tetrahedron kept") {
  std::vector<std::int32_t> tris = tetra;
  tris.insert(tris.end(), {4, 5, 6});
  std::vector<float> pos(3 * 8, 0.0f);  // vertex 7 is used by nothing
  for (std::size_t i = 0; i < pos.size(); ++i) pos[i] = float(i);
  CHECK(dg::mesh_genus(tris, 8).components == 2);
  const int dropped = dg::drop_small_components(pos, tris, 0.5f);
  CHECK(dropped == 1);
  CHECK(tris.size() == tetra.size());
  CHECK(pos.size() == 12);
  CHECK(pos[3] == 6.0f);  // renumbered in order of first use: vertex 2 comes second
}

TEST_CASE("topology: union-find joins what unite() joins") {
  dg::UnionFind uf(5);
  uf.unite(0, 1);
  uf.unite(3, 4);
  uf.unite(1, 4);
  CHECK(uf.find(0) == uf.find(3));
  CHECK(uf.find(2) != uf.find(0));
}
