// Mesh quality: dihedral angles, genus and self-intersections on meshes whose
// answers are known — a box (12 edges at 90°, 6 face diagonals at 0°),
// icospheres (the angle falls as they are refined), two boxes that overlap
// (their faces cross) or lie apart (nothing crosses), a dented sphere.
#include "difftrans/metrics/mesh_quality.hpp"

#include <doctest/doctest.h>

#include <cmath>

#include "support/shapes.hpp"

using difftrans::metrics::mesh_quality;
using difftrans::metrics::MeshQuality;
using dt_test::Shape;

namespace {

// Two shapes in one mesh, the second moved by (dx, dy, dz).
Shape combined(const Shape& a, const Shape& b, float dx, float dy, float dz) {
  Shape s = a;
  const std::int32_t offset = std::int32_t(a.positions.size() / 3);
  for (std::size_t i = 0; i < b.positions.size(); i += 3) {
    s.positions.push_back(b.positions[i] + dx);
    s.positions.push_back(b.positions[i + 1] + dy);
    s.positions.push_back(b.positions[i + 2] + dz);
  }
  for (std::int32_t v : b.triangles) s.triangles.push_back(v + offset);
  return s;
}

}  // namespace

TEST_CASE("a box: 12 edges at 90 degrees, 6 diagonals at 0, closed, genus 0, no crossing") {
  const Shape box = dt_test::make_box(0.5f, 0.3f, 0.2f);
  const MeshQuality q = mesh_quality(box.positions, box.triangles);
  CHECK(q.interior_edges == 18);
  CHECK(q.mean_dihedral_degrees == doctest::Approx(12.0 * 90.0 / 18.0));
  CHECK(q.max_dihedral_degrees == doctest::Approx(90.0));
  CHECK(q.closed);
  CHECK(q.genus == 0);
  CHECK(q.components == 1);
  CHECK(q.self_intersections == 0);
}

TEST_CASE("icospheres: finer is smoother; a dent raises the mean angle") {
  const Shape coarse = dt_test::make_icosphere(0.5f, 1), fine = dt_test::make_icosphere(0.5f, 3);
  const MeshQuality qc = mesh_quality(coarse.positions, coarse.triangles);
  const MeshQuality qf = mesh_quality(fine.positions, fine.triangles);
  CHECK(qf.mean_dihedral_degrees < 0.5 * qc.mean_dihedral_degrees);
  CHECK(qf.self_intersections == 0);
  CHECK(qf.genus == 0);
  // speckle: every 7th vertex pushed out by 3 % of the radius
  Shape noisy = fine;
  for (std::size_t v = 0; v < noisy.positions.size() / 3; v += 7)
    for (int c = 0; c < 3; ++c) noisy.positions[3 * v + std::size_t(c)] *= 1.03f;
  const MeshQuality qn = mesh_quality(noisy.positions, noisy.triangles);
  CHECK(qn.mean_dihedral_degrees > 1.5 * qf.mean_dihedral_degrees);
  CHECK(qn.self_intersections == 0);
}

TEST_CASE("self-intersections: two boxes that overlap cross, two apart do not") {
  const Shape box = dt_test::make_box(0.5f, 0.5f, 0.5f);
  const Shape apart = combined(box, box, 2.0f, 0.0f, 0.0f);
  const MeshQuality qa = mesh_quality(apart.positions, apart.triangles);
  CHECK(qa.self_intersections == 0);
  CHECK(qa.components == 2);
  const Shape overlapping = combined(box, box, 0.5f, 0.25f, 0.125f);
  const MeshQuality qo = mesh_quality(overlapping.positions, overlapping.triangles);
  CHECK(qo.self_intersections > 0);
  // a vertex pushed through the opposite face of a box folds the surface through itself
  Shape folded = box;
  folded.positions[0] = 0.9f;  // corner (−0.5, −0.5, −0.5) moved to x = 0.9, past the face x = 0.5
  const MeshQuality qf = mesh_quality(folded.positions, folded.triangles);
  CHECK(qf.self_intersections > 0);
}
