// Procedural shapes of known topology: the voxel boundary is closed,
// consistently oriented and of the stated genus; its volume is the voxel count.
// The icosphere: closed, outward, genus 0, on its sphere, volume → 4/3 π r³.
#include "difftrans/geometry/procedural.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <map>
#include <utility>

#include "difftrans/geometry/topology.hpp"

namespace dg = difftrans::geometry;

namespace {

// Every directed edge once and its reverse once: closed and consistently oriented.
bool closed_and_oriented(const dg::ProceduralMesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (std::size_t f = 0; f + 2 < m.triangles.size(); f += 3)
    for (int k = 0; k < 3; ++k) ++directed[{m.triangles[f + k], m.triangles[f + (k + 1) % 3]}];
  for (const auto& [e, n] : directed) {
    if (n != 1) return false;
    const auto r = directed.find({e.second, e.first});
    if (r == directed.end() || r->second != 1) return false;
  }
  return true;
}

double signed_volume(const dg::ProceduralMesh& m) {
  double v = 0.0;
  for (std::size_t f = 0; f + 2 < m.triangles.size(); f += 3) {
    const float* a = &m.positions[3 * std::size_t(m.triangles[f])];
    const float* b = &m.positions[3 * std::size_t(m.triangles[f + 1])];
    const float* c = &m.positions[3 * std::size_t(m.triangles[f + 2])];
    v += (double(a[0]) * (double(b[1]) * c[2] - double(b[2]) * c[1]) - double(a[1]) * (double(b[0]) * c[2] - double(b[2]) * c[0]) +
          double(a[2]) * (double(b[0]) * c[1] - double(b[1]) * c[0])) / 6.0;
  }
  return v;
}

}  // namespace

TEST_CASE("block_with_holes: closed, oriented outward, genus N, volume = voxels") {
  for (int holes : {0, 1, 2, 5, 9}) {
    CAPTURE(holes);
    const dg::VoxelShape v = dg::block_with_holes(holes);
    CHECK(dg::voxel_shape_is_manifold(v));
    const dg::ProceduralMesh m = dg::voxel_boundary(v);
    CHECK(closed_and_oriented(m));
    const dg::MeshGenus g = dg::mesh_genus(m.triangles, std::int32_t(m.positions.size() / 3));
    CHECK(g.closed);
    CHECK(g.components == 1);
    CHECK(g.genus == holes);
    int voxels = 0;
    for (auto o : v.occupied) voxels += o;
    CHECK(signed_volume(m) == doctest::Approx(voxels));
  }
  // each voxel face cut into s x s quads: the same solid, s² times the triangles, vertices on the 1/s lattice
  for (int s : {2, 5}) {
    CAPTURE(s);
    const dg::VoxelShape v = dg::block_with_holes(3);
    const dg::ProceduralMesh coarse = dg::voxel_boundary(v), fine = dg::voxel_boundary(v, s);
    CHECK(fine.triangles.size() == coarse.triangles.size() * std::size_t(s * s));
    CHECK(closed_and_oriented(fine));
    const dg::MeshGenus g = dg::mesh_genus(fine.triangles, std::int32_t(fine.positions.size() / 3));
    CHECK(g.closed);
    CHECK(g.components == 1);
    CHECK(g.genus == 3);
    CHECK(signed_volume(fine) == doctest::Approx(signed_volume(coarse)));
    bool on_lattice = true;
    for (float x : fine.positions) on_lattice = on_lattice && std::abs(x * float(s) - std::round(x * float(s))) < 1e-4f;
    CHECK(on_lattice);
  }
  CHECK_THROWS_AS(dg::voxel_boundary(dg::block_with_holes(1), 0), std::invalid_argument);
  // other proportions
  const dg::ProceduralMesh thick = dg::voxel_boundary(dg::block_with_holes(3, 3, 2, 4));
  CHECK(dg::mesh_genus(thick.triangles, std::int32_t(thick.positions.size() / 3)).genus == 3);
  CHECK_THROWS_AS(dg::block_with_holes(2, 0), std::invalid_argument);
}

