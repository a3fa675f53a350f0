// Mesh validation (errors and located warnings) and the unit-box normalization.
#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
using difftrans::Vec3f;

TEST_CASE("a closed cube and a UV sphere pass without warnings") {
  CHECK(io::check_mesh(cube_mesh(), "cube").empty());
  CHECK(io::check_mesh(uv_sphere(1.0, 8, 12), "sphere").empty());
  CHECK(io::surface_area(cube_mesh()) == doctest::Approx(6.0));
}

TEST_CASE("out-of-range indices and non-finite vertices are errors") {
  auto m = cube_mesh();
  m.triangles[3].y = 8;
  CHECK(error_of([&] { io::check_mesh(m, "m.obj"); }) == "m.obj: triangle 3: vertex index 8 is out of range [0, 8)");
  m.triangles[3].y = -1;
  CHECK(contains(error_of([&] { io::check_mesh(m, "m.obj"); }), "vertex index -1 is out of range"));
  m = cube_mesh();
  m.positions[5].z = std::nanf("");
  const auto msg = error_of([&] { io::check_mesh(m, "m.obj"); });
  CHECK(contains(msg, "m.obj: vertex 5 has a non-finite coordinate"));
  m.positions[5].z = INFINITY;
  CHECK(contains(error_of([&] { io::check_mesh(m, "m.obj"); }), "vertex 5 has a non-finite"));
}

TEST_CASE("degenerate faces are warned about, with where") {
  auto m = cube_mesh();
  m.triangles.emplace_back(0, 0, 1);  // repeated vertex
  m.positions.emplace_back(0.5f, 0.0f, 0.0f);
  m.triangles.emplace_back(0, 8, 1);  // collinear: zero area
  const auto w = joined(io::check_mesh(m, "m.obj", [](int t) { return "face #" + std::to_string(t); }));
  CHECK(contains(w, "m.obj: 2 degenerate face(s)"));
  CHECK(contains(w, "face #12 (vertices 0, 0, 1): repeated vertex"));
  CHECK(contains(w, "face #13 (vertices 0, 8, 1): zero area"));
}

TEST_CASE("non-manifold, boundary and flipped edges are warned about") {
  auto m = cube_mesh();
  m.positions.emplace_back(0.5f, -1.0f, 0.5f);
  m.triangles.emplace_back(0, 1, 8);  // a fin on edge (0, 1): three faces share it
  auto w = joined(io::check_mesh(m, "fin.ply"));
  CHECK(contains(w, "fin.ply: 1 non-manifold edge(s): edge (0, 1) is shared by 3 faces"));
  CHECK(contains(w, "boundary edge(s)"));  // the fin's two other edges
  m = cube_mesh();
  m.triangles.pop_back();  // a hole
  w = joined(io::check_mesh(m, "open.obj"));
  CHECK(contains(w, "open.obj: 3 boundary edge(s), the mesh is not closed"));
  CHECK_FALSE(contains(w, "non-manifold"));
  m = cube_mesh();
  std::swap(m.triangles[0].y, m.triangles[0].z);  // one face turned over
  w = joined(io::check_mesh(m, "flip.obj"));
  CHECK(contains(w, "flip.obj: 3 edge(s) whose two faces have opposite orientation"));
  CHECK(contains(w, "triangle 0"));
}

TEST_CASE("warnings list a few places and count the rest") {
  io::Mesh m;
  m.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0)};
  for (int i = 0; i < 9; ++i) m.triangles.emplace_back(0, 1, 1);
  const auto w = joined(io::check_mesh(m, "d.obj"));
  CHECK(contains(w, "9 degenerate face(s)"));
  CHECK(contains(w, "(and 4 more)"));
  CHECK_FALSE(contains(w, "triangle 5 "));
}

TEST_CASE("normalize_to_unit_box: box centre to the origin, longest side 1, transform reusable") {
  auto m = cube_mesh();
  for (auto& p : m.positions) p = Vec3f(p.x * 4.0f + 1.0f, p.y * 2.0f - 3.0f, p.z + 10.0f);  // box [1,5]x[-3,-1]x[10,11]
  auto other = m;
  const io::UnitBoxTransform t = io::normalize_to_unit_box(m);
  CHECK(t.scale == doctest::Approx(0.25));
  CHECK(t.centre.x == doctest::Approx(3.0));
  CHECK(t.centre.y == doctest::Approx(-2.0));
  CHECK(t.centre.z == doctest::Approx(10.5));
  const io::Box box = io::bounding_box(m);
  CHECK(box.lo.x == doctest::Approx(-0.5));
  CHECK(box.hi.x == doctest::Approx(0.5));
  CHECK(box.lo.y == doctest::Approx(-0.25));
  CHECK(box.hi.z == doctest::Approx(0.125));
  // the same transform moves another mesh the same way, and inverts
  io::apply_transform(t, other);
  for (size_t i = 0; i < m.positions.size(); ++i) CHECK(other.positions[i] == m.positions[i]);
  const Vec3f back = t.invert(m.positions[7]);
  CHECK(back.x == doctest::Approx(5.0f));
  CHECK(back.z == doctest::Approx(11.0f));
  // unreferenced vertices do not count
  auto with_stray = cube_mesh();
  with_stray.positions.emplace_back(100.0f, 0.0f, 0.0f);
  CHECK(io::unit_box_transform(with_stray).scale == doctest::Approx(1.0));
  CHECK_THROWS_AS(io::unit_box_transform(io::Mesh{}), std::invalid_argument);
}
