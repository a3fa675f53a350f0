// FlexiCubes lookup tables, derived at compile time from the dual-vertex rule
// (no pasted table): cube numbering, per-case dual-vertex edge groups, ambiguous cases.
#pragma once

#include <cstdint>

#include "difftrans/core/platform.hpp"

namespace difftrans::geometry {

// ------------------------------------------------------------- numbering
// Corner c of a cube sits at offset ((c >> 0) & 1, (c >> 1) & 1, (c >> 2) & 1):
// (0,0,0) (1,0,0) (0,1,0) (1,1,0) (0,0,1) (1,0,1) (0,1,1) (1,1,1).
// Edges are corner pairs in the FlexiCubes order. A case id is
// sum over corners of occ_c << c with occ_c = (s_c < 0), "inside".
// Faces are numbered 2 * axis + side: the four corners whose coordinate on
// `axis` equals `side`.
inline constexpr int flexicubes_edge_corners[12][2] = {{0, 1}, {1, 5}, {4, 5}, {0, 4}, {2, 3}, {3, 7},
                                                       {6, 7}, {2, 6}, {2, 0}, {3, 1}, {7, 5}, {6, 4}};
inline constexpr int flexicubes_max_groups = 4;  // dual vertices per cube, at most

DT_HOST_DEVICE constexpr int flexicubes_corner_offset(int corner, int axis) { return (corner >> axis) & 1; }

// One case's dual vertices: each group of sign-changing edges is one vertex.
struct FlexiCubesCase {
  std::int8_t num_groups = 0;
  std::int8_t edge_group[12] = {-1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1};  // -1: no sign change
  std::uint16_t group_edges[flexicubes_max_groups] = {0, 0, 0, 0};  // bit e set: edge e belongs to the group
};

// Configurations: index c (< 256) is case c under the rule; index 256 + c is
// case c with its merged ambiguous face split the other way (joined around
// the outside corners), used when the neighbour across that face has merged
// it too. For cases without a merged face both entries are equal.
inline constexpr int flexicubes_num_configs = 512;

struct FlexiCubesTables {
  FlexiCubesCase configs[flexicubes_num_configs];
  // The ambiguous face (2 * axis + side) whose two edge pairs the rule merged
  // into one dual vertex, or -1. Non-negative for exactly the cases that must
  // look at the neighbouring cube across that face.
  std::int8_t merged_face[256] = {};
  std::int8_t edge_axis[12] = {};        // axis along which edge e runs
  std::int8_t edge_lower[12] = {};       // the corner of edge e at the lower coordinate
  std::int8_t edge_at[3][2][2] = {};     // edge along axis a at offsets (u, v) on axes (a + 1) % 3, (a + 2) % 3
  std::int8_t face_edges[6][4] = {};     // the four edges lying on face f
  std::int8_t face_corners[6][4] = {};   // the four corners of face f
};

namespace detail {

constexpr int fc_find(int* parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

constexpr void fc_join(int* parent, int a, int b) {
  a = fc_find(parent, a);
  b = fc_find(parent, b);
  if (a != b) parent[a < b ? b : a] = a < b ? a : b;  // the smaller edge id is the root
}

constexpr bool fc_on_face(int corner, int face) { return flexicubes_corner_offset(corner, face / 2) == face % 2; }

constexpr bool fc_edge_on_face(int e, int face) {
  return fc_on_face(flexicubes_edge_corners[e][0], face) && fc_on_face(flexicubes_edge_corners[e][1], face);
}

constexpr bool fc_edge_has_corner(int e, int corner) {
  return flexicubes_edge_corners[e][0] == corner || flexicubes_edge_corners[e][1] == corner;
}

constexpr bool fc_changes(int case_id, int e) {
  return ((case_id >> flexicubes_edge_corners[e][0]) & 1) != ((case_id >> flexicubes_edge_corners[e][1]) & 1);
}

// The rule. Two sign-changing edges on the same face are joined; on an
// ambiguous face (all four edges change sign) the two edges around each inside
// corner are joined instead, except on face `flip_face`, where the two edges
// around each outside corner are joined. Connected groups of edges are the
// dual vertices, numbered in the order of their smallest edge.
constexpr FlexiCubesCase fc_group_edges(int case_id, int flip_face) {
  int parent[12] = {};
  for (int e = 0; e < 12; ++e) parent[e] = e;
  for (int f = 0; f < 6; ++f) {
    int changing[4] = {}, n = 0;
    for (int e = 0; e < 12; ++e)
      if (fc_edge_on_face(e, f) && fc_changes(case_id, e)) changing[n++] = e;
    if (n == 2) {
      fc_join(parent, changing[0], changing[1]);
    } else if (n == 4) {
      for (int c = 0; c < 8; ++c) {
        if (!fc_on_face(c, f)) continue;
        const bool inside = (case_id >> c) & 1;
        if (inside == (f == flip_face)) continue;  // join around inside corners (outside ones on flip_face)
        int around[2] = {}, m = 0;
        for (int k = 0; k < 4; ++k)
          if (fc_edge_has_corner(changing[k], c)) around[m++] = changing[k];
        fc_join(parent, around[0], around[1]);
      }
    }
  }
  FlexiCubesCase r{};
  int root_group[12] = {-1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1};
  for (int e = 0; e < 12; ++e) {
    if (!fc_changes(case_id, e)) continue;
    const int root = fc_find(parent, e);
    if (root_group[root] < 0) root_group[root] = r.num_groups++;
    const int g = root_group[root];
    r.edge_group[e] = std::int8_t(g);
    if (g < flexicubes_max_groups) r.group_edges[g] = std::uint16_t(r.group_edges[g] | (1u << e));
  }
  return r;
}

// The ambiguous face whose two edge pairs ended up in one group, or -1.
constexpr int fc_merged_face(int case_id, const FlexiCubesCase& c) {
  for (int f = 0; f < 6; ++f) {
    int group = -2;
    bool all_change = true, merged = true;
    for (int e = 0; e < 12; ++e) {
      if (!fc_edge_on_face(e, f)) continue;
      all_change = all_change && fc_changes(case_id, e);
      if (group == -2) group = c.edge_group[e];
      merged = merged && c.edge_group[e] == group;
    }
    if (all_change && merged) return f;
  }
  return -1;
}

constexpr FlexiCubesTables fc_build_tables() {
  FlexiCubesTables t{};
  for (int e = 0; e < 12; ++e) {
    const int a = flexicubes_edge_corners[e][0], b = flexicubes_edge_corners[e][1];
    const int diff = a ^ b;
    const int axis = diff == 1 ? 0 : (diff == 2 ? 1 : 2);
    t.edge_axis[e] = std::int8_t(axis);
    t.edge_lower[e] = std::int8_t(flexicubes_corner_offset(a, axis) == 0 ? a : b);
    const int lo = t.edge_lower[e];
    t.edge_at[axis][flexicubes_corner_offset(lo, (axis + 1) % 3)][flexicubes_corner_offset(lo, (axis + 2) % 3)] =
        std::int8_t(e);
  }
  for (int f = 0; f < 6; ++f) {
    int ne = 0, nc = 0;
    for (int e = 0; e < 12; ++e)
      if (fc_edge_on_face(e, f)) t.face_edges[f][ne++] = std::int8_t(e);
    for (int c = 0; c < 8; ++c)
      if (fc_on_face(c, f)) t.face_corners[f][nc++] = std::int8_t(c);
  }
  for (int c = 0; c < 256; ++c) {
    t.configs[c] = fc_group_edges(c, -1);
    const int f = fc_merged_face(c, t.configs[c]);
    t.merged_face[c] = std::int8_t(f);
    t.configs[256 + c] = f < 0 ? t.configs[c] : fc_group_edges(c, f);
  }
  return t;
}

}  // namespace detail

// Built once, at compile time.
inline constexpr FlexiCubesTables flexicubes_tables = detail::fc_build_tables();

}  // namespace difftrans::geometry
