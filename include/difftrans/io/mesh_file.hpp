// Reads and writes a mesh file in the format its extension names (.obj, .ply).
#pragma once

#include "difftrans/io/obj.hpp"
#include "difftrans/io/ply.hpp"

namespace difftrans::io {

inline Mesh read_mesh(const std::filesystem::path& path, std::vector<std::string>* warnings = nullptr) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".obj") return read_obj(path, warnings);
  if (ext == ".ply") return read_ply(path, warnings);
  throw Error(path, "unsupported mesh format '" + ext + "' (expected .obj or .ply)");
}

// PLY is written binary.
inline void write_mesh(const std::filesystem::path& path, const Mesh& mesh) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".obj") return write_obj(path, mesh);
  if (ext == ".ply") return write_ply(path, mesh);
  throw Error(path, "unsupported mesh format '" + ext + "' (expected .obj or .ply)");
}

}  // namespace difftrans::io
