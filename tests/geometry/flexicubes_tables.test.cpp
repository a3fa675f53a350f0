// Properties of the derived FlexiCubes tables: numbering, every case's edge
// groups, symmetry under the 48 cube symmetries, and the ambiguous cases.
#include "difftrans/geometry/flexicubes_tables.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <set>
#include <vector>

namespace {

using namespace difftrans::geometry;
const FlexiCubesTables& tab = flexicubes_tables;

int inside_count(int c) {
  int n = 0;
  for (int k = 0; k < 8; ++k) n += (c >> k) & 1;
  return n;
}

bool changes(int c, int e) {
  return ((c >> flexicubes_edge_corners[e][0]) & 1) != ((c >> flexicubes_edge_corners[e][1]) & 1);
}

int edge_of(int a, int b) {
  for (int e = 0; e < 12; ++e) {
    const int x = flexicubes_edge_corners[e][0], y = flexicubes_edge_corners[e][1];
    if ((x == a && y == b) || (x == b && y == a)) return e;
  }
  return -1;
}

// A face is ambiguous when its four edges all change sign.
int ambiguous_faces(int c) {
  int n = 0;
  for (int f = 0; f < 6; ++f) {
    bool all = true;
    for (int k = 0; k < 4; ++k) all = all && changes(c, tab.face_edges[f][k]);
    n += all;
  }
  return n;
}

// The groups of a configuration as a set of edge masks.
std::set<unsigned> group_set(const FlexiCubesCase& cs) {
  std::set<unsigned> s;
  for (int g = 0; g < cs.num_groups; ++g) s.insert(cs.group_edges[g]);
  return s;
}

// The 48 symmetries of the cube as corner permutations: axes permuted by p, then reflected by mask r.
std::vector<std::array<int, 8>> cube_symmetries() {
  std::vector<std::array<int, 8>> out;
  std::array<int, 3> p = {0, 1, 2};
  do {
    for (int r = 0; r < 8; ++r) {
      std::array<int, 8> m{};
      for (int c = 0; c < 8; ++c) {
        int image = 0;
        for (int a = 0; a < 3; ++a) image |= (flexicubes_corner_offset(c, p[a]) ^ ((r >> a) & 1)) << a;
        m[std::size_t(c)] = image;
      }
      out.push_back(m);
    }
  } while (std::next_permutation(p.begin(), p.end()));
  return out;
}

}  // namespace

TEST_CASE("flexicubes_tables: numbering of corners, edges and faces") {
  std::set<std::pair<int, int>> seen;
  for (int e = 0; e < 12; ++e) {
    const int a = flexicubes_edge_corners[e][0], b = flexicubes_edge_corners[e][1];
    const int diff = a ^ b;
    CHECK((diff == 1 || diff == 2 || diff == 4));  // one axis apart: a cube edge
    CHECK((1 << tab.edge_axis[e]) == diff);
    CHECK(flexicubes_corner_offset(tab.edge_lower[e], tab.edge_axis[e]) == 0);
    seen.insert({std::min(a, b), std::max(a, b)});
  }
  CHECK(seen.size() == 12);
  // edge_at names each edge exactly once
  std::set<int> at;
  for (int a = 0; a < 3; ++a)
    for (int u = 0; u < 2; ++u)
      for (int v = 0; v < 2; ++v) {
        const int e = tab.edge_at[a][u][v];
        at.insert(e);
        CHECK(tab.edge_axis[e] == a);
        CHECK(flexicubes_corner_offset(tab.edge_lower[e], (a + 1) % 3) == u);
        CHECK(flexicubes_corner_offset(tab.edge_lower[e], (a + 2) % 3) == v);
      }
  CHECK(at.size() == 12);
  // each edge lies on exactly two faces; each face has 4 corners and 4 edges between them
  int on_faces[12] = {};
  for (int f = 0; f < 6; ++f)
    for (int k = 0; k < 4; ++k) {
      const int e = tab.face_edges[f][k];
      ++on_faces[e];
      const int a = flexicubes_edge_corners[e][0], b = flexicubes_edge_corners[e][1];
      CHECK(std::count(tab.face_corners[f], tab.face_corners[f] + 4, a) == 1);
      CHECK(std::count(tab.face_corners[f], tab.face_corners[f] + 4, b) == 1);
    }
  for (int e = 0; e < 12; ++e) CHECK(on_faces[e] == 2);
  // the design's examples: corner 3 at (1,1,0), edge 10 joins corners 7 and 5
  CHECK(flexicubes_corner_offset(3, 0) == 1);
  CHECK(flexicubes_corner_offset(3, 1) == 1);
  CHECK(flexicubes_corner_offset(3, 2) == 0);
  CHECK(edge_of(7, 5) == 10);
}

