// OBJ: reading (polygons fanned, errors and warnings with line numbers) and writing.
#include "difftrans/io/obj.hpp"

#include <cmath>
#include <string>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("OBJ: triangles, a quad and a pentagon are fan-triangulated; groups keep file order") {
  TempDir dir;
  const auto path = dir / "poly.obj";
  write_text(path,
             "# comment\nmtllib none.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\nvn 0 0 1\n"
             "o first\nf 1 2 3\ng second\nf 1/1/1 2//1 3 4\nf -5 -4 -3 5 -2\n");
  std::vector<std::string> warnings;
  const io::Mesh m = io::read_obj(path, &warnings);
  REQUIRE(m.positions.size() == 5);
  CHECK(m.positions[4] == difftrans::Vec3f(0.5f, 1.5f, 0.0f));
  REQUIRE(m.triangles.size() == 1 + 2 + 3);
  CHECK(m.triangles[0] == difftrans::Vec3i(0, 1, 2));
  CHECK(m.triangles[1] == difftrans::Vec3i(0, 1, 2));
  CHECK(m.triangles[2] == difftrans::Vec3i(0, 2, 3));
  CHECK(m.triangles[3] == difftrans::Vec3i(0, 1, 2));
  CHECK(m.triangles[4] == difftrans::Vec3i(0, 2, 4));
  CHECK(m.triangles[5] == difftrans::Vec3i(0, 4, 3));
  // an open, overlapping fan: warnings, located by line
  const auto w = joined(warnings);
  CHECK(contains(w, "non-manifold edge(s)"));
  CHECK(contains(w, "face on line 12"));
}

TEST_CASE("OBJ: bad input gives an Error with file and line") {
  TempDir dir;
  const auto bad = [&](const std::string& text) {
    const auto path = dir / "bad.obj";
    write_text(path, text);
    return error_of([&] { io::read_obj(path); });
  };
  const std::string f = (dir / "bad.obj").string();
  CHECK(bad("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n") == f + ":3: vertex coordinate 'nan' is not a finite number");
  CHECK(bad("v 0 0 0\nv 1 0 inf\n") == f + ":2: vertex coordinate 'inf' is not a finite number");
  CHECK(bad("v 0 0 1e39\n") == f + ":1: vertex coordinate '1e39' is not a finite number");  // beyond float
  CHECK(bad("v 0 abc 0\n") == f + ":1: vertex coordinate 'abc' is not a number");
  CHECK(bad("v 0 0\n") == f + ":1: vertex needs 3 coordinates, found 2");
  CHECK(bad("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 7\n") == f + ":5: face vertex index 7 is out of range: the file has 3 vertices");
  CHECK(bad("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n") == f + ":4: face vertex index 0 (OBJ indices start at 1)");
  CHECK(bad("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n") ==
        f + ":4: relative face vertex index -4 is out of range: only 3 vertices so far");
  CHECK(bad("v 0 0 0\nf 1 x 1\n") == f + ":2: face vertex 'x' is not an index");
  // found by scripts/fuzz.sh: indices beyond long used to negate LONG_MIN (undefined behaviour)
  CHECK(bad("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -66666666666666666666666661 -2 -3\n") ==
        f + ":4: face vertex index '-66666666666666666666666661' is out of range");
  CHECK(bad("v 0 0 0\nf 99999999999999999999999/2 1 1\n") == f + ":2: face vertex index '99999999999999999999999' is out of range");
  CHECK(error_of([&] { io::read_obj(dir / "missing.obj"); }) == (dir / "missing.obj").string() + ": file not found");
}

TEST_CASE("OBJ: a face of 256 or more vertices is refused at its line; 255 are read in full") {
  TempDir dir;
  // a convex polygon of n vertices on the unit circle, after a triangle
  const auto polygon = [&](int n) {
    std::string text = "v 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\n";
    for (int i = 0; i < n; ++i) {
      const double a = 2.0 * 3.14159265358979 * i / n;
      text += "v " + std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0\n";
    }
    text += "f";
    for (int i = 0; i < n; ++i) text += " " + std::to_string(4 + i);
    const auto path = dir / "polygon.obj";
    write_text(path, text + "\n");
    return path;
  };
  const io::Mesh m = io::read_obj(polygon(255));
  CHECK(m.triangles.size() == 1 + 253);  // the whole fan: each vertex of the polygon is used
  CHECK(m.triangles.back() == difftrans::Vec3i(3, 3 + 253, 3 + 254));
  for (const int n : {256, 300, 1000}) {
    const auto path = polygon(n);
    CHECK(error_of([&] { io::read_obj(path); }) ==
          path.string() + ":" + std::to_string(4 + n + 1) + ": face with " + std::to_string(n) +
              " vertices: at most 255 are read (tinyobjloader keeps a face's vertex count in one byte); split the "
              "polygon into triangles");
  }
}

TEST_CASE("OBJ: short and degenerate faces are warnings with lines") {
  TempDir dir;
  const auto path = dir / "warn.obj";
  write_text(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2\nf 1 2 3\nf 1 2 4\n");
  std::vector<std::string> warnings;
  const io::Mesh m = io::read_obj(path, &warnings);
  CHECK(m.triangles.size() == 2);
  const auto w = joined(warnings);
  CHECK(contains(w, path.string() + ": 1 face(s) with fewer than 3 vertices ignored, on line(s) 5"));
  CHECK(contains(w, "face on line 7 (vertices 0, 1, 3): zero area"));
  // a file with vertices only
  write_text(path, "v 0 0 0\n");
  warnings.clear();
  io::read_obj(path, &warnings);
  CHECK(contains(joined(warnings), path.string() + ": no faces"));
}

TEST_CASE("OBJ: write then read gives the same mesh bit for bit") {
  TempDir dir;
  auto m = uv_sphere(0.37, 7, 9, {0.1, -2.0, 3.3});
  m.positions[3].x = 1.0f / 3.0f;  // a float that needs 9 digits
  io::write_obj(dir / "s.obj", m);
  std::vector<std::string> warnings;
  const io::Mesh back = io::read_obj(dir / "s.obj", &warnings);
  CHECK(warnings.empty());
  CHECK(back.positions == m.positions);
  CHECK(back.triangles == m.triangles);
  CHECK(contains(error_of([&] { io::write_obj(dir / "no/dir/s.obj", m); }), "cannot open for writing"));
}
