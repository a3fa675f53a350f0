// Radiance-field files: written and read back bit for bit (with the occupancy
// recomputed); bad files are refused with the file and field named.
#include "support/ad_check.hpp"

#include <filesystem>

#include "difftrans/io/radiance_field.hpp"

using namespace dt_test;
namespace sc = difftrans::scene;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("difftrans_test_radiance_field_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

sc::RadianceField small_field() {
  sc::RadianceField f(Vec3i(3, 4, 2), Vec3f(-1.0f, -2.0f, -0.5f), Vec3f(1.0f, 2.0f, 0.5f), -2.0f, 0.5f);
  for (std::size_t i = 0; i < f.values.size(); ++i) f.values[i] = 0.25f * float(i % 13) - 1.5f;
  f.density_scale = 7.5f;
  f.step_voxels = 0.4f;
  f.min_transmittance = 0.002f;
  f.background = Vec3f(0.1f, 0.2f, 0.3f);
  return f;
}

std::string error_of(const fs::path& p) {
  try {
    (void)difftrans::io::read_radiance_field(p);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("radiance field file: round trip") {
  const fs::path d = temp_dir("roundtrip");
  const sc::RadianceField f = small_field();
  difftrans::io::write_radiance_field(d / "field.json", f, 0.5f);
  CHECK(fs::exists(d / "field.f32"));
  CHECK(fs::file_size(d / "field.f32") == f.values.size() * 4);
  const sc::RadianceField g = difftrans::io::read_radiance_field(d / "field.json");
  CHECK(g.res == f.res);
  CHECK(g.lo == f.lo);
  CHECK(g.hi == f.hi);
  CHECK(g.density_scale == f.density_scale);
  CHECK(g.step_voxels == f.step_voxels);
  CHECK(g.min_transmittance == f.min_transmittance);
  CHECK(g.background == f.background);
  CHECK(g.values == f.values);
  sc::RadianceField h = f;
  h.update_occupancy(0.5f);
  CHECK(g.occupancy == h.occupancy);
  fs::remove_all(d);
}

TEST_CASE("radiance field file: bad input names the file and the field") {
  const fs::path d = temp_dir("bad");
  const sc::RadianceField f = small_field();
  difftrans::io::write_radiance_field(d / "field.json", f, 0.0f);
  const difftrans::io::Json good = difftrans::io::read_json(d / "field.json");
  const auto variant = [&](const std::string& key, const difftrans::io::Json& value) {
    difftrans::io::Json j = good;
    j[key] = value;
    difftrans::io::write_json(d / "bad.json", j);
    return error_of(d / "bad.json");
  };
  CHECK(error_of(d / "missing.json").find("file not found") != std::string::npos);
  CHECK(variant("format", "something-else").find("format") != std::string::npos);
  CHECK(variant("res", {3, 4}).find("res") != std::string::npos);
  CHECK(variant("res", {3, 4, 1}).find("res") != std::string::npos);
  CHECK(variant("res", {3, 5, 2}).find("needs") != std::string::npos);  // the raw file is too short for it
  CHECK(variant("hi", {1.0, -3.0, 0.5}).find("hi") != std::string::npos);
  CHECK(variant("density_scale", -1.0).find("density_scale") != std::string::npos);
  CHECK(variant("background", {0.1, "x", 0.3}).find("background") != std::string::npos);
  // finite doubles that a float cannot hold
  CHECK(variant("hi", {1.0, 1e39, 0.5}).find("bad.json: hi[1]: 1e+39 is beyond the range of a float") != std::string::npos);
  CHECK(variant("density_scale", 1e39).find("bad.json: density_scale: 1e+39 is beyond the range of a float") !=
        std::string::npos);
  CHECK(variant("occupancy_sigma", 1e39).find("occupancy_sigma: 1e+39 is beyond") != std::string::npos);
  CHECK(variant("values", "absent.f32").find("absent.f32: file not found") != std::string::npos);
  // a non-finite value in the raw file
  std::vector<float> raw = f.values;
  raw[5] = std::numeric_limits<float>::quiet_NaN();
  difftrans::io::detail::write_file_bytes(d / "field.f32", raw.data(), raw.size() * 4);
  CHECK(error_of(d / "field.json").find("value 5 is not finite") != std::string::npos);
  fs::remove_all(d);
}
