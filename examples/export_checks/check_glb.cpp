// Test of difftrans export --format gltf: loads the .glb back with tinygltf and
// checks it against the mesh and material it was made from: the extensions,
// base colour / metallic / roughness / transmission, the IoR, an attenuation
// whose -ln(colour) / distance gives the absorption back (a grid's: a value
// between its smallest and largest, with extras saying it was averaged),
// vertex and triangle counts, positions, indices and unit normals.
// Prints "check_glb: ok" or the failures, and exits non-zero on any.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "difftrans/core/constants.hpp"
#include "difftrans/io/material.hpp"
#include "expected_material.hpp"
#include "difftrans/io/mesh_file.hpp"

namespace {

int failures = 0;

void expect(bool ok, const std::string& what) {
  if (!ok) {
    std::cerr << "check_glb: FAILED: " << what << std::endl;
    ++failures;
  }
}

bool close(double a, double b, double rel = 1e-6, double abs = 1e-9) {
  return std::abs(a - b) <= abs + rel * std::max(std::abs(a), std::abs(b));
}

const tinygltf::Value* member(const tinygltf::Value& v, const std::string& key) {
  if (!v.IsObject() || !v.Has(key)) return nullptr;
  return &v.Get(key);
}

double number_or(const tinygltf::Value* v, double fallback) {
  return v && v->IsNumber() ? v->GetNumberAsDouble() : fallback;
}

// The bytes of accessor `index` as T values (tightly packed views only, as export writes them).
template <class T>
std::vector<T> accessor_values(const tinygltf::Model& model, int index, int components) {
  const tinygltf::Accessor& a = model.accessors.at(std::size_t(index));
  const tinygltf::BufferView& view = model.bufferViews.at(std::size_t(a.bufferView));
  const tinygltf::Buffer& buffer = model.buffers.at(std::size_t(view.buffer));
  const std::size_t n = a.count * std::size_t(components);
  std::vector<T> out(n);
  const std::size_t offset = view.byteOffset + a.byteOffset;
  if (offset + n * sizeof(T) > buffer.data.size() || (view.byteStride != 0 && view.byteStride != components * sizeof(T))) {
    expect(false, "accessor " + std::to_string(index) + " does not fit its buffer");
    return {};
  }
  std::memcpy(out.data(), buffer.data.data() + offset, n * sizeof(T));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Checks a .glb written by difftrans export against its mesh and material"};
  std::string glb, mesh_path;
  app.add_option("glb", glb, "the exported .glb")->required();
  app.add_option("--mesh", mesh_path, "the mesh it was exported from")->required();
  difftrans::checks::ExpectedMaterial expected;
  expected.add(app);
  CLI11_PARSE(app, argc, argv);

  using namespace difftrans;
  const io::Mesh mesh = io::read_mesh(mesh_path);
  const io::Material material = expected.resolve();

  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warning;
  if (!loader.LoadBinaryFromFile(&model, &err, &warning, glb)) {
    std::cerr << "check_glb: FAILED: " << glb << ": tinygltf cannot load it: " << err << std::endl;
    return 1;
  }
  expect(warning.empty(), "tinygltf warns: " + warning);
  expect(model.asset.version == "2.0", "asset.version is '" + model.asset.version + "'");
  for (const char* ext : {"KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"})
    expect(std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), ext) != model.extensionsUsed.end(),
           std::string(ext) + " is not in extensionsUsed");

  // geometry
  expect(model.meshes.size() == 1 && model.meshes[0].primitives.size() == 1, "expected one mesh with one primitive");
  if (model.meshes.empty() || model.meshes[0].primitives.empty()) return 1;
  const tinygltf::Primitive& prim = model.meshes[0].primitives[0];
  expect(prim.mode == TINYGLTF_MODE_TRIANGLES, "primitive mode is not TRIANGLES");
  expect(prim.attributes.count("POSITION") && prim.attributes.count("NORMAL"), "POSITION or NORMAL missing");
  if (!prim.attributes.count("POSITION") || !prim.attributes.count("NORMAL") || prim.indices < 0) return 1;
  const tinygltf::Accessor& pa = model.accessors.at(std::size_t(prim.attributes.at("POSITION")));
  const tinygltf::Accessor& ia = model.accessors.at(std::size_t(prim.indices));
  expect(pa.count == mesh.positions.size(), "vertex count " + std::to_string(pa.count) + ", the mesh has " +
                                                std::to_string(mesh.positions.size()));
  expect(ia.count == 3 * mesh.triangles.size(), "index count " + std::to_string(ia.count) + ", the mesh has " +
                                                    std::to_string(mesh.triangles.size()) + " triangles");
  expect(ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, "indices are not uint32");
  expect(pa.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT && pa.type == TINYGLTF_TYPE_VEC3, "POSITION is not float VEC3");
  expect(pa.minValues.size() == 3 && pa.maxValues.size() == 3, "POSITION has no min/max");
  const auto positions = accessor_values<float>(model, prim.attributes.at("POSITION"), 3);
  const auto normals = accessor_values<float>(model, prim.attributes.at("NORMAL"), 3);
  const auto indices = accessor_values<std::uint32_t>(model, prim.indices, 1);
  if (positions.size() == 3 * mesh.positions.size()) {
    bool same = true;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v)
      for (int c = 0; c < 3; ++c) same = same && positions[3 * v + std::size_t(c)] == mesh.positions[v][c];
    expect(same, "positions differ from the mesh's");
  }
  if (indices.size() == 3 * mesh.triangles.size()) {
    bool same = true;
    for (std::size_t f = 0; f < mesh.triangles.size(); ++f)
      for (int c = 0; c < 3; ++c) same = same && indices[3 * f + std::size_t(c)] == std::uint32_t(mesh.triangles[f][c]);
    expect(same, "indices differ from the mesh's triangles");
  }
  {
    bool unit = normals.size() == positions.size();
    for (std::size_t v = 0; unit && v + 2 < normals.size(); v += 3)
      unit = std::abs(std::sqrt(double(normals[v] * normals[v] + normals[v + 1] * normals[v + 1] +
                                       normals[v + 2] * normals[v + 2])) - 1.0) < 1e-4;
    expect(unit, "normals are missing or not unit length");
    // outward: the normals of the topmost vertex points up
    std::size_t top = 0;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v)
      if (mesh.positions[v].y > mesh.positions[top].y) top = v;
    if (unit && !normals.empty()) expect(normals[3 * top + 1] > 0.0f, "the topmost vertex's normal does not point up");
  }

  // material
  expect(model.materials.size() == 1 && prim.material == 0, "expected one material on the primitive");
  if (model.materials.empty()) return 1;
  const tinygltf::Material& m = model.materials[0];
  const auto& pbr = m.pbrMetallicRoughness;
  expect(pbr.baseColorFactor == std::vector<double>{1.0, 1.0, 1.0, 1.0}, "base colour is not white");
  expect(pbr.metallicFactor == 0.0 && pbr.roughnessFactor == 0.0, "metallic or roughness is not 0");
  const auto ext = [&](const std::string& name) -> const tinygltf::Value& {
    static const tinygltf::Value none;
    const auto it = m.extensions.find(name);
    expect(it != m.extensions.end(), "material has no " + name);
    return it != m.extensions.end() ? it->second : none;
  };
  expect(number_or(member(ext("KHR_materials_transmission"), "transmissionFactor"), 0.0) == 1.0,
         "transmissionFactor is not 1");
  const double ior = number_or(member(ext("KHR_materials_ior"), "ior"), 1.5);
  expect(close(ior, material.ior, 1e-9), "ior " + std::to_string(ior) + ", the material's is " + std::to_string(material.ior));
  const tinygltf::Value& volume = ext("KHR_materials_volume");
  expect(number_or(member(volume, "thicknessFactor"), 0.0) > 0.0, "thicknessFactor is not > 0");
  const tinygltf::Value* distance = member(volume, "attenuationDistance");
  const tinygltf::Value* color = member(volume, "attenuationColor");
  double sigma[3] = {0.0, 0.0, 0.0};  // what a glTF renderer absorbs per unit length
  if (distance) {
    const double d = number_or(distance, 0.0);
    expect(d > 0.0 && std::isfinite(d), "attenuationDistance is not > 0");
    expect(color && color->IsArray() && color->ArrayLen() == 3, "attenuationColor is not 3 numbers");
    if (color && color->IsArray() && color->ArrayLen() == 3)
      for (int c = 0; c < 3; ++c) {
        const double v = number_or(&color->Get(c), -1.0);
        expect(v > 0.0 && v <= 1.0, "attenuationColor channel " + std::to_string(c) + " is not in (0, 1]");
        sigma[c] = v > 0.0 ? -std::log(v) / d : 0.0;
      }
  }
  const tinygltf::Value* extras_type = member(m.extras, "absorption_type");
  const std::string type = extras_type && extras_type->IsString() ? extras_type->Get<std::string>() : "";
  expect(type == io::to_string(material.absorption), "material.extras.absorption_type is '" + type + "', the material's is " +
                                                         io::to_string(material.absorption));
  if (material.absorption == io::AbsorptionType::none) {
    expect(!distance && !color, "clear glass has an attenuation");
  } else if (material.absorption == io::AbsorptionType::homogeneous) {
    for (int c = 0; c < 3; ++c)
      expect(close(sigma[c], material.sigma[c]), "attenuation gives sigma[" + std::to_string(c) + "] = " +
                                                      std::to_string(sigma[c]) + ", the material's is " +
                                                      std::to_string(material.sigma[c]));
  } else {
    const auto& g = material.grid.sigma;
    for (int c = 0; c < 3; ++c) {
      float lo = std::numeric_limits<float>::infinity(), hi = 0.0f;
      for (std::size_t i = std::size_t(c); i < g.size(); i += 3) lo = std::min(lo, g[i]), hi = std::max(hi, g[i]);
      expect(sigma[c] >= lo * (1 - 1e-6) && sigma[c] <= hi * (1 + 1e-6),
             "grid: attenuation gives sigma[" + std::to_string(c) + "] = " + std::to_string(sigma[c]) +
                 ", outside the grid's range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    const double used = number_or(member(m.extras, "volume_samples_inside"), 0.0);
    const double total = number_or(member(m.extras, "volume_samples"), 0.0);
    expect(used > 0 && used < total, "extras do not say over how many points inside the mesh the grid was averaged");
    const tinygltf::Value* how = member(m.extras, "absorption");
    expect(how && how->IsString() && how->Get<std::string>().find("averaged") != std::string::npos,
           "extras.absorption does not say the grid was averaged");
  }
  // the coefficients agree with the ones extras records
  const tinygltf::Value* extras_sigma = member(m.extras, "sigma");
  if (extras_sigma && extras_sigma->IsArray() && extras_sigma->ArrayLen() == 3)
    for (int c = 0; c < 3; ++c)
      expect(close(sigma[c], number_or(&extras_sigma->Get(c), -1.0)), "extras.sigma disagrees with the attenuation");
  else
    expect(false, "material.extras.sigma is not 3 numbers");

  if (failures) {
    std::cerr << "check_glb: " << failures << " failures in " << glb << std::endl;
    return 1;
  }
  std::cout << "check_glb: ok: " << pa.count << " vertices, " << ia.count / 3 << " triangles, ior " << ior
            << ", sigma (" << sigma[0] << ", " << sigma[1] << ", " << sigma[2] << ")" << std::endl;
  return 0;
}
