// PLY: ASCII and binary (both byte orders) with extra properties and
// elements, polygons fanned; bad input located by line (ASCII) or byte offset.
#include "difftrans/io/ply.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <vector>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
using difftrans::Vec3f;
using difftrans::Vec3i;

namespace {

// Appends a value in the given byte order.
template <class T>
void put(std::string& out, T value, bool big_endian) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (big_endian) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

// A square (quad) and a triangle over 5 vertices, with a normal and a colour
// per vertex, a uchar flag per face and an extra "edge" element in between.
std::string binary_ply(bool big_endian) {
  std::string s = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\ncomment test\nelement vertex 5\nproperty double x\nproperty float nx\nproperty float y\n"
                  "property float z\nproperty uchar red\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n"
                  "element face 2\nproperty uchar flag\nproperty list uchar uint vertex_indices\n"
                  "property list ushort float texcoord\nend_header\n";
  const float p[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5f, 0.25f, -1.5f}};
  for (const auto& v : p) {
    put<double>(s, v[0], big_endian);
    put<float>(s, 0.0f, big_endian);
    put<float>(s, v[1], big_endian);
    put<float>(s, v[2], big_endian);
    put<unsigned char>(s, 200, big_endian);
  }
  put<std::int32_t>(s, 0, big_endian);
  put<std::int32_t>(s, 1, big_endian);
  // quad 0 1 2 3 with 2 texcoords, triangle 0 1 4 with none
  put<unsigned char>(s, 1, big_endian);
  put<unsigned char>(s, 4, big_endian);
  for (std::uint32_t i : {0u, 1u, 2u, 3u}) put(s, i, big_endian);
  put<std::uint16_t>(s, 2, big_endian);
  put<float>(s, 0.5f, big_endian);
  put<float>(s, 0.5f, big_endian);
  put<unsigned char>(s, 0, big_endian);
  put<unsigned char>(s, 3, big_endian);
  for (std::uint32_t i : {0u, 1u, 4u}) put(s, i, big_endian);
  put<std::uint16_t>(s, 0, big_endian);
  return s;
}

void check_fixture(const io::Mesh& m) {
  REQUIRE(m.positions.size() == 5);
  CHECK(m.positions[4] == Vec3f(0.5f, 0.25f, -1.5f));
  REQUIRE(m.triangles.size() == 3);
  CHECK(m.triangles[0] == Vec3i(0, 1, 2));
  CHECK(m.triangles[1] == Vec3i(0, 2, 3));
  CHECK(m.triangles[2] == Vec3i(0, 1, 4));
}

}  // namespace

TEST_CASE("PLY: binary little and big endian with extra properties and elements") {
  TempDir dir;
  for (const bool big : {false, true}) {
    CAPTURE(big);
    write_text(dir / "m.ply", binary_ply(big));
    check_fixture(io::read_ply(dir / "m.ply"));
  }
}

TEST_CASE("PLY: ASCII with CRLF line ends, comments and obj_info") {
  TempDir dir;
  write_text(dir / "a.ply",
             "ply\r\nformat ascii 1.0\r\nobj_info made by hand\r\nelement vertex 5\r\nproperty float x\r\n"
             "property float y\r\nproperty float z\r\nelement face 2\r\nproperty list uchar int vertex_index\r\n"
             "end_header\r\n0 0 0\r\n1 0 0\r\n1 1 0\r\n0 1 0\r\n0.5 0.25 -1.5\r\n4 0 1 2 3\r\n3 0 1 4\r\n");
  check_fixture(io::read_ply(dir / "a.ply"));
}

TEST_CASE("PLY: write binary and ASCII, read back bit for bit") {
  TempDir dir;
  const auto m = uv_sphere(1.25, 6, 8, {0.3, 0.0, -7.0});
  for (const bool ascii : {false, true}) {
    io::write_ply(dir / "s.ply", m, ascii);
    std::vector<std::string> warnings;
    const io::Mesh back = io::read_ply(dir / "s.ply", &warnings);
    CHECK(warnings.empty());
    CHECK(back.positions == m.positions);
    CHECK(back.triangles == m.triangles);
  }
}

TEST_CASE("PLY: written with vertex normals, which readers that skip them ignore") {
  TempDir dir;
  const auto m = uv_sphere(1.0, 4, 6, {0.0, 0.0, 0.0});
  std::vector<Vec3f> normals;
  for (const Vec3f& p : m.positions) normals.push_back(p * 0.5f);
  for (const bool ascii : {false, true}) {
    io::write_ply(dir / "n.ply", m, ascii, &normals);
    const io::Mesh back = io::read_ply(dir / "n.ply");
    CHECK(back.positions == m.positions);
    CHECK(back.triangles == m.triangles);
    const std::string text = io::detail::read_file_text(dir / "n.ply");
    CHECK(contains(text, "property float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face"));
    const std::size_t body = text.find("end_header\n") + 11;
    if (ascii) {
      std::istringstream in(text.substr(body));
      for (std::size_t v = 0; v < m.positions.size(); ++v) {
        float x[6];
        for (float& c : x) in >> c;
        CHECK(Vec3f(x[3], x[4], x[5]) == normals[v]);
      }
    } else {
      for (std::size_t v = 0; v < m.positions.size(); ++v) {
        float n[3];
        std::memcpy(n, text.data() + body + v * 24 + 12, sizeof(n));  // little-endian host
        CHECK(Vec3f(n[0], n[1], n[2]) == normals[v]);
      }
    }
  }
  normals.pop_back();
  const std::string message = (dir / "bad.ply").string() + ": cannot write " + std::to_string(normals.size()) +
                              " normals for " + std::to_string(m.positions.size()) + " vertices";
  CHECK_THROWS_WITH_AS(io::write_ply(dir / "bad.ply", m, false, &normals), message.c_str(), io::Error);
}

