// Test helpers for io and metrics: a temporary folder removed at the end of
// the test, file writers, the message of the io::Error a call throws, and
// small meshes built at test time.
#pragma once

#include <doctest/doctest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "difftrans/io/error.hpp"
#include "difftrans/io/mesh.hpp"

namespace dt_test {

namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("difftrans-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

inline void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  REQUIRE(out.good());
}

// Creates the folder a file will go in; returns the file's path.
inline const fs::path& in_new_dir(const fs::path& path) {
  fs::create_directories(path.parent_path());
  return path;
}

// The message of the io::Error that f() throws; fails the test (and returns
// "") when it throws nothing or something else.
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const difftrans::io::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    FAIL("expected io::Error, got another exception: " << e.what());
    return "";
  }
  FAIL("expected io::Error, nothing was thrown");
  return "";
}

inline bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// The joined warnings, for substring checks.
inline std::string joined(const std::vector<std::string>& warnings) {
  std::string s;
  for (const auto& w : warnings) s += w + "\n";
  return s;
}

// Unit cube [0, 1]^3, 8 vertices, 12 outward triangles.
inline difftrans::io::Mesh cube_mesh() {
  difftrans::io::Mesh m;
  for (int i = 0; i < 8; ++i) m.positions.emplace_back(float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1));
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.triangles.emplace_back(f[0], f[1], f[2]);
    m.triangles.emplace_back(f[0], f[2], f[3]);
  }
  return m;
}

// UV sphere of radius r about `centre`: poles on +-y, `rings` latitude bands,
// `segments` longitudes (a multiple of 4 puts vertices on +-x and +-z, so the
// bounding box is exactly the sphere's). Outward, closed, manifold.
inline difftrans::io::Mesh uv_sphere(double r, int rings, int segments,
                                     difftrans::Vec3d centre = difftrans::Vec3d(0.0)) {
  difftrans::io::Mesh m;
  const double pi = 3.14159265358979323846;
  m.positions.emplace_back(difftrans::Vec3d(0, r, 0) + centre);
  for (int i = 1; i < rings; ++i) {
    const double theta = pi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * pi * j / segments;
      m.positions.emplace_back(
          difftrans::Vec3d(r * std::sin(theta) * std::cos(phi), r * std::cos(theta), r * std::sin(theta) * std::sin(phi)) +
          centre);
    }
  }
  m.positions.emplace_back(difftrans::Vec3d(0, -r, 0) + centre);
  const int south = int(m.positions.size()) - 1;
  const auto at = [&](int ring, int j) { return 1 + (ring - 1) * segments + (j % segments); };
  for (int j = 0; j < segments; ++j) m.triangles.emplace_back(0, at(1, j + 1), at(1, j));
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      m.triangles.emplace_back(at(i, j), at(i, j + 1), at(i + 1, j + 1));
      m.triangles.emplace_back(at(i, j), at(i + 1, j + 1), at(i + 1, j));
    }
  for (int j = 0; j < segments; ++j) m.triangles.emplace_back(south, at(rings - 1, j), at(rings - 1, j + 1));
  return m;
}

}  // namespace dt_test
