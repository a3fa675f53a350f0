// Closed test meshes with outward, counter-clockwise triangles: boxes (a cube,
// a thin slab) and icospheres, as flat position / index arrays.
#pragma once

#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <algorithm>
#include <map>
#include <utility>
#include <vector>

#include "difftrans/geometry/procedural.hpp"
#include "difftrans/geometry/procedural.hpp"
#include "difftrans/scene/envmap.hpp"

namespace dt_test {

struct Shape {
  std::vector<float> positions;
  std::vector<std::int32_t> triangles;
};

// Axis-aligned box centred at the origin with half extents (hx, hy, hz)
// (the library's geometry::box).
inline Shape make_box(float hx, float hy, float hz) {
  difftrans::geometry::ProceduralMesh m = difftrans::geometry::box(hx, hy, hz);
  return Shape{std::move(m.positions), std::move(m.triangles)};
}

// Icosphere of the given radius: an icosahedron subdivided `levels` times
// (the library's geometry::icosphere).
inline Shape make_icosphere(float radius, int levels) {
  difftrans::geometry::ProceduralMesh m = difftrans::geometry::icosphere(radius, levels);
  return Shape{std::move(m.positions), std::move(m.triangles)};
}

// A torus about the z axis of n × m quads (two triangles each), major radius
// R, minor r; genus 1, outward counter-clockwise.
inline Shape make_torus(int n, int m, float R = 1.0f, float r = 0.35f) {
  Shape s;
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = 2 * pi * i / n, v = 2 * pi * j / m;
      s.positions.push_back(float((R + r * std::cos(v)) * std::cos(u)));
      s.positions.push_back(float((R + r * std::cos(v)) * std::sin(u)));
      s.positions.push_back(float(r * std::sin(v)));
    }
  const auto id = [&](int i, int j) { return ((i + n) % n) * m + (j + m) % m; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      for (int k : {a, b, c, a, c, d}) s.triangles.push_back(k);
    }
  return s;
}

// A smooth, varied w x h equirectangular environment (RGB texels) for tests
// whose gradients should see the look-up direction (the library's
// scene::varied_sky).
inline std::vector<float> smooth_sky(int w, int h) { return difftrans::scene::varied_sky(w, h); }

// The triangles of a data/ mesh ("v x y z", "f a b c", also a/b/c
// tokens), normalized as docs/conventions.md says: box centre at the origin, longest
// side 1. Enough for the closed, triangulated meshes the tests use.
inline Shape load_normalized_mesh(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  Shape s;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") {
      float x, y, z;
      ls >> x >> y >> z;
      s.positions.insert(s.positions.end(), {x, y, z});
    } else if (tag == "f") {
      std::string tok;
      while (ls >> tok) s.triangles.push_back(std::stoi(tok.substr(0, tok.find('/'))) - 1);
    }
  }
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (std::size_t i = 0; i < s.positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], s.positions[i]);
    hi[i % 3] = std::max(hi[i % 3], s.positions[i]);
  }
  const float scale = 1.0f / std::max(hi[0] - lo[0], std::max(hi[1] - lo[1], hi[2] - lo[2]));
  for (std::size_t i = 0; i < s.positions.size(); ++i)
    s.positions[i] = (s.positions[i] - 0.5f * (lo[i % 3] + hi[i % 3])) * scale;
  return s;
}

}  // namespace dt_test
