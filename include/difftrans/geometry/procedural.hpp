// Procedural closed meshes of known topology, for testing shape recovery:
// the boundary of a set of voxels, a block pierced by N holes (genus N), and
// an icosphere.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace difftrans::geometry {

struct VoxelShape {
  int nx = 0, ny = 0, nz = 0;
  std::vector<std::uint8_t> occupied;  // nx·ny·nz, x fastest
  bool at(int x, int y, int z) const {
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return false;
    return occupied[(std::size_t(z) * std::size_t(ny) + std::size_t(y)) * std::size_t(nx) + std::size_t(x)] != 0;
  }
};

struct ProceduralMesh {
  std::vector<float> positions;        // 3 per vertex
  std::vector<std::int32_t> triangles;  // 3 per face, counter-clockwise seen from outside
};

// The boundary of the occupied voxels (unit cubes at integer corners): each
// face between an occupied and an empty cell cut into subdivisions ×
// subdivisions quads (two triangles each), vertices shared on the lattice of
// spacing 1 / subdivisions. The result is a closed, consistently oriented
// surface; it is a 2-manifold when no two occupied voxels touch only along
// an edge or at a corner (voxel_shape_is_manifold checks that).
//
// Why subdivide: a tracer that shades with vertex normals (the mean of the
// faces' normals around each vertex, scene/mesh.hpp) bends every triangle
// that touches an edge of the box. With one quad per voxel face that is
// every triangle: a slab two voxels thick is shaded as if its sides were
// round, and images rendered from it show an object whose optical normals
// are not its geometry's, which no finer mesh of the same surface can
// reproduce. Cut into s × s quads, the bent band along each edge is 1 / s of
// a voxel wide.
inline ProceduralMesh voxel_boundary(const VoxelShape& v, int subdivisions = 1) {
  if (subdivisions < 1) throw std::invalid_argument("voxel_boundary: subdivisions >= 1 expected");
  ProceduralMesh m;
  const std::int64_t s = subdivisions;
  const std::int64_t lx = v.nx * s + 1, ly = v.ny * s + 1;
  std::unordered_map<std::int64_t, std::int32_t> id;
  const float unit = 1.0f / float(subdivisions);
  const auto vertex = [&](const std::int64_t q[3]) {  // q on the fine lattice
    const auto [it, added] = id.emplace((q[2] * ly + q[1]) * lx + q[0], std::int32_t(m.positions.size() / 3));
    if (added) m.positions.insert(m.positions.end(), {float(q[0]) * unit, float(q[1]) * unit, float(q[2]) * unit});
    return it->second;
  };
  for (int z = 0; z < v.nz; ++z)
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < v.nx; ++x) {
        if (!v.at(x, y, z)) continue;
        const int c[3] = {x, y, z};
        for (int a = 0; a < 3; ++a)
          for (int sgn = -1; sgn <= 1; sgn += 2) {
            int n[3] = {c[0], c[1], c[2]};
            n[a] += sgn;
            if (v.at(n[0], n[1], n[2])) continue;
            // the face's axes (u, w) in cyclic order after a, so e_u × e_w = e_a
            const int u = (a + 1) % 3, w = (a + 2) % 3;
            std::int64_t origin[3] = {c[0] * s, c[1] * s, c[2] * s};
            origin[a] += sgn > 0 ? s : 0;
            for (std::int64_t i = 0; i < s; ++i)
              for (std::int64_t j = 0; j < s; ++j) {
                std::int64_t p[4][3];
                for (int k = 0; k < 4; ++k) {
                  for (int d = 0; d < 3; ++d) p[k][d] = origin[d];
                  p[k][u] += i + (k == 1 || k == 2 ? 1 : 0);
                  p[k][w] += j + (k == 2 || k == 3 ? 1 : 0);
                }
                std::int32_t q[4];
                for (int k = 0; k < 4; ++k) q[k] = vertex(p[k]);
                if (sgn > 0)
                  m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
                else
                  m.triangles.insert(m.triangles.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
              }
          }
      }
  return m;
}

// True when no two occupied voxels meet only along an edge or at a corner
// (inspects every 2×2×2 block of cells, including those past the border).
inline bool voxel_shape_is_manifold(const VoxelShape& v) {
  for (int z = -1; z < v.nz; ++z)
    for (int y = -1; y < v.ny; ++y)
      for (int x = -1; x < v.nx; ++x) {
        bool o[8];
        for (int k = 0; k < 8; ++k) o[k] = v.at(x + (k & 1), y + ((k >> 1) & 1), z + ((k >> 2) & 1));
        // two diagonal cells occupied in a 2×2 face layer while both others are empty
        for (int a = 0; a < 3; ++a)
          for (int layer = 0; layer < 2; ++layer) {
            int cell[4], n = 0;
            for (int k = 0; k < 8; ++k)
              if (((k >> a) & 1) == layer) cell[n++] = k;
            // cell[0], cell[3] diagonal; cell[1], cell[2] diagonal
            if (o[cell[0]] && o[cell[3]] && !o[cell[1]] && !o[cell[2]]) return false;
            if (o[cell[1]] && o[cell[2]] && !o[cell[0]] && !o[cell[3]]) return false;
          }
        // opposite corners of the block occupied, nothing else around them
        for (int k = 0; k < 4; ++k) {
          const int j = 7 - k;
          if (!o[k] || !o[j]) continue;
          int others = 0;
          for (int i = 0; i < 8; ++i)
            if (i != k && i != j && o[i]) ++others;
          if (others == 0) return false;
        }
      }
  return true;
}

