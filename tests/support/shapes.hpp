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

namespace dt_test {

struct Shape {
  std::vector<float> positions;
  std::vector<std::int32_t> triangles;
};

// Axis-aligned box centred at the origin with half extents (hx, hy, hz).
inline Shape make_box(float hx, float hy, float hz) {
  Shape s;
  for (int i = 0; i < 8; ++i) {
    s.positions.push_back(i & 1 ? hx : -hx);
    s.positions.push_back(i & 2 ? hy : -hy);
    s.positions.push_back(i & 4 ? hz : -hz);
  }
  // each face as a quad of corner ids, counter-clockwise seen from outside
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    for (int k : {q[0], q[1], q[2], q[0], q[2], q[3]}) s.triangles.push_back(k);
  }
  return s;
}

// Icosphere of the given radius: an icosahedron subdivided `levels` times.
inline Shape make_icosphere(float radius, int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<double> p = {-1, t, 0, 1, t, 0, -1, -t, 0, 1, -t, 0, 0, -1, t, 0, 1, t,
                           0, -1, -t, 0, 1, -t, t, 0, -1, t, 0, 1, -t, 0, -1, -t, 0, 1};
  std::vector<std::int32_t> f = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,
                                 11, 10, 2, 10, 7, 6, 7, 1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8,
                                 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
  const auto normalize = [&](std::size_t i) {
    const double l = std::sqrt(p[3 * i] * p[3 * i] + p[3 * i + 1] * p[3 * i + 1] + p[3 * i + 2] * p[3 * i + 2]);
    for (int k = 0; k < 3; ++k) p[3 * i + k] /= l;
  };
  for (std::size_t i = 0; i < p.size() / 3; ++i) normalize(i);
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    const auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      for (int k = 0; k < 3; ++k) p.push_back(0.5 * (p[3 * a + k] + p[3 * b + k]));
      const int id = int(p.size() / 3) - 1;
      normalize(std::size_t(id));
      mid[key] = id;
      return id;
    };
    std::vector<std::int32_t> g;
    for (std::size_t i = 0; i < f.size(); i += 3) {
      const int a = f[i], b = f[i + 1], c = f[i + 2];
      const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      for (int k : {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca}) g.push_back(k);
    }
    f.swap(g);
  }
  Shape s;
  for (double x : p) s.positions.push_back(float(x * radius));
  s.triangles = f;
  return s;
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
// whose gradients should see the look-up direction.
inline std::vector<float> smooth_sky(int w, int h) {
  std::vector<float> t;
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const float u = (col + 0.5f) / float(w), v = (row + 0.5f) / float(h);
      t.insert(t.end(), {0.6f + 0.4f * std::sin(6.2831853f * u), 0.5f + 0.4f * std::cos(3.14159f * v),
                         0.3f + 0.6f * u * v});
    }
  return t;
}

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