TEST_CASE("PLY: written with vertex colours (uchar red green blue), positions read back unchanged") {
  TempDir dir;
  const auto m = uv_sphere(1.0, 4, 6, {0.0, 0.0, 0.0});
  std::vector<std::array<std::uint8_t, 3>> colours;
  for (std::size_t v = 0; v < m.positions.size(); ++v)
    colours.push_back({std::uint8_t(v), std::uint8_t(255 - v), std::uint8_t(7 * v)});
  for (const bool ascii : {false, true}) {
    io::write_ply(dir / "c.ply", m, ascii, nullptr, &colours);
    const io::Mesh back = io::read_ply(dir / "c.ply");
    CHECK(back.positions == m.positions);
    CHECK(back.triangles == m.triangles);
    const std::string text = io::detail::read_file_text(dir / "c.ply");
    CHECK(contains(text, "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face"));
    const std::size_t body = text.find("end_header\n") + 11;
    if (ascii) {
      std::istringstream in(text.substr(body));
      for (std::size_t v = 0; v < m.positions.size(); ++v) {
        float x[3];
        int c[3];
        in >> x[0] >> x[1] >> x[2] >> c[0] >> c[1] >> c[2];
        for (int k = 0; k < 3; ++k) CHECK(c[k] == int(colours[v][std::size_t(k)]));
      }
    } else {
      for (std::size_t v = 0; v < m.positions.size(); ++v)
        for (int k = 0; k < 3; ++k)
          CHECK(std::uint8_t(text[body + v * 15 + 12 + std::size_t(k)]) == colours[v][std::size_t(k)]);
    }
  }
  colours.pop_back();
  CHECK_THROWS_AS(io::write_ply(dir / "bad.ply", m, false, nullptr, &colours), io::Error);
}

TEST_CASE("PLY: bad input gives an Error naming the file and the problem") {
  TempDir dir;
  const auto path = dir / "bad.ply";
  const std::string f = path.string();
  const auto bad = [&](const std::string& bytes) {
    write_text(path, bytes);
    return error_of([&] { io::read_ply(path); });
  };
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  CHECK(bad("PLY\n") == f + ":1: not a PLY file (the first line is not \"ply\")");
  CHECK(bad("ply\nformat ascii 1.0\nelement vertex 3\n") == f + ": the header has no end_header line");
  CHECK(bad("ply\nformat ascii 2.0\nend_header\n") == f + ":2: unsupported PLY version '2.0'");
  CHECK(bad("ply\nformat text 1.0\nend_header\n") == f + ":2: unknown format 'text'");
  CHECK(bad("ply\nformat ascii 1.0\nelement vertex 3\nproperty real x\nend_header\n") ==
        f + ":4: unknown property type 'real'");
  CHECK(bad("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n") ==
        f + ":3: element count '-3' is not a non-negative integer");
  CHECK(bad("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n") ==
        f + ":3: element 'vertex' lacks one of the properties x, y, z");
  CHECK(bad("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n") ==
        f + ": no 'vertex' element");
  // body: out-of-range index, NaN vertex, junk, truncation (lines count from the file's start)
  CHECK(bad(head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n") == f + ":13: face 0: vertex index 3 is out of range [0, 3)");
  CHECK(bad(head + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n") == f + ":13: face 0: vertex index -1 is out of range [0, 3)");
  CHECK(bad(head + "0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n") == f + ":11: vertex 1 has a non-finite coordinate x");
  CHECK(bad(head + "0 0 0\n1 0 0\n0 1 oops\n3 0 1 2\n") == f + ":12: 'oops' is not a number, reading vertex 2");
  CHECK(bad(head + "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n") == f + ":13: '1.5' is not an integer, reading face 0");
  CHECK(bad(head + "0 0 0\n1 0 0\n") == f + ":12: unexpected end of file while reading vertex 2");
  // found by scripts/fuzz.sh: huge numbers in messages used to be cast to long (undefined behaviour)
  CHECK(contains(bad(head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 26666666666666666666666\n"),
                 ":13: face 0: vertex index 266666666666666"));  // printed as the double it was read as
  CHECK(contains(bad(head + "0 0 0\n1 0 0\n0 1 0\n2666666666666666666666666666666 0 1 2\n"),
                 "list length 2666666666666666"));
  // binary: a face list that runs past the end, an element count larger than the file
  std::string bin = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const size_t body = bin.size();
  for (int k = 0; k < 3; ++k) put<float>(bin, 0.0f, false);
  put<unsigned char>(bin, 200, false);
  CHECK(bad(bin) == f + ": face 0: list length 200 exceeds the file (byte offset " + std::to_string(body + 13) + ")");
  CHECK(bad("ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n") ==
        f + ":3: element 'vertex' declares 4000000000 entries, more than the file can hold");
  // a huge count on an element without properties reads nothing (no hang)
  write_text(path, "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                   "element nothing 99999999999\nend_header\n");
  CHECK(io::read_ply(path).positions.empty());
}

TEST_CASE("PLY: short faces and non-manifold faces are warnings naming face and line") {
  TempDir dir;
  write_text(dir / "w.ply",
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 3\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
             "2 0 1\n3 0 1 2\n3 0 1 1\n");
  std::vector<std::string> warnings;
  const io::Mesh m = io::read_ply(dir / "w.ply", &warnings);
  CHECK(m.triangles.size() == 2);
  const auto w = joined(warnings);
  CHECK(contains(w, "1 face(s) with fewer than 3 vertices ignored: face 0 (line 14)"));
  CHECK(contains(w, "face 2 (line 16) (vertices 0, 1, 1): repeated vertex"));
  CHECK(contains(w, "boundary edge(s)"));
}
