// Radiance-field files (the near-field environment that `difftrans
// reconstruct` writes): a small JSON description and a raw float32 file.
//
//   radiance_field.json
//     {"format": "difftrans-radiance-field", "version": 1,
//      "res": [nx, ny, nz], "lo": [x0, y0, z0], "hi": [x1, y1, z1],
//      "density_scale": s, "step_voxels": 0.5, "min_transmittance": 0.001,
//      "occupancy_sigma": 0.003, "background": [r, g, b],
//      "values": "radiance_field.f32"}
//   radiance_field.f32   nx·ny·nz·4 little-endian IEEE float32: at vertex
//     (i, j, k), offset ((k·ny + j)·nx + i)·4, the raw density and the raw
//     red, green, blue; σ = s·softplus(raw density) per unit length, colour =
//     softplus(raw colour), trilinear between vertices
//     (scene/radiance_field.hpp); "values" is relative to the JSON file.
// Empty cells (σ < occupancy_sigma at all 8 corners) are recomputed on load.
#pragma once

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

#include "difftrans/io/json.hpp"
#include "difftrans/scene/radiance_field.hpp"

namespace difftrans::io {

inline constexpr const char* radiance_field_format = "difftrans-radiance-field";

inline void write_radiance_field(const std::filesystem::path& json_path, const scene::RadianceField& f,
                                 float occupancy_sigma) {
  f.check();
  const std::filesystem::path raw = json_path.stem().string() + ".f32";
  static_assert(sizeof(float) == 4, "float32 expected");
  detail::write_file_bytes(json_path.parent_path() / raw, f.values.data(), f.values.size() * sizeof(float));
  Json j = Json::object();
  j["format"] = radiance_field_format;
  j["version"] = 1;
  j["res"] = {f.res.x, f.res.y, f.res.z};
  j["lo"] = {f.lo.x, f.lo.y, f.lo.z};
  j["hi"] = {f.hi.x, f.hi.y, f.hi.z};
  j["density_scale"] = f.density_scale;
  j["step_voxels"] = f.step_voxels;
  j["min_transmittance"] = f.min_transmittance;
  j["occupancy_sigma"] = occupancy_sigma;
  j["background"] = {f.background.x, f.background.y, f.background.z};
  j["values"] = raw.string();
  write_json(json_path, j);
}

inline scene::RadianceField read_radiance_field(const std::filesystem::path& json_path) {
  const Json json = read_json(json_path);
  const JsonReader top(json, json_path);
  top.require_object();
  const std::string format = top.string("format");
  if (format != radiance_field_format)
    top.fail("format", detail::excerpt(format) + " is not \"" + std::string(radiance_field_format) + "\"");
  // three finite numbers under `key`, within the range of a float
  const auto read3 = [&](const std::string& key) {
    const Json& a = top.at(key);
    if (!a.is_array() || a.size() != 3) top.fail(key, "expected an array of three numbers, found " + json_excerpt(a));
    float v[3];
    for (std::size_t i = 0; i < 3; ++i) v[i] = top.as_float(a[i], top.field(key) + "[" + std::to_string(i) + "]");
    return Vec3f(v[0], v[1], v[2]);
  };
  scene::RadianceField f;
  const Vec3f res = read3("res");
  for (int a = 0; a < 3; ++a) {
    if (res[a] != std::floor(res[a]) || res[a] < 2 || res[a] > 4096)
      top.fail("res", "expected three integers in [2, 4096], found " + json_excerpt(top.at("res")));
    f.res[a] = int(res[a]);
  }
  f.lo = read3("lo");
  f.hi = read3("hi");
  f.background = read3("background");
  for (int a = 0; a < 3; ++a) {
    if (!(f.hi[a] > f.lo[a])) top.fail("hi", "must exceed lo on every axis");
    if (!(f.background[a] >= 0.0f)) top.fail("background", "must be >= 0");
  }
  f.density_scale = top.float_number("density_scale");
  f.step_voxels = top.float_number("step_voxels");
  f.min_transmittance = top.float_number("min_transmittance", 1e-3f);
  const float occupancy_sigma = top.float_number("occupancy_sigma", 0.0f);
  if (!(f.density_scale > 0.0f)) top.fail("density_scale", "must be > 0");
  if (!(f.step_voxels > 0.0f)) top.fail("step_voxels", "must be > 0");
  if (!(f.min_transmittance >= 0.0f && f.min_transmittance < 1.0f)) top.fail("min_transmittance", "must lie in [0, 1)");
  const std::filesystem::path raw = json_path.parent_path() / top.string("values");
  std::string bytes;
  try {
    bytes = detail::read_file_text(raw);
  } catch (const Error& e) {  // say which file named it
    throw Error(raw, e.reason() + " (the \"values\" of " + json_path.string() + ")");
  }
  const std::size_t want = f.vertex_count() * 4 * sizeof(float);
  if (bytes.size() != want)
    throw Error(raw, "holds " + std::to_string(bytes.size()) + " bytes; res " + std::to_string(f.res.x) + " x " +
                         std::to_string(f.res.y) + " x " + std::to_string(f.res.z) + " in " + json_path.string() +
                         " needs " + std::to_string(want));
  f.values.resize(f.vertex_count() * 4);
  std::memcpy(f.values.data(), bytes.data(), want);
  for (std::size_t i = 0; i < f.values.size(); ++i)
    if (!std::isfinite(f.values[i]))
      throw Error(raw, "value " + std::to_string(i) + " is not finite");
  f.update_occupancy(occupancy_sigma);
  return f;
}

}  // namespace difftrans::io
