// The scene the report programs of bench/ time: a mesh of data/meshes in the
// unit box under venice_sunset (data/envmaps), clear, with the given IoR.
#pragma once

#include <string>

#include "difftrans/io/hdr.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/views.hpp"

namespace dt_bench {

inline difftrans::render::HostScene venice_scene(const std::string& mesh, float ior) {
  const std::string data = DIFFTRANS_DATA_DIR;
  difftrans::io::Mesh m = difftrans::io::read_mesh(data + "/meshes/" + mesh + ".obj");
  difftrans::io::normalize_to_unit_box(m);
  difftrans::render::HostScene s = difftrans::render::make_host_scene(m, difftrans::io::Material{}, mesh);
  s.ior = ior;
  difftrans::render::set_environment(s, difftrans::io::read_hdr(data + "/envmaps/venice_sunset_1k.hdr"));
  return s;
}

}  // namespace dt_bench
