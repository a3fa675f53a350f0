// difftrans shape: writes a procedural mesh of known topology (for testing
// shape recovery), e.g. a block with five holes: feed it to synth --mesh.
#include "command.hpp"

#include "difftrans/geometry/procedural.hpp"
#include "difftrans/geometry/topology.hpp"
#include "difftrans/io/mesh_file.hpp"

namespace difftrans::cli {

void add_shape(CLI::App& app) {
  auto name = std::make_shared<std::string>();
  auto out = std::make_shared<std::filesystem::path>();
  auto subdivide = std::make_shared<int>(8);
  CLI::App* cmd = app.add_subcommand("shape", "Write a procedural mesh of known genus (.obj or .ply)");
  cmd->footer("Shapes: holes-N, a slab pierced by N square holes in a row (genus N), each voxel face cut into\n"
              "S x S quads (--subdivide); sphere-L, an icosphere of radius 1 subdivided L times (L = 0..9;\n"
              "20 x 4^L triangles).\n"
              "Example: difftrans shape holes-5 --out holes5.obj && difftrans synth --mesh holes5.obj --ior 1.5 \\\n"
              "           --env constant:1,1,1 --variant quick --out scenes/holes5");
  cmd->add_option("name", *name, "shape name")->required();
  cmd->add_option("--out", *out, "mesh file to write")->required();
  cmd->add_option("--subdivide", *subdivide,
                  "holes-N: each voxel face cut into S x S quads, so that the vertex normals a renderer interpolates "
                  "bend only a band 1/S of a voxel wide along the edges (1: one quad per face, every face bent)")
      ->capture_default_str()->check(CLI::Range(1, 64));
  cmd->callback([name, out, subdivide] {
    geometry::ProceduralMesh p;
    try {
      p = geometry::procedural_shape(*name, *subdivide);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(e.what());
    }
    io::Mesh m;
    for (std::size_t i = 0; i + 2 < p.positions.size(); i += 3)
      m.positions.emplace_back(p.positions[i], p.positions[i + 1], p.positions[i + 2]);
    for (std::size_t f = 0; f + 2 < p.triangles.size(); f += 3)
      m.triangles.emplace_back(p.triangles[f], p.triangles[f + 1], p.triangles[f + 2]);
    io::write_mesh(*out, m);
    const geometry::MeshGenus g = geometry::mesh_genus(p.triangles, std::int32_t(p.positions.size() / 3));
    io::Json j;
    j["shape"] = *name;
    j["file"] = out->string();
    j["vertices"] = g.vertices;
    j["triangles"] = g.faces;
    j["genus"] = g.genus;
    j["closed"] = g.closed;
    emit_json(j, std::nullopt);
  });
}

}  // namespace difftrans::cli
