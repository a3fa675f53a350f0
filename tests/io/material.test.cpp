// material.json and absorption-grid files: round trips of each absorption
// type, the preset materials, and bad files with errors naming file and field.
#include <doctest/doctest.h>

#include "difftrans/io/material.hpp"
#include "io/fixtures.hpp"

namespace io = difftrans::io;
using difftrans::Vec3f;
using difftrans::Vec3i;
using namespace dt_test;

TEST_CASE("material round trip: none, homogeneous, grid") {
  TempDir dir;
  io::Material none;
  none.ior = 1.33;
  io::write_material(dir / "none.json", none);
  const auto a = io::read_material(dir / "none.json");
  CHECK(a.ior == 1.33);
  CHECK(a.absorption == io::AbsorptionType::none);

  io::Material homo;
  homo.ior = 1.45;
  homo.absorption = io::AbsorptionType::homogeneous;
  homo.sigma = Vec3f(4.0f, 0.4f, 4.0f);
  io::write_material(dir / "homo.json", homo);
  const auto b = io::read_material(dir / "homo.json");
  CHECK(b.absorption == io::AbsorptionType::homogeneous);
  CHECK(b.sigma == homo.sigma);

  const io::Material grid = io::preset_material(io::find_preset("monkey-bands"));
  CHECK(grid.absorption == io::AbsorptionType::grid);
  io::write_material(dir / "grid.json", grid);
  CHECK(fs::exists(dir / "absorption_grid.json"));
  const auto c = io::read_material(dir / "grid.json");
  CHECK(c.ior == doctest::Approx(1.6));
  CHECK(c.absorption == io::AbsorptionType::grid);
  CHECK(c.grid.res == grid.grid.res);
  CHECK(c.grid.lo == grid.grid.lo);
  CHECK(c.grid.hi == grid.grid.hi);
  CHECK(c.grid.sigma == grid.grid.sigma);
  CHECK(c.procedural.find("bands") != std::string::npos);
}

TEST_CASE("material: shorthand forms") {
  TempDir dir;
  write_text(dir / "a.json", R"({"ior": 1.5, "absorption": [1, 2, 3]})");
  const auto a = io::read_material(dir / "a.json");
  CHECK(a.absorption == io::AbsorptionType::homogeneous);
  CHECK(a.sigma == Vec3f(1.0f, 2.0f, 3.0f));
  write_text(dir / "b.json", R"({"ior": 1.5})");
  CHECK(io::read_material(dir / "b.json").absorption == io::AbsorptionType::none);
  write_text(dir / "c.json", R"({"ior": 1.5, "absorption": null})");
  CHECK(io::read_material(dir / "c.json").absorption == io::AbsorptionType::none);
}

TEST_CASE("material: bad files name the file and the field") {
  TempDir dir;
  const auto msg = [&](const std::string& text, const std::string& name = "m.json") {
    write_text(dir / name, text);
    return error_of([&] { io::read_material(dir / name); });
  };
  CHECK(msg(R"({"absorption": [1, 2, 3]})").find("ior: missing") != std::string::npos);
  CHECK(msg(R"({"ior": 0.5})").find("ior: must lie in [1, 4]") != std::string::npos);
  CHECK(msg(R"({"ior": 1.5, "absorption": [1, -2, 3]})").find(">= 0") != std::string::npos);
  CHECK(msg(R"({"ior": 1.5, "absorption": [1, 2]})").find("expected 3 numbers") != std::string::npos);
  CHECK(msg(R"({"ior": 1.5, "absorption": {"type": "fog"}})").find("absorption.type") != std::string::npos);
  CHECK(msg(R"({"ior": 1.5, "absorption": {"type": "grid", "file": "nope.json"}})").find("nope.json: file not found") !=
        std::string::npos);
  CHECK(msg(R"({"ior": 1.5,)").find("m.json:1: malformed JSON") != std::string::npos);
  // finite as a double, infinite as the float that stores it
  CHECK(msg(R"({"ior": 1.5, "absorption": [1, 1e39, 3]})") ==
        (dir / "m.json").string() + ": absorption[1]: 1e+39 is beyond the range of a float (magnitude at most 3.4e38), "
                                    "the type that stores it");
  CHECK(msg(R"({"ior": 1.5, "absorption": {"type": "homogeneous", "sigma": [1e39, 0, 0]}})")
            .find("absorption.sigma[0]: 1e+39 is beyond the range of a float") != std::string::npos);
  CHECK(error_of([&] { io::read_material(dir / "missing.json"); }).find("missing.json: file not found") !=
        std::string::npos);
}