TEST_CASE("flexicubes_tables: every sign-changing edge in exactly one group, at most 4 groups") {
  int max_groups = 0;
  for (int cfg = 0; cfg < flexicubes_num_configs; ++cfg) {
    const int c = cfg & 255;
    const FlexiCubesCase& cs = tab.configs[cfg];
    CAPTURE(cfg);
    REQUIRE(cs.num_groups >= 0);
    REQUIRE(cs.num_groups <= flexicubes_max_groups);
    max_groups = std::max(max_groups, int(cs.num_groups));
    CHECK((cs.num_groups == 0) == (c == 0 || c == 255));
    unsigned all = 0;
    for (int g = 0; g < cs.num_groups; ++g) {
      CHECK(cs.group_edges[g] != 0);
      CHECK((all & cs.group_edges[g]) == 0);  // disjoint
      all |= cs.group_edges[g];
      // a group has at least 3 edges (a vertex's quads close a cycle around it)
      int n = 0;
      for (int e = 0; e < 12; ++e) n += (cs.group_edges[g] >> e) & 1;
      CHECK(n >= 3);
    }
    for (int e = 0; e < 12; ++e) {
      CHECK(((all >> e) & 1) == unsigned(changes(c, e)));
      if (changes(c, e)) {
        REQUIRE(cs.edge_group[e] >= 0);
        CHECK(((cs.group_edges[cs.edge_group[e]] >> e) & 1) == 1u);
      } else {
        CHECK(cs.edge_group[e] == -1);
      }
    }
    for (int g = cs.num_groups; g < flexicubes_max_groups; ++g) CHECK(cs.group_edges[g] == 0);
  }
  CHECK(max_groups == 4);
}

TEST_CASE("flexicubes_tables: in every group each edge meets one partner per face (a cycle)") {
  // Seen from a dual vertex, its quads form a closed fan only if every edge of
  // its group has exactly one other edge of the group on each of its two faces.
  for (int cfg = 0; cfg < flexicubes_num_configs; ++cfg) {
    const FlexiCubesCase& cs = tab.configs[cfg];
    for (int g = 0; g < cs.num_groups; ++g)
      for (int e = 0; e < 12; ++e) {
        if (!((cs.group_edges[g] >> e) & 1)) continue;
        for (int f = 0; f < 6; ++f) {
          if (std::count(tab.face_edges[f], tab.face_edges[f] + 4, e) == 0) continue;
          int partners = 0;
          for (int k = 0; k < 4; ++k) {
            const int o = tab.face_edges[f][k];
            partners += o != e && ((cs.group_edges[g] >> o) & 1);
          }
          CAPTURE(cfg);
          CAPTURE(e);
          CAPTURE(f);
          // an ambiguous face merged by the rule puts all four edges in one group
          if (tab.merged_face[cfg & 255] == f && cfg < 256)
            CHECK(partners == 3);
          else
            CHECK(partners == 1);
        }
      }
  }
}