TEST_CASE("voxel shapes: edge and corner contacts are reported as non-manifold") {
  dg::VoxelShape v;
  v.nx = v.ny = v.nz = 2;
  v.occupied.assign(8, 0);
  v.occupied[0] = v.occupied[3] = 1;  // (0,0,0) and (1,1,0): an edge contact
  CHECK_FALSE(dg::voxel_shape_is_manifold(v));
  v.occupied.assign(8, 0);
  v.occupied[0] = v.occupied[7] = 1;  // opposite corners
  CHECK_FALSE(dg::voxel_shape_is_manifold(v));
  v.occupied[1] = 1;                 // (1,0,0) joins them through faces... and the edge (1,0,0)-(1,1,1) still only an edge
  CHECK_FALSE(dg::voxel_shape_is_manifold(v));
  v.occupied[5] = 1;                 // (1,0,1): now 0-1-5-7 is face-connected, no bare contacts left
  CHECK(dg::voxel_shape_is_manifold(v));
  v.occupied.assign(8, 1);
  CHECK(dg::voxel_shape_is_manifold(v));
}

TEST_CASE("icosphere: closed, outward, genus 0, vertices on the sphere, volume of the ball") {
  const double pi = 3.14159265358979323846;
  double last_gap = 1.0;
  for (int levels : {0, 1, 3, 5}) {
    CAPTURE(levels);
    const dg::ProceduralMesh m = dg::icosphere(0.5f, levels);
    const int nv = int(m.positions.size() / 3), nf = int(m.triangles.size() / 3);
    CHECK(nf == 20 * (1 << (2 * levels)));
    CHECK(nv == 10 * (1 << (2 * levels)) + 2);
    CHECK(closed_and_oriented(m));
    const dg::MeshGenus g = dg::mesh_genus(m.triangles, nv);
    CHECK(g.closed);
    CHECK(g.genus == 0);
    for (int i = 0; i < nv; ++i) {
      const float* q = &m.positions[3 * std::size_t(i)];
      CHECK(std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2]) == doctest::Approx(0.5).epsilon(1e-6));
    }
    // inscribed: below the ball's volume, closer at every level (the gap falls about 4x per level)
    const double gap = 1.0 - signed_volume(m) / (4.0 / 3.0 * pi * 0.125);
    CHECK(gap > 0.0);
    CHECK(gap < last_gap);
    last_gap = gap;
  }
  CHECK(last_gap < 2e-3);
  CHECK_THROWS_AS(dg::icosphere(1.0f, -1), std::invalid_argument);
}

TEST_CASE("procedural_shape by name") {
  const dg::ProceduralMesh m = dg::procedural_shape("holes-4");
  CHECK(dg::mesh_genus(m.triangles, std::int32_t(m.positions.size() / 3)).genus == 4);
  const dg::ProceduralMesh m3 = dg::procedural_shape("holes-4", 3);
  CHECK(m3.triangles.size() == 9u * m.triangles.size());
  CHECK(dg::mesh_genus(m3.triangles, std::int32_t(m3.positions.size() / 3)).genus == 4);
  const dg::ProceduralMesh sphere = dg::procedural_shape("sphere-2");
  CHECK(sphere.triangles.size() == 3u * 320u);
  CHECK_THROWS_WITH_AS(dg::procedural_shape("sphere-x"), doctest::Contains("'sphere-x'"), std::invalid_argument);
  CHECK_THROWS_WITH_AS(dg::procedural_shape("sphere-10"), doctest::Contains("'sphere-10'"), std::invalid_argument);
  CHECK_THROWS_WITH_AS(dg::procedural_shape("holes-"), doctest::Contains("'holes-'"), std::invalid_argument);
  CHECK_THROWS_WITH_AS(dg::procedural_shape("donut"), doctest::Contains("'donut'"), std::invalid_argument);
}