TEST_CASE("absorption grid file: layout and bad grids") {
  TempDir dir;
  io::AbsorptionGrid g = io::sample_absorption_grid(Vec3i(3, 2, 2), Vec3f(-1.0f), Vec3f(1.0f),
                                                    [](const Vec3f& p) { return Vec3f(p.x + 1.0f, 2.0f, 3.0f); });
  io::write_absorption_grid(dir / "g.json", g);
  const io::Json j = io::read_json(dir / "g.json");
  CHECK(j["format"] == "difftrans-absorption-grid");
  CHECK(j["sigma"].size() == 3 * 2 * 2 * 3);
  // x runs fastest: the first three vertices are i = 0, 1, 2 at x = -1, 0, 1
  CHECK(j["sigma"][0].get<double>() == 0.0);
  CHECK(j["sigma"][3].get<double>() == 1.0);
  CHECK(j["sigma"][6].get<double>() == 2.0);
  CHECK(io::read_absorption_grid(dir / "g.json").sigma == g.sigma);

  const auto msg = [&](const std::string& text) {
    write_text(dir / "bad.json", text);
    return error_of([&] { io::read_absorption_grid(dir / "bad.json"); });
  };
  CHECK(msg(R"({"res": [2, 2], "lo": [0,0,0], "hi": [1,1,1], "sigma": []})").find("bad.json: res:") != std::string::npos);
  CHECK(msg(R"({"res": [2, 1, 2], "lo": [0,0,0], "hi": [1,1,1], "sigma": []})").find("[2, 4096]") != std::string::npos);
  CHECK(msg(R"({"res": [2, 2, 2], "lo": [0,0,0], "hi": [1,0,1], "sigma": []})").find("hi:") != std::string::npos);
  CHECK(msg(R"({"res": [2, 2, 2], "lo": [0,0,0], "hi": [1,1,1], "sigma": [1, 2]})").find("24 numbers") !=
        std::string::npos);
  std::string values = "[";
  for (int i = 0; i < 24; ++i) values += (i ? "," : "") + std::string(i == 7 ? "-1" : "0.5");
  values += "]";
  CHECK(msg(R"({"res": [2, 2, 2], "lo": [0,0,0], "hi": [1,1,1], "sigma": )" + values + "}").find("element 7") !=
        std::string::npos);
  CHECK(msg(R"({"format": "voxels", "res": [2, 2, 2]})").find("format:") != std::string::npos);
  // beyond the range of the float that stores it: a value, a corner
  std::string huge = "[";
  for (int i = 0; i < 24; ++i) huge += (i ? "," : "") + std::string(i == 5 ? "1e39" : "0.5");
  huge += "]";
  CHECK(msg(R"({"res": [2, 2, 2], "lo": [0,0,0], "hi": [1,1,1], "sigma": )" + huge + "}") ==
        (dir / "bad.json").string() + ": sigma: element 5 (vertex 1, channel 2) must be a number in [0, 3.4e38] (the "
                                      "range of the float that stores it), found 1e+39");
  CHECK(msg(R"({"res": [2, 2, 2], "lo": [0,-1e39,0], "hi": [1,1,1], "sigma": []})").find("bad.json: lo[1]: -1e+39 is beyond") !=
        std::string::npos);
}
