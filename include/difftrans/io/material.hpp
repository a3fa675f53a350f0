// Materials of transparent objects on disk: material.json (IoR and absorption:
// none, homogeneous RGB or a grid file) and the absorption-grid file format.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <string>

#include "difftrans/io/json.hpp"
#include "difftrans/io/presets.hpp"

namespace difftrans::io {

// material.json, as synth writes it into gt/ and relight reads it:
//   {"ior": 1.45, "absorption": {"type": "none"}}
//   {"ior": 1.45, "absorption": {"type": "homogeneous", "sigma": [4.0, 0.4, 4.0]}}
//   {"ior": 1.60, "absorption": {"type": "grid", "file": "absorption_grid.json",
//                                "procedural": "free text, how the grid was made"}}
// "absorption" may also be absent or null (none) or a bare [r, g, b] array
// (homogeneous). sigma is per unit length in the scene's frame; a grid file's
// path is relative to the material file.
//
// Absorption-grid file (JSON, e.g. absorption_grid.json):
//   {"format": "difftrans-absorption-grid", "res": [nx, ny, nz],
//    "lo": [x0, y0, z0], "hi": [x1, y1, z1], "sigma": [nx·ny·nz·3 numbers]}
// sigma holds RGB per grid vertex, vertex (i, j, k) at lo + (i, j, k)(hi − lo)
// / (res − 1), flat index ((k·ny + j)·nx + i)·3 + channel (x fastest); values
// finite and >= 0; each res >= 2. Between vertices sigma is trilinear; outside
// the box it is 0 (scene/absorption.hpp).

enum class AbsorptionType { none, homogeneous, grid };

inline const char* to_string(AbsorptionType t) {
  return t == AbsorptionType::none ? "none" : t == AbsorptionType::homogeneous ? "homogeneous" : "grid";
}

struct Material {
  double ior = 1.5;
  AbsorptionType absorption = AbsorptionType::none;
  Vec3f sigma{0.0f};      // homogeneous
  AbsorptionGrid grid;    // grid
  std::string grid_file;  // grid: the file name written into / read from material.json
  std::string procedural; // grid: optional description
};

inline constexpr const char* absorption_grid_format = "difftrans-absorption-grid";

// Largest grid accepted from a file (vertices), so a typo cannot allocate gigabytes.
inline constexpr std::size_t max_grid_vertices = std::size_t(512) * 512 * 512;

namespace detail {

// Three numbers under `key`, each finite and within the range of the float that stores it.
inline Vec3f read_vec3(const JsonReader& r, const std::string& key) {
  const Json& v = r.at(key);
  if (!v.is_array() || v.size() != 3) r.fail(key, "expected 3 numbers, found " + json_excerpt(v));
  Vec3f out;
  for (int c = 0; c < 3; ++c) out[c] = r.as_float(v[size_t(c)], r.field(key) + "[" + std::to_string(c) + "]");
  return out;
}

inline void require_sigma(const JsonReader& r, const std::string& key, const Vec3f& s) {
  for (int c = 0; c < 3; ++c)
    if (!(s[c] >= 0.0f)) r.fail(key, "absorption must be >= 0, found " + std::to_string(s[c]));
}

inline std::string number_text(double x) {
  char b[32];
  std::snprintf(b, sizeof(b), "%g", x);
  return b;
}
inline std::string rgb_text(const Vec3f& c) {
  return "(" + number_text(c.x) + ", " + number_text(c.y) + ", " + number_text(c.z) + ")";
}

}  // namespace detail

inline AbsorptionGrid parse_absorption_grid(const Json& json, const std::filesystem::path& file) {
  const JsonReader top(json, file);
  top.require_object();
  const std::string format = top.string("format", absorption_grid_format);
  if (format != absorption_grid_format)
    top.fail("format", detail::excerpt(format) + " is not \"" + absorption_grid_format + "\"");
  AbsorptionGrid g;
  const Json& res = top.at("res");
  if (!res.is_array() || res.size() != 3) top.fail("res", "expected 3 integers [nx, ny, nz], found " + json_excerpt(res));
  for (int a = 0; a < 3; ++a) {
    const Json& v = res[size_t(a)];
    if (!v.is_number_integer() || v.get<long long>() < 2 || v.get<long long>() > 4096)
      top.fail("res", "each resolution must be an integer in [2, 4096], found " + json_excerpt(v));
    g.res[a] = int(v.get<long long>());
  }
  if (g.vertex_count() > max_grid_vertices)
    top.fail("res", std::to_string(g.vertex_count()) + " vertices is more than the limit " +
                        std::to_string(max_grid_vertices));
  g.lo = detail::read_vec3(top, "lo");
  g.hi = detail::read_vec3(top, "hi");
  if (!(g.lo.x < g.hi.x && g.lo.y < g.hi.y && g.lo.z < g.hi.z))
    top.fail("hi", "the box's upper corner must lie above \"lo\" on every axis");
  const Json& sigma = top.at("sigma");
  const std::size_t expected = g.vertex_count() * 3;
  if (!sigma.is_array() || sigma.size() != expected)
    top.fail("sigma", "expected an array of " + std::to_string(expected) + " numbers (res " + std::to_string(g.res.x) +
                          " x " + std::to_string(g.res.y) + " x " + std::to_string(g.res.z) + " x RGB), found " +
                          (sigma.is_array() ? std::to_string(sigma.size()) + " elements" : std::string(sigma.type_name())));
  g.sigma.resize(expected);
  for (std::size_t i = 0; i < expected; ++i) {
    const Json& v = sigma[i];
    const double x = v.is_number() ? v.get<double>() : std::nan("");
    // stored as float: a finite double beyond FLT_MAX would become infinity
    if (!std::isfinite(x) || x < 0.0 || x > double(std::numeric_limits<float>::max()))
      top.fail("sigma", "element " + std::to_string(i) + " (vertex " + std::to_string(i / 3) + ", channel " +
                            std::to_string(i % 3) + ") must be a number in [0, 3.4e38] (the range of the float that "
                            "stores it), found " + json_excerpt(v));
    g.sigma[i] = float(x);
  }
  return g;
}

inline AbsorptionGrid read_absorption_grid(const std::filesystem::path& path) {
  return parse_absorption_grid(read_json(path), path);
}

inline void write_absorption_grid(const std::filesystem::path& path, const AbsorptionGrid& g) {
  if (g.sigma.size() != g.vertex_count() * 3)
    throw Error(path, "cannot write an absorption grid whose values (" + std::to_string(g.sigma.size()) +
                          ") do not match its resolution");
  Json json = Json::object();
  json["format"] = absorption_grid_format;
  json["res"] = {g.res.x, g.res.y, g.res.z};
  json["lo"] = {g.lo.x, g.lo.y, g.lo.z};
  json["hi"] = {g.hi.x, g.hi.y, g.hi.z};
  json["sigma"] = g.sigma;
  write_json(path, json, -1);  // compact: the array is long
}

inline Material read_material(const std::filesystem::path& path) {
  const Json json = read_json(path);
  const JsonReader top(json, path);
  top.require_object();
  Material m;
  m.ior = top.number("ior");
  if (!(m.ior >= 1.0 && m.ior <= 4.0)) top.fail("ior", "must lie in [1, 4], found " + std::to_string(m.ior));
  if (!top.has("absorption")) return m;
  const Json& a = top.at("absorption");
  if (a.is_array()) {
    m.absorption = AbsorptionType::homogeneous;
    m.sigma = detail::read_vec3(top, "absorption");
    detail::require_sigma(top, "absorption", m.sigma);
    return m;
  }
  const JsonReader ar = top.child("absorption");
  ar.require_object();
  const std::string type = ar.string("type");
  if (type == "none") {
    m.absorption = AbsorptionType::none;
  } else if (type == "homogeneous") {
    m.absorption = AbsorptionType::homogeneous;
    m.sigma = detail::read_vec3(ar, "sigma");
    detail::require_sigma(ar, "sigma", m.sigma);
  } else if (type == "grid") {
    m.absorption = AbsorptionType::grid;
    m.grid_file = ar.string("file");
    m.procedural = ar.string("procedural", "");
    const std::filesystem::path grid_path = std::filesystem::path(m.grid_file).is_absolute()
                                                ? std::filesystem::path(m.grid_file)
                                                : path.parent_path() / m.grid_file;
    try {
      m.grid = read_absorption_grid(grid_path);
    } catch (const Error& e) {  // say which file named it
      throw Error(e.file(), e.reason() + " (the absorption grid that " + path.string() + " names)", e.line());
    }
  } else {
    ar.fail("type", detail::excerpt(type) + " is none of \"none\", \"homogeneous\", \"grid\"");
  }
  return m;
}

// Writes material.json; a grid material also writes its grid next to it
// (file name m.grid_file, "absorption_grid.json" when empty).
inline void write_material(const std::filesystem::path& path, const Material& m) {
  Json json = Json::object();
  json["ior"] = m.ior;
  Json a = Json::object();
  a["type"] = to_string(m.absorption);
  if (m.absorption == AbsorptionType::homogeneous) a["sigma"] = {m.sigma.x, m.sigma.y, m.sigma.z};
  if (m.absorption == AbsorptionType::grid) {
    const std::string name = m.grid_file.empty() ? "absorption_grid.json" : m.grid_file;
    a["file"] = name;
    if (!m.procedural.empty()) a["procedural"] = m.procedural;
    write_absorption_grid(path.parent_path() / name, m.grid);
  }
  json["absorption"] = a;
  write_json(path, json);
}

// The material of a preset (the bands field sampled by bands_absorption_grid).
inline Material preset_material(const Preset& p) {
  Material m;
  m.ior = p.ior;
  switch (p.absorption) {
    case AbsorptionModel::none: break;
    case AbsorptionModel::homogeneous:
      m.absorption = AbsorptionType::homogeneous;
      m.sigma = p.sigma;
      break;
    case AbsorptionModel::bands:
      m.absorption = AbsorptionType::grid;
      m.grid = bands_absorption_grid(p.bands);
      m.grid_file = "absorption_grid.json";
      m.procedural = "bands: sigma = " + detail::rgb_text(p.bands.below) + " below y = " +
                     detail::number_text(p.bands.centre) + ", " + detail::rgb_text(p.bands.above) +
                     " above, smooth step of width " + detail::number_text(p.bands.width);
      break;
  }
  return m;
}

}  // namespace difftrans::io
