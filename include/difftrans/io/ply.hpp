// Stanford PLY meshes: a bounds-checked reader for ASCII and binary (little
// and big endian) files, polygons fan-triangulated; a binary writer.
#pragma once

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "difftrans/io/mesh.hpp"

namespace difftrans::io {
namespace detail {

enum class PlyType { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

inline bool ply_type(const std::string& name, PlyType& type) {
  static const struct {
    const char* name;
    PlyType type;
  } table[] = {{"char", PlyType::int8},     {"int8", PlyType::int8},       {"uchar", PlyType::uint8},
               {"uint8", PlyType::uint8},   {"short", PlyType::int16},     {"int16", PlyType::int16},
               {"ushort", PlyType::uint16}, {"uint16", PlyType::uint16},   {"int", PlyType::int32},
               {"int32", PlyType::int32},   {"uint", PlyType::uint32},     {"uint32", PlyType::uint32},
               {"float", PlyType::float32}, {"float32", PlyType::float32}, {"double", PlyType::float64},
               {"float64", PlyType::float64}};
  for (const auto& e : table)
    if (name == e.name) {
      type = e.type;
      return true;
    }
  return false;
}

inline int ply_size(PlyType t) {
  switch (t) {
    case PlyType::int8: case PlyType::uint8: return 1;
    case PlyType::int16: case PlyType::uint16: return 2;
    case PlyType::int32: case PlyType::uint32: case PlyType::float32: return 4;
    case PlyType::float64: return 8;
  }
  return 0;
}

inline bool ply_integer(PlyType t) { return t != PlyType::float32 && t != PlyType::float64; }

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::float32;
  bool list = false;
  PlyType count_type = PlyType::uint8;
};

struct PlyElement {
  std::string name;
  unsigned long long count = 0;
  std::vector<PlyProperty> properties;
  long line = 0;
};

// Reads values one at a time from the body, ASCII or binary, with bounds checks.
class PlyBody {
 public:
  enum class Format { ascii, binary_le, binary_be };

  PlyBody(const std::string& text, size_t start, long line, Format format, const std::filesystem::path& file)
      : text_(text), pos_(start), line_(line), format_(format), file_(file) {}

  double read(PlyType type, const std::string& what) {
    return format_ == Format::ascii ? read_ascii(type, what) : read_binary(type, what);
  }
  // Line of the last ASCII value read (0 for binary bodies).
  long line() const { return format_ == Format::ascii ? value_line_ : 0; }
  size_t offset() const { return pos_; }
  size_t remaining() const { return text_.size() - pos_; }
  bool ascii() const { return format_ == Format::ascii; }
  [[noreturn]] void fail(const std::string& what) const {
    if (format_ == Format::ascii) throw Error(file_, what, value_line_ > 0 ? value_line_ : line_);
    throw Error(file_, what + " (byte offset " + std::to_string(pos_) + ")");
  }

 private:
  double read_ascii(PlyType type, const std::string& what) {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    value_line_ = line_;
    if (pos_ >= text_.size()) fail("unexpected end of file while reading " + what);
    const size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    const std::string token = text_.substr(start, pos_ - start);
    char* stop = nullptr;
    const double v = std::strtod(token.c_str(), &stop);
    if (stop == token.c_str() || *stop != '\0') fail(excerpt(token) + " is not a number, reading " + what);
    if (ply_integer(type) && (!std::isfinite(v) || v != std::floor(v)))
      fail(excerpt(token) + " is not an integer, reading " + what);
    return v;
  }

