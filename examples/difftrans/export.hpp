// difftrans export: what is exported (mesh, material, environment, cameras),
// the absorption as one RGB coefficient for formats that hold no grid, the
// glTF attenuation that reproduces it, and the writers of each format
// (export.cpp, export_gltf.cpp, export_mitsuba.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "views.hpp"

namespace difftrans::cli {

// The object to export and where each piece came from (for messages and records).
struct ExportInput {
  io::Mesh mesh;
  std::filesystem::path mesh_source;
  io::Material material;
  std::string material_source;      // a file, or a description ("default: ...")
  std::optional<Environment> env;   // mitsuba only
  std::vector<io::Frame> cameras;   // mitsuba only: the sensors
  std::filesystem::path scene;      // where the cameras came from (empty: none)
  int max_depth = 16;               // surface interactions per path, as difftrans render --max-depth
  int spp = 256;                    // mitsuba: samples per pixel
  std::string mesh_format = "ply";  // mitsuba: the mesh file beside the XML (ply or obj)
};

// The absorption as one RGB coefficient per unit length: homogeneous sigma as
// it is; a grid's mean over the object's volume (its trilinear sigma at the
// points of an n^3 lattice over the mesh's box that lie inside the mesh; the
// mean over its vertices when no point does).
inline constexpr int absorption_samples_per_axis = 48;

struct AbsorptionSummary {
  std::string type = "none";  // of the material: none, homogeneous, grid
  Vec3d sigma{0.0};
  std::string how;               // how sigma was obtained, for the files and stderr
  std::size_t samples_used = 0;  // grid: lattice points inside the mesh
  std::size_t samples_total = 0;
  bool absorbing() const { return sigma.x > 0.0 || sigma.y > 0.0 || sigma.z > 0.0; }
};

AbsorptionSummary summarize_absorption(const io::Mesh& mesh, const io::Material& material);

// Unit vertex normals as the renderer shades with them (scene::TriangleMesh:
// the normalized sum of the unit normals of the faces around each vertex);
// +Y for a vertex no face with an area uses.
std::vector<Vec3f> export_vertex_normals(const io::Mesh& mesh);

// glTF's KHR_materials_volume attenuation: the coefficient of channel c is
// -ln(color_c) / distance. distance is the object's size (the longest side
// of its box), shortened where needed so that no colour falls below e^-20;
// then color_c = exp(-sigma_c · distance) gives back sigma_c exactly up to
// rounding. No absorption: no attenuation (infinite distance, colour 1).
struct GltfAttenuation {
  Vec3d color{1.0};
  double distance = 0.0;  // 0: infinite (attenuation omitted)
};

inline GltfAttenuation gltf_attenuation(const Vec3d& sigma, double object_size) {
  GltfAttenuation a;
  const double largest = std::max(sigma.x, std::max(sigma.y, sigma.z));
  if (!(largest > 0.0)) return a;
  constexpr double max_optical_depth = 20.0;
  a.distance = object_size > 0.0 ? std::min(object_size, max_optical_depth / largest) : 1.0 / largest;
  for (int c = 0; c < 3; ++c) a.color[c] = std::exp(-sigma[c] * a.distance);
  return a;
}

// Writes the object as a binary glTF 2.0 file; returns its record.
io::Json write_gltf(const ExportInput& in, const AbsorptionSummary& absorption, const std::filesystem::path& file);

// Writes a Mitsuba 3 scene into `dir` (scene.xml, the mesh, the environment);
// returns its record.
io::Json write_mitsuba(const ExportInput& in, const AbsorptionSummary& absorption, const std::filesystem::path& dir);

}  // namespace difftrans::cli
