// read_mesh / write_mesh pick the format by extension; the shared meshes load clean.
#include "difftrans/io/mesh_file.hpp"

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("round trip through both formats by extension") {
  TempDir dir;
  const auto m = uv_sphere(0.5, 5, 8);
  for (const char* name : {"a.obj", "b.PLY"}) {
    io::write_mesh(dir / name, m);
    const io::Mesh back = io::read_mesh(dir / name);
    CHECK(back.positions == m.positions);
    CHECK(back.triangles == m.triangles);
  }
  CHECK(error_of([&] { io::write_mesh(dir / "c.stl", m); }) ==
        (dir / "c.stl").string() + ": unsupported mesh format '.stl' (expected .obj or .ply)");
  CHECK(error_of([&] { io::read_mesh(dir / "noext"); }) ==
        (dir / "noext").string() + ": unsupported mesh format '' (expected .obj or .ply)");
}

TEST_CASE("the shared meshes are closed 2-manifolds: read without warnings") {
  for (const char* name : {"spot", "bunny"}) {
    const fs::path path = fs::path(DIFFTRANS_DATA_DIR) / "meshes" / (std::string(name) + ".obj");
    if (!fs::exists(path)) {
      MESSAGE("skipped: " << path << " not present");
      continue;
    }
    std::vector<std::string> warnings;
    const io::Mesh m = io::read_mesh(path, &warnings);
    CHECK(joined(warnings) == "");
    CHECK(m.triangles.size() > 1000);
    CHECK(m.triangles.size() + 4 == 2 * m.positions.size());  // closed, genus 0: F = 2V - 4
  }
}