  double read_binary(PlyType type, const std::string& what) {
    const int n = ply_size(type);
    if (remaining() < size_t(n)) fail("unexpected end of file while reading " + what);
    unsigned char b[8];
    std::memcpy(b, text_.data() + pos_, size_t(n));
    pos_ += size_t(n);
    const bool little = [] {
      const std::uint16_t one = 1;
      unsigned char c;
      std::memcpy(&c, &one, 1);
      return c == 1;
    }();
    if ((format_ == Format::binary_le) != little) std::reverse(b, b + n);
    switch (type) {
      case PlyType::int8: { std::int8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::uint8: return b[0];
      case PlyType::int16: { std::int16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::uint16: { std::uint16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::int32: { std::int32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::uint32: { std::uint32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::float32: { float v; std::memcpy(&v, b, 4); return double(v); }
      case PlyType::float64: { double v; std::memcpy(&v, b, 8); return v; }
    }
    return 0.0;
  }

  const std::string& text_;
  size_t pos_;
  long line_;
  long value_line_ = 0;
  Format format_;
  const std::filesystem::path& file_;
};

}  // namespace detail

// Parses the bytes of a PLY file (`file` names it in messages). Needs an
// element "vertex" with properties x, y, z; faces come from the list property
// "vertex_indices" (or "vertex_index") of element "face"; everything else is
// skipped. Throws Error on bad input; appends warnings to *warnings if given.
namespace detail {
// A whole number read as double, printed without the undefined behaviour of
// casting an out-of-range value to long (found by scripts/fuzz.sh).
inline std::string integer_text(double x) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.0f", x);
  return buf;
}
}  // namespace detail

inline Mesh parse_ply(const std::string& text, const std::filesystem::path& file,
                      std::vector<std::string>* warnings = nullptr) {
  using namespace detail;
  // ---- header
  size_t pos = 0;
  long line = 0;
  const auto next_line = [&](std::string& out) {
    if (pos >= text.size()) return false;
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    out.assign(text, pos, end - pos);
    if (!out.empty() && out.back() == '\r') out.pop_back();
    pos = std::min(end + 1, text.size());
    ++line;
    return true;
  };
  const auto words = [](const std::string& s) {
    std::vector<std::string> w;
    std::istringstream in(s);
    std::string x;
    while (in >> x) w.push_back(x);
    return w;
  };
  std::string l;
  if (!next_line(l) || l != "ply") throw Error(file, "not a PLY file (the first line is not \"ply\")", 1);
  PlyBody::Format format = PlyBody::Format::ascii;
  bool have_format = false, ended = false;
  std::vector<PlyElement> elements;
  while (next_line(l)) {
    const auto w = words(l);
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") {
      ended = true;
      break;
    }
    if (w[0] == "format") {
      if (w.size() != 3) throw Error(file, "malformed format line", line);
      if (w[1] == "ascii") format = PlyBody::Format::ascii;
      else if (w[1] == "binary_little_endian") format = PlyBody::Format::binary_le;
      else if (w[1] == "binary_big_endian") format = PlyBody::Format::binary_be;
      else throw Error(file, "unknown format " + excerpt(w[1]), line);
      if (w[2] != "1.0") throw Error(file, "unsupported PLY version " + excerpt(w[2]), line);
      have_format = true;
    } else if (w[0] == "element") {
      if (w.size() != 3) throw Error(file, "malformed element line (expected: element NAME COUNT)", line);
      char* stop = nullptr;
      errno = 0;
      const unsigned long long count = std::strtoull(w[2].c_str(), &stop, 10);
      if (*stop != '\0' || w[2][0] == '-' || errno == ERANGE)
        throw Error(file, "element count " + excerpt(w[2]) + " is not a non-negative integer", line);
      elements.push_back({w[1], count, {}, line});
    } else if (w[0] == "property") {
      if (elements.empty()) throw Error(file, "property before any element", line);
      PlyProperty p;
      if (w.size() == 5 && w[1] == "list") {
        p.list = true;
        if (!ply_type(w[2], p.count_type) || !ply_type(w[3], p.type))
          throw Error(file, "unknown property type in " + excerpt(l), line);
        if (!ply_integer(p.count_type)) throw Error(file, "list count type must be an integer type", line);
        p.name = w[4];
      } else if (w.size() == 3 && w[1] != "list") {
        if (!ply_type(w[1], p.type)) throw Error(file, "unknown property type " + excerpt(w[1]), line);
        p.name = w[2];
      } else {
        throw Error(file, "malformed property line " + excerpt(l), line);
      }
      elements.back().properties.push_back(p);
    } else {
      throw Error(file, "unknown header keyword " + excerpt(w[0]), line);
    }
  }
  if (!ended) throw Error(file, "the header has no end_header line");
  if (!have_format) throw Error(file, "the header has no format line");

  // ---- body
  PlyBody body(text, pos, line + 1, format, file);
  Mesh mesh;
  std::vector<long> triangle_line;  // ASCII: line of each triangle's face
  std::vector<long> triangle_face;
  bool have_vertices = false, have_faces = false;
  long short_faces = 0;
  std::string short_list;
  const unsigned long long max_count = std::numeric_limits<std::int32_t>::max();
  for (const PlyElement& e : elements) {
    size_t min_size = 0;  // bytes (binary) or characters (ASCII, 2 per value) one instance needs at least
    for (const auto& p : e.properties) min_size += body.ascii() ? 2 : size_t(ply_size(p.list ? p.count_type : p.type));
    if (min_size > 0 && e.count > body.remaining() / min_size + 1)
      throw Error(file, "element " + excerpt(e.name) + " declares " + std::to_string(e.count) +
                            " entries, more than the file can hold", e.line);
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    int xyz[3] = {-1, -1, -1};
    int indices = -1;
    for (size_t k = 0; k < e.properties.size(); ++k) {
      const auto& p = e.properties[k];
      if (is_vertex && !p.list) {
        if (p.name == "x") xyz[0] = int(k);
        if (p.name == "y") xyz[1] = int(k);
        if (p.name == "z") xyz[2] = int(k);
      }
      if (is_face && p.list && (p.name == "vertex_indices" || p.name == "vertex_index")) indices = int(k);
    }
    if (is_vertex) {
      if (have_vertices) throw Error(file, "a second 'vertex' element", e.line);
      if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
        throw Error(file, "element 'vertex' lacks one of the properties x, y, z", e.line);
      if (e.count > max_count) throw Error(file, "too many vertices for int32 indices", e.line);
      mesh.positions.resize(size_t(e.count));
      have_vertices = true;
    }
    if (is_face) {
      if (have_faces) throw Error(file, "a second 'face' element", e.line);
      if (indices < 0) throw Error(file, "element 'face' has no list property vertex_indices", e.line);
      if (!ply_integer(e.properties[size_t(indices)].type))
        throw Error(file, "face vertex indices must have an integer type", e.line);
      have_faces = true;
    }
    if (e.properties.empty()) continue;  // nothing to read, whatever the count
    std::vector<int> face;
    for (unsigned long long i = 0; i < e.count; ++i) {
      const std::string what = e.name + " " + std::to_string(i);
      long first_line = 0;
      for (size_t k = 0; k < e.properties.size(); ++k) {
        const auto& p = e.properties[k];
        if (!p.list) {
          const double v = body.read(p.type, what);
          if (k == 0) first_line = body.line();
          if (is_vertex)
            for (int c = 0; c < 3; ++c)
              if (int(k) == xyz[c]) {
                if (!std::isfinite(v) || std::abs(v) > double(std::numeric_limits<float>::max()))
                  body.fail("vertex " + std::to_string(i) + " has a non-finite coordinate " + p.name);
                mesh.positions[size_t(i)][c] = float(v);
              }
          continue;
        }
        const double n = body.read(p.count_type, what + " list length");
        if (k == 0) first_line = body.line();
        if (n < 0) body.fail(what + ": negative list length");
        if (body.ascii() ? n > double(body.remaining()) / 2 + 1 : n * ply_size(p.type) > double(body.remaining()))
          body.fail(what + ": list length " + detail::integer_text(n) + " exceeds the file");
        if (int(k) == indices) face.clear();
        for (long j = 0; j < long(n); ++j) {
          const double v = body.read(p.type, what);
          if (int(k) != indices) continue;
          if (v < 0 || v >= double(mesh.positions.size()))
            body.fail("face " + std::to_string(i) + ": vertex index " + detail::integer_text(v) +
                      " is out of range [0, " + std::to_string(mesh.positions.size()) + ")" +
                      (have_vertices ? "" : " (no vertex element before the faces)"));
          face.push_back(int(v));
        }
      }
      if (!is_face) continue;
      if (face.size() < 3) {
        if (short_faces < max_listed_warnings)
          short_list += (short_list.empty() ? "" : ", ") + std::to_string(i) +
                        (first_line > 0 ? " (line " + std::to_string(first_line) + ")" : "");
        ++short_faces;
      }
      for (size_t k = 1; k + 1 < face.size(); ++k) {
        mesh.triangles.emplace_back(face[0], face[k], face[k + 1]);
        triangle_line.push_back(first_line);
        triangle_face.push_back(int(i));
      }
    }
  }
  if (!have_vertices) throw Error(file, "no 'vertex' element");
  if (short_faces > 0 && warnings)
    warnings->push_back(file.string() + ": " + std::to_string(short_faces) +
                        " face(s) with fewer than 3 vertices ignored: face " + short_list +
                        list_more(short_faces, max_listed_warnings));
  auto found = check_mesh(mesh, file, [&](int t) {
    const long ln = triangle_line[size_t(t)];
    return "face " + std::to_string(triangle_face[size_t(t)]) + (ln > 0 ? " (line " + std::to_string(ln) + ")" : "");
  });
  if (mesh.triangles.empty()) found.push_back(file.string() + ": no faces");
  if (warnings) warnings->insert(warnings->end(), found.begin(), found.end());
  return mesh;
}

inline Mesh read_ply(const std::filesystem::path& path, std::vector<std::string>* warnings = nullptr) {
  return parse_ply(detail::read_file_text(path), path, warnings);
}

// Writes binary little-endian PLY (float x y z; uchar-counted int indices),
// or ASCII when ascii = true; with `normals` (one per vertex) also float
// nx ny nz per vertex, with `colors` uchar red green blue (what mesh viewers
// show as vertex colours).
inline void write_ply(const std::filesystem::path& path, const Mesh& mesh, bool ascii = false,
                      const std::vector<Vec3f>* normals = nullptr,
                      const std::vector<std::array<std::uint8_t, 3>>* colors = nullptr) {
  if (normals && normals->size() != mesh.positions.size())
    throw Error(path, "cannot write " + std::to_string(normals->size()) + " normals for " +
                          std::to_string(mesh.positions.size()) + " vertices");
  if (colors && colors->size() != mesh.positions.size())
    throw Error(path, "cannot write " + std::to_string(colors->size()) + " colours for " +
                          std::to_string(mesh.positions.size()) + " vertices");
  std::string out = "ply\nformat ";
  out += ascii ? "ascii" : "binary_little_endian";
  out += " 1.0\ncomment written by difftrans\nelement vertex " + std::to_string(mesh.positions.size()) +
         "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  out += "element face " + std::to_string(mesh.triangles.size()) +
         "\nproperty list uchar int vertex_indices\nend_header\n";
  if (ascii) {
    char line[256];
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      const Vec3f& p = mesh.positions[v];
      std::snprintf(line, sizeof(line), "%.9g %.9g %.9g", double(p.x), double(p.y), double(p.z));
      out += line;
      if (normals) {
        const Vec3f& n = (*normals)[v];
        std::snprintf(line, sizeof(line), " %.9g %.9g %.9g", double(n.x), double(n.y), double(n.z));
        out += line;
      }
      if (colors) {
        const auto& c = (*colors)[v];
        std::snprintf(line, sizeof(line), " %d %d %d", int(c[0]), int(c[1]), int(c[2]));
        out += line;
      }
      out += '\n';
    }
    for (const auto& f : mesh.triangles) {
      std::snprintf(line, sizeof(line), "3 %d %d %d\n", f.x, f.y, f.z);
      out += line;
    }
  } else {
    const auto put = [&](const void* p, size_t n) {
      unsigned char b[4];
      std::memcpy(b, p, n);
      const std::uint16_t one = 1;
      unsigned char c;
      std::memcpy(&c, &one, 1);
      if (c != 1) std::reverse(b, b + n);  // big-endian host
      out.append(reinterpret_cast<const char*>(b), n);
    };
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      for (int c = 0; c < 3; ++c) put(&mesh.positions[v][c], 4);
      if (normals)
        for (int c = 0; c < 3; ++c) put(&(*normals)[v][c], 4);
      if (colors)
        for (int c = 0; c < 3; ++c) out.push_back(char((*colors)[v][std::size_t(c)]));
    }
    for (const auto& f : mesh.triangles) {
      out.push_back(char(3));
      for (int c = 0; c < 3; ++c) {
        const std::int32_t i = f[c];
        put(&i, 4);
      }
    }
  }
  detail::write_file_bytes(path, out.data(), out.size());
}

}  // namespace difftrans::io
