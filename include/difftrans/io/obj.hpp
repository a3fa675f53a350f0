// Wavefront OBJ meshes: read with tinyobjloader (polygons fan-triangulated,
// errors and warnings located by line), write as plain "v"/"f" statements.
#pragma once

#include <tiny_obj_loader.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "difftrans/io/mesh.hpp"

namespace difftrans::io {
namespace detail {

// Most vertices of one OBJ face: tinyobjloader stores the count in an
// unsigned char, so a larger polygon would be read as another one.
inline constexpr std::size_t max_obj_face_vertices = 255;

// Where the "v" and "f" statements of an OBJ text are, checked for what
// tinyobjloader accepts silently (it reads "nan" or "abc" as 0, and a face's
// vertex count modulo 256).
struct ObjStatements {
  std::vector<long> vertex_lines;
  std::vector<long> face_lines;  // faces with 3 or more vertices, in file order
};

inline bool obj_space(char c) { return c == ' ' || c == '\t' || c == '\r'; }

inline ObjStatements scan_obj(const std::string& text, const std::filesystem::path& file,
                              std::vector<std::string>* warnings) {
  ObjStatements st;
  struct FaceRef {
    long index;
    long line;
  };
  std::vector<FaceRef> positive;  // checked once the vertex count is known
  long line = 0;
  size_t pos = 0;
  long short_faces = 0;
  std::string short_list;
  while (pos < text.size()) {
    ++line;
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    size_t i = pos;
    while (i < end && obj_space(text[i])) ++i;
    const auto tokens = [&](size_t from) {
      std::vector<std::string> out;
      size_t k = from;
      while (k < end) {
        while (k < end && obj_space(text[k])) ++k;
        if (k >= end || text[k] == '#') break;
        const size_t s = k;
        while (k < end && !obj_space(text[k])) ++k;
        out.emplace_back(text, s, k - s);
      }
      return out;
    };
    if (i + 1 < end && text[i] == 'v' && obj_space(text[i + 1])) {
      const auto t = tokens(i + 1);
      if (t.size() < 3)
        throw Error(file, "vertex needs 3 coordinates, found " + std::to_string(t.size()), line);
      for (size_t k = 0; k < 3; ++k) {
        char* stop = nullptr;
        errno = 0;
        const double v = std::strtod(t[k].c_str(), &stop);
        if (stop == t[k].c_str() || *stop != '\0')
          throw Error(file, "vertex coordinate " + excerpt(t[k]) + " is not a number", line);
        if (!std::isfinite(v) || std::abs(v) > double(std::numeric_limits<float>::max()))
          throw Error(file, "vertex coordinate " + excerpt(t[k]) + " is not a finite number", line);
      }
      st.vertex_lines.push_back(line);
    } else if (i + 1 < end && text[i] == 'f' && obj_space(text[i + 1])) {
      const auto t = tokens(i + 1);
      if (t.size() > max_obj_face_vertices)
        throw Error(file, "face with " + std::to_string(t.size()) + " vertices: at most " +
                              std::to_string(max_obj_face_vertices) + " are read (tinyobjloader keeps a face's vertex "
                              "count in one byte); split the polygon into triangles", line);
      for (const auto& tok : t) {
        char* stop = nullptr;
        errno = 0;
        const long index = std::strtol(tok.c_str(), &stop, 10);
        if (stop == tok.c_str() || (*stop != '\0' && *stop != '/'))
          throw Error(file, "face vertex " + excerpt(tok) + " is not an index", line);
        if (errno == ERANGE)  // (found by scripts/fuzz.sh: negating LONG_MIN was undefined)
          throw Error(file, "face vertex index " + excerpt(tok.substr(0, tok.find('/'))) + " is out of range", line);
        if (index == 0) throw Error(file, "face vertex index 0 (OBJ indices start at 1)", line);
        if (index < 0) {
          const long available = long(st.vertex_lines.size());
          if (index < -available)
            throw Error(file, "relative face vertex index " + std::to_string(index) + " is out of range: only " +
                                  std::to_string(available) + " vertices so far", line);
        } else {
          positive.push_back({index, line});
        }
      }
      if (t.size() >= 3) {
        st.face_lines.push_back(line);
      } else {
        if (short_faces < max_listed_warnings) short_list += (short_list.empty() ? "" : ", ") + std::to_string(line);
        ++short_faces;
      }
    }
    pos = end + 1;
  }
  const long nv = long(st.vertex_lines.size());
  for (const auto& ref : positive)
    if (ref.index > nv)
      throw Error(file, "face vertex index " + std::to_string(ref.index) + " is out of range: the file has " +
                            std::to_string(nv) + " vertices", ref.line);
  if (short_faces > 0 && warnings)
    warnings->push_back(file.string() + ": " + std::to_string(short_faces) +
                        " face(s) with fewer than 3 vertices ignored, on line(s) " + short_list +
                        list_more(short_faces, max_listed_warnings));
  return st;
}

}  // namespace detail

// Parses OBJ text (`file` names it in messages). Throws Error on bad input;
// appends warnings (degenerate, non-manifold faces ...) to *warnings if given.
inline Mesh parse_obj(const std::string& text, const std::filesystem::path& file,
                      std::vector<std::string>* warnings = nullptr) {
  const detail::ObjStatements st = detail::scan_obj(text, file, warnings);
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warn, err;
  std::istringstream stream(text);
  // No material reader: materials are not needed and "mtllib" is ignored.
  if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &stream, nullptr, false, false))
    throw Error(file, "tinyobjloader: " + (err.empty() ? std::string("parse failed") : err));

  Mesh mesh;
  const size_t nv = attrib.vertices.size() / 3;
  if (nv != st.vertex_lines.size())
    throw Error(file, "tinyobjloader read " + std::to_string(nv) + " vertices where the file has " +
                          std::to_string(st.vertex_lines.size()));
  if (nv > size_t(std::numeric_limits<int>::max())) throw Error(file, "too many vertices for int32 indices");
  mesh.positions.resize(nv);
  for (size_t i = 0; i < nv; ++i)
    mesh.positions[i] = Vec3f(attrib.vertices[3 * i], attrib.vertices[3 * i + 1], attrib.vertices[3 * i + 2]);
  std::vector<int> triangle_face;  // source face of each triangle, counted over the file
  int face = 0;
  for (const auto& shape : shapes) {
    size_t offset = 0;
    for (const unsigned char n : shape.mesh.num_face_vertices) {
      for (unsigned k = 1; k + 1 < n; ++k) {
        mesh.triangles.emplace_back(shape.mesh.indices[offset].vertex_index,
                                    shape.mesh.indices[offset + k].vertex_index,
                                    shape.mesh.indices[offset + k + 1].vertex_index);
        triangle_face.push_back(face);
      }
      offset += n;
      ++face;
    }
  }
  const bool located = size_t(face) == st.face_lines.size();
  auto found = check_mesh(mesh, file, [&](int t) {
    return located ? "face on line " + std::to_string(st.face_lines[size_t(triangle_face[size_t(t)])])
                   : "face " + std::to_string(triangle_face[size_t(t)]);
  });
  if (mesh.triangles.empty()) found.push_back(file.string() + ": no faces");
  if (warnings) warnings->insert(warnings->end(), found.begin(), found.end());
  return mesh;
}

inline Mesh read_obj(const std::filesystem::path& path, std::vector<std::string>* warnings = nullptr) {
  return parse_obj(detail::read_file_text(path), path, warnings);
}

// Writes "v x y z" (9 significant digits: floats round-trip) and 1-based "f a b c".
inline void write_obj(const std::filesystem::path& path, const Mesh& mesh) {
  std::string out = "# written by difftrans\n";
  out.reserve(mesh.positions.size() * 40 + mesh.triangles.size() * 30);
  char line[128];
  for (const auto& p : mesh.positions) {
    std::snprintf(line, sizeof(line), "v %.9g %.9g %.9g\n", double(p.x), double(p.y), double(p.z));
    out += line;
  }
  for (const auto& f : mesh.triangles) {
    std::snprintf(line, sizeof(line), "f %d %d %d\n", f.x + 1, f.y + 1, f.z + 1);
    out += line;
  }
  detail::write_file_bytes(path, out.data(), out.size());
}

}  // namespace difftrans::io
