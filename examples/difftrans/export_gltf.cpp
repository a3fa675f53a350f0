// difftrans export --format gltf: the object as a glTF 2.0 binary file written
// with tinygltf. One mesh (positions, the renderer's vertex normals, uint32
// indices) with a glass material: white base colour, metallic 0, roughness 0,
// KHR_materials_transmission (1), KHR_materials_ior and KHR_materials_volume,
// whose attenuation reproduces the absorption (gltf_attenuation).
#include "export.hpp"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>
#include <limits>

#include <tiny_gltf.h>

#include "stage_output.hpp"

namespace difftrans::cli {
namespace {

using Value = tinygltf::Value;

Value number(double x) { return Value(x); }
Value rgb(const Vec3d& c) { return Value(Value::Array{number(c.x), number(c.y), number(c.z)}); }

// Appends `size` bytes to the buffer (4-byte aligned) and adds a buffer view; returns its index.
int add_view(tinygltf::Model& model, const void* data, std::size_t size, int target) {
  std::vector<unsigned char>& bytes = model.buffers[0].data;
  while (bytes.size() % 4 != 0) bytes.push_back(0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = bytes.size();
  view.byteLength = size;
  view.target = target;
  const auto* p = static_cast<const unsigned char*>(data);
  bytes.insert(bytes.end(), p, p + size);
  model.bufferViews.push_back(view);
  return int(model.bufferViews.size()) - 1;
}

int add_accessor(tinygltf::Model& model, int view, int component, int type, std::size_t count,
                 std::vector<double> min = {}, std::vector<double> max = {}) {
  tinygltf::Accessor a;
  a.bufferView = view;
  a.byteOffset = 0;
  a.componentType = component;
  a.type = type;
  a.count = count;
  a.minValues = std::move(min);
  a.maxValues = std::move(max);
  model.accessors.push_back(a);
  return int(model.accessors.size()) - 1;
}

}  // namespace

io::Json write_gltf(const ExportInput& in, const AbsorptionSummary& absorption, const std::filesystem::path& file) {
  const io::Mesh& mesh = in.mesh;
  const io::Box box = io::bounding_box(mesh);
  const Vec3d size = box.size();
  const double longest = std::max(size.x, std::max(size.y, size.z));
  const double thickness = (size.x + size.y + size.z) / 3.0;

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "difftrans export";
  model.buffers.resize(1);

  // geometry
  std::vector<float> positions;
  positions.reserve(mesh.positions.size() * 3);
  for (const Vec3f& p : mesh.positions) positions.insert(positions.end(), {p.x, p.y, p.z});
  std::vector<float> normals;
  normals.reserve(mesh.positions.size() * 3);
  for (const Vec3f& n : export_vertex_normals(mesh)) normals.insert(normals.end(), {n.x, n.y, n.z});
  std::vector<std::uint32_t> indices;
  indices.reserve(mesh.triangles.size() * 3);
  for (const Vec3i& t : mesh.triangles)
    indices.insert(indices.end(), {std::uint32_t(t.x), std::uint32_t(t.y), std::uint32_t(t.z)});
  std::vector<double> lo(3, std::numeric_limits<double>::infinity()), hi(3, -std::numeric_limits<double>::infinity());
  for (const Vec3f& p : mesh.positions)
    for (int c = 0; c < 3; ++c) lo[size_t(c)] = std::min(lo[size_t(c)], double(p[c])), hi[size_t(c)] = std::max(hi[size_t(c)], double(p[c]));

  const int position_view = add_view(model, positions.data(), positions.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
  const int normal_view = add_view(model, normals.data(), normals.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
  const int index_view =
      add_view(model, indices.data(), indices.size() * sizeof(std::uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  const int position_accessor = add_accessor(model, position_view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                                             mesh.positions.size(), lo, hi);
  const int normal_accessor =
      add_accessor(model, normal_view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, mesh.positions.size());
  const int index_accessor =
      add_accessor(model, index_view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
  model.buffers[0].name = "geometry";

  // material
  tinygltf::Material material;
  material.name = "glass";
  material.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};
  material.pbrMetallicRoughness.metallicFactor = 0.0;
  material.pbrMetallicRoughness.roughnessFactor = 0.0;
  material.extensions["KHR_materials_transmission"] = Value(Value::Object{{"transmissionFactor", number(1.0)}});
  material.extensions["KHR_materials_ior"] = Value(Value::Object{{"ior", number(in.material.ior)}});
  Value::Object volume{{"thicknessFactor", number(thickness > 0.0 ? thickness : 1.0)}};
  const GltfAttenuation att = gltf_attenuation(absorption.sigma, longest);
  if (att.distance > 0.0) {
    volume["attenuationDistance"] = number(att.distance);
    volume["attenuationColor"] = rgb(att.color);
  }
  material.extensions["KHR_materials_volume"] = Value(std::move(volume));
  Value::Object extras{{"absorption_type", Value(absorption.type)},
                       {"absorption", Value(absorption.how)},
                       {"sigma", rgb(absorption.sigma)},
                       {"sigma_unit", Value(std::string("per unit length of the mesh's coordinates"))}};
  if (absorption.type == "grid") {
    extras["volume_samples_inside"] = Value(int(absorption.samples_used));
    extras["volume_samples"] = Value(int(absorption.samples_total));
  }
  material.extras = Value(std::move(extras));
  model.materials.push_back(material);
  model.extensionsUsed = {"KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"};

  tinygltf::Primitive primitive;
  primitive.attributes["POSITION"] = position_accessor;
  primitive.attributes["NORMAL"] = normal_accessor;
  primitive.indices = index_accessor;
  primitive.material = 0;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh gmesh;
  gmesh.name = in.mesh_source.stem().string();
  gmesh.primitives.push_back(primitive);
  model.meshes.push_back(gmesh);
  tinygltf::Node node;
  node.name = gmesh.name;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  model.asset.extras = Value(Value::Object{{"source_mesh", Value(in.mesh_source.string())},
                                           {"source_material", Value(in.material_source)}});

  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToFile(&model, file.string(), true, true, false, true))
    throw io::Error(file, "cannot write glTF binary");
  progress("export: " + file.filename().string() + ": " + std::to_string(mesh.positions.size()) + " vertices, " +
           std::to_string(mesh.triangles.size()) + " triangles, IoR " + fixed(in.material.ior, 4) +
           (att.distance > 0.0 ? ", attenuation distance " + fixed(att.distance, 4) : ", clear"));
  io::Json j = io::Json::object();
  j["glb"] = file.filename().string();
  j["thickness"] = thickness;
  if (att.distance > 0.0) {
    j["attenuation_distance"] = att.distance;
    j["attenuation_color"] = {att.color.x, att.color.y, att.color.z};
  }
  return j;
}

}  // namespace difftrans::cli