TEST_CASE("flexicubes_tables: hand-derived cases") {
  // corner 0 alone inside: its three edges, 0-1, 0-4, 2-0
  CHECK(tab.configs[1].num_groups == 1);
  CHECK(tab.configs[1].group_edges[0] == ((1u << 0) | (1u << 3) | (1u << 8)));
  // corners 0 and 3 inside: face z = 0 is ambiguous and split around them
  const unsigned around0 = (1u << 0) | (1u << 3) | (1u << 8);
  const unsigned around3 = (1u << edge_of(2, 3)) | (1u << edge_of(3, 7)) | (1u << edge_of(3, 1));
  CHECK(group_set(tab.configs[9]) == std::set<unsigned>{around0, around3});
  CHECK(tab.merged_face[9] == -1);
  // the complement: six corners inside, the rule merges everything through face z = 0
  CHECK(tab.configs[246].num_groups == 1);
  CHECK(tab.merged_face[246] == 4);
  CHECK(group_set(tab.configs[256 + 246]) == std::set<unsigned>{around0, around3});
  // corners 0 and 7 inside (opposite): two separate groups, no ambiguous face
  CHECK(tab.configs[129].num_groups == 2);
}

TEST_CASE("flexicubes_tables: the groups commute with the 48 symmetries of the cube") {
  const auto syms = cube_symmetries();
  REQUIRE(syms.size() == 48);
  for (const auto& m : syms) {
    int edge_map[12];
    for (int e = 0; e < 12; ++e) edge_map[e] = edge_of(m[std::size_t(flexicubes_edge_corners[e][0])],
                                                       m[std::size_t(flexicubes_edge_corners[e][1])]);
    for (int c = 0; c < 256; ++c) {
      int image = 0;
      for (int k = 0; k < 8; ++k) image |= ((c >> k) & 1) << m[std::size_t(k)];
      std::set<unsigned> mapped;
      for (unsigned g : group_set(tab.configs[c])) {
        unsigned h = 0;
        for (int e = 0; e < 12; ++e)
          if ((g >> e) & 1) h |= 1u << edge_map[e];
        mapped.insert(h);
      }
      CAPTURE(c);
      CHECK(mapped == group_set(tab.configs[image]));
      CHECK((tab.merged_face[c] < 0) == (tab.merged_face[image] < 0));
    }
  }
}

TEST_CASE("flexicubes_tables: complementary cases differ only on ambiguous faces") {
  int counts[5] = {};
  for (int c = 0; c < 256; ++c) {
    ++counts[tab.configs[c].num_groups];
    if (ambiguous_faces(c) == 0) {
      CAPTURE(c);
      CHECK(group_set(tab.configs[c]) == group_set(tab.configs[255 - c]));
    }
  }
  int total = 0;
  for (int k = 0; k <= 4; ++k) total += counts[k];
  CHECK(total == 256);
  CHECK(counts[0] == 2);
  MESSAGE("cases with 0..4 dual vertices: " << counts[0] << " " << counts[1] << " " << counts[2] << " "
                                            << counts[3] << " " << counts[4]);
}

TEST_CASE("flexicubes_tables: the 36 cases that look across an ambiguous face") {
  int merged = 0, five = 0, six = 0;
  for (int c = 0; c < 256; ++c) {
    const int f = tab.merged_face[c];
    if (f < 0) {
      // no merged face: the alternate configuration is the same
      CHECK(group_set(tab.configs[256 + c]) == group_set(tab.configs[c]));
      continue;
    }
    CAPTURE(c);
    ++merged;
    five += inside_count(c) == 5;
    six += inside_count(c) == 6;
    CHECK(ambiguous_faces(c) == 1);
    CHECK(tab.configs[c].num_groups == 1);
    // the other split of that face separates the two pairs: two vertices
    CHECK(tab.configs[256 + c].num_groups == 2);
    // and it is the split the complementary case gets from the rule
    CHECK(group_set(tab.configs[256 + c]) == group_set(tab.configs[255 - c]));
    // the face's inside corners are diagonal
    int in = 0;
    for (int k = 0; k < 4; ++k) in += (c >> tab.face_corners[f][k]) & 1;
    CHECK(in == 2);
  }
  CHECK(merged == 36);
  CHECK(five + six == 36);
  MESSAGE("merged cases with 5 inside corners: " << five << ", with 6: " << six);
}