// A slab pierced by `holes` square holes in a row: genus `holes`. Holes of
// `hole` × `hole` voxels, bars `bar` voxels wide, the slab `thickness` voxels
// thick along z (the holes go through along z).
inline VoxelShape block_with_holes(int holes, int hole = 2, int bar = 1, int thickness = 2) {
  if (holes < 0 || hole < 1 || bar < 1 || thickness < 1)
    throw std::invalid_argument("block_with_holes: holes >= 0 and hole, bar, thickness >= 1 expected");
  VoxelShape v;
  v.nx = bar + holes * (hole + bar);
  v.ny = 2 * bar + hole;
  v.nz = thickness;
  v.occupied.assign(std::size_t(v.nx) * std::size_t(v.ny) * std::size_t(v.nz), 1);
  for (int z = 0; z < v.nz; ++z)
    for (int y = bar; y < bar + hole; ++y)
      for (int x = 0; x < v.nx; ++x)
        if (x % (hole + bar) >= bar) v.occupied[(std::size_t(z) * std::size_t(v.ny) + std::size_t(y)) * std::size_t(v.nx) + std::size_t(x)] = 0;
  return v;
}

// An axis-aligned box centred at the origin with half extents (hx, hy, hz):
// 8 corners, each face two counter-clockwise triangles seen from outside.
inline ProceduralMesh box(float hx, float hy, float hz) {
  ProceduralMesh m;
  for (int i = 0; i < 8; ++i) m.positions.insert(m.positions.end(), {i & 1 ? hx : -hx, i & 2 ? hy : -hy, i & 4 ? hz : -hz});
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    for (int k : {q[0], q[1], q[2], q[0], q[2], q[3]}) m.triangles.push_back(k);
  return m;
}

// A sphere of `radius`: an icosahedron whose faces are split in four
// `levels` times, every new vertex pushed onto the sphere (20·4^levels
// triangles, 10·4^levels + 2 vertices).
inline ProceduralMesh icosphere(float radius, int levels) {
  if (levels < 0 || levels > 9) throw std::invalid_argument("icosphere: levels 0..9 expected");
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;  // the golden ratio: the icosahedron's corners
  std::vector<double> p = {-1, g, 0, 1, g, 0, -1, -g, 0, 1, -g, 0, 0, -1, g, 0, 1, g,
                           0, -1, -g, 0, 1, -g, g, 0, -1, g, 0, 1, -g, 0, -1, -g, 0, 1};
  std::vector<std::int32_t> f = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,
                                 11, 10, 2, 10, 7, 6, 7, 1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8,
                                 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
  const auto onto_sphere = [&p](std::size_t i) {
    const double l = std::sqrt(p[3 * i] * p[3 * i] + p[3 * i + 1] * p[3 * i + 1] + p[3 * i + 2] * p[3 * i + 2]);
    for (int k = 0; k < 3; ++k) p[3 * i + k] /= l;
  };
  for (std::size_t i = 0; i < p.size() / 3; ++i) onto_sphere(i);
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> middle;  // an edge's new vertex, shared by its two faces
    const auto split = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto found = middle.find(key);
      if (found != middle.end()) return found->second;
      for (int k = 0; k < 3; ++k) p.push_back(0.5 * (p[3 * std::size_t(a) + std::size_t(k)] + p[3 * std::size_t(b) + std::size_t(k)]));
      const int id = int(p.size() / 3) - 1;
      onto_sphere(std::size_t(id));
      middle[key] = id;
      return id;
    };
    std::vector<std::int32_t> finer;
    finer.reserve(4 * f.size());
    for (std::size_t i = 0; i < f.size(); i += 3) {
      const int a = f[i], b = f[i + 1], c = f[i + 2];
      const int ab = split(a, b), bc = split(b, c), ca = split(c, a);
      for (int k : {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca}) finer.push_back(k);
    }
    f.swap(finer);
  }
  ProceduralMesh m;
  m.positions.reserve(p.size());
  for (double x : p) m.positions.push_back(float(x * radius));
  m.triangles = std::move(f);
  return m;
}

namespace detail {
// The non-negative integer after `prefix` in `name` (at most `digits` digits), or -1.
inline int shape_number(const std::string& name, const std::string& prefix, std::size_t digits) {
  if (name.compare(0, prefix.size(), prefix) != 0) return -1;
  const std::string rest = name.substr(prefix.size());
  if (rest.empty() || rest.size() > digits) return -1;
  for (char c : rest)
    if (c < '0' || c > '9') return -1;
  return std::stoi(rest);
}
}  // namespace detail

// Shapes by name: "holes-N" (block_with_holes(N), each voxel face cut into
// subdivisions² quads), "sphere-L" (icosphere of radius 1, L = 0..9 levels).
// Throws std::invalid_argument naming the value.
inline ProceduralMesh procedural_shape(const std::string& name, int subdivisions = 1) {
  const int holes = detail::shape_number(name, "holes-", 3);
  if (holes >= 0) return voxel_boundary(block_with_holes(holes), subdivisions);
  const int levels = detail::shape_number(name, "sphere-", 1);
  if (levels >= 0) return icosphere(1.0f, levels);
  throw std::invalid_argument("procedural shape '" + name + "' is not known (known: holes-N, N = 0..999; sphere-L, L = 0..9)");
}

}  // namespace difftrans::geometry
