// Procedural closed meshes of known topology, for testing shape recovery:
// the boundary of a set of voxels, and a block pierced by N holes (genus N).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
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

// The boundary of the occupied voxels (unit cubes at integer corners): one
// quad (two triangles) per face between an occupied and an empty cell,
// vertices shared on the lattice. The result is a closed, consistently
// oriented surface; it is a 2-manifold when no two occupied voxels touch
// only along an edge or at a corner (voxel_shape_is_manifold checks that).
inline ProceduralMesh voxel_boundary(const VoxelShape& v) {
  ProceduralMesh m;
  const std::int64_t lx = v.nx + 1, ly = v.ny + 1, lz = v.nz + 1;
  std::vector<std::int32_t> id(std::size_t(lx * ly * lz), -1);
  const auto vertex = [&](int x, int y, int z) {
    std::int32_t& slot = id[std::size_t((std::int64_t(z) * ly + y) * lx + x)];
    if (slot < 0) {
      slot = std::int32_t(m.positions.size() / 3);
      m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
    }
    return slot;
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
            // the face's corners: (u, v) the two other axes in cyclic order, so eu × ev = e_a
            const int u = (a + 1) % 3, w = (a + 2) % 3;
            int p[4][3];
            for (int k = 0; k < 4; ++k) {
              p[k][0] = c[0], p[k][1] = c[1], p[k][2] = c[2];
              p[k][a] += sgn > 0 ? 1 : 0;
            }
            p[1][u] += 1;
            p[2][u] += 1, p[2][w] += 1;
            p[3][w] += 1;
            std::int32_t q[4];
            for (int k = 0; k < 4; ++k) q[k] = vertex(p[k][0], p[k][1], p[k][2]);
            if (sgn > 0)
              m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
            else
              m.triangles.insert(m.triangles.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
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

// Shapes by name: "holes-N" (block_with_holes(N)). Throws std::invalid_argument naming the value.
inline ProceduralMesh procedural_shape(const std::string& name) {
  const std::string prefix = "holes-";
  if (name.compare(0, prefix.size(), prefix) == 0) {
    const std::string digits = name.substr(prefix.size());
    bool ok = !digits.empty() && digits.size() <= 3;
    for (char c : digits) ok = ok && c >= '0' && c <= '9';
    if (ok) return voxel_boundary(block_with_holes(std::stoi(digits)));
  }
  throw std::invalid_argument("procedural shape '" + name + "' is not known (known: holes-N, N = 0..999)");
}

}  // namespace difftrans::geometry
