// FlexiCubes extraction: closed oriented 2-manifolds for every case and random
// grids, spheres within the resolution, genus, the split rules, and gradients.
#include "difftrans/geometry/flexicubes.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "support/ad_check.hpp"
#include "support/flexicubes_grid.hpp"

namespace {

using namespace difftrans;
using namespace difftrans::geometry;

// ------------------------------------------------------------------ helpers

using dt_test::GridData;

// Checks that the triangles form a closed, consistently oriented 2-manifold:
// every directed edge occurs once and its reverse once (so every edge has
// exactly two faces, of opposite orientation), no triangle repeats a vertex,
// every vertex is used, and the triangles around each vertex form one fan.
// Returns an empty string, or what is wrong.
std::string manifold_problem(const std::vector<std::int32_t>& tris, std::int32_t num_vertices) {
  const std::size_t nt = tris.size() / 3;
  std::vector<std::uint64_t> directed;
  directed.reserve(3 * nt);
  auto key = [](std::int32_t a, std::int32_t b) { return std::uint64_t(std::uint32_t(a)) << 32 | std::uint32_t(b); };
  for (std::size_t t = 0; t < nt; ++t) {
    const std::int32_t* p = &tris[3 * t];
    if (p[0] == p[1] || p[1] == p[2] || p[2] == p[0]) return "degenerate triangle " + std::to_string(t);
    for (int m = 0; m < 3; ++m) {
      if (p[m] < 0 || p[m] >= num_vertices) return "index out of range";
      directed.push_back(key(p[m], p[(m + 1) % 3]));
    }
  }
  std::sort(directed.begin(), directed.end());
  if (std::adjacent_find(directed.begin(), directed.end()) != directed.end())
    return "a directed edge occurs twice (more than two faces or inconsistent orientation)";
  for (std::uint64_t d : directed) {
    const std::uint64_t r = (d << 32) | (d >> 32);
    if (!std::binary_search(directed.begin(), directed.end(), r)) return "an edge with only one face (open boundary)";
  }
  // fans: at vertex v, each triangle (v, a, b) links a -> b; one cycle through all of them
  std::vector<std::vector<std::pair<std::int32_t, std::int32_t>>> around(static_cast<std::size_t>(num_vertices));
  for (std::size_t t = 0; t < nt; ++t) {
    const std::int32_t* p = &tris[3 * t];
    for (int m = 0; m < 3; ++m) around[std::size_t(p[m])].push_back({p[(m + 1) % 3], p[(m + 2) % 3]});
  }
  for (std::int32_t v = 0; v < num_vertices; ++v) {
    auto& fan = around[std::size_t(v)];
    if (fan.empty()) return "vertex " + std::to_string(v) + " is unused";
    std::sort(fan.begin(), fan.end());
    std::int32_t cur = fan[0].first;
    std::size_t steps = 0;
    do {
      auto it = std::lower_bound(fan.begin(), fan.end(), std::make_pair(cur, std::int32_t(-1)));
      if (it == fan.end() || it->first != cur) return "broken fan at vertex " + std::to_string(v);
      cur = it->second;
      ++steps;
    } while (cur != fan[0].first && steps <= fan.size());
    if (steps != fan.size()) return "vertex " + std::to_string(v) + " is not a single fan (pinched)";
  }
  return "";
}

struct Components {
  int count = 0;
  std::vector<int> of_vertex;
};

Components components(const std::vector<std::int32_t>& tris, std::int32_t num_vertices) {
  std::vector<int> parent(static_cast<std::size_t>(num_vertices));
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int x) { return parent[std::size_t(x)] == x ? x : parent[std::size_t(x)] = find(parent[std::size_t(x)]); };
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
    parent[std::size_t(find(tris[t]))] = find(tris[t + 1]);
    parent[std::size_t(find(tris[t + 1]))] = find(tris[t + 2]);
  }
  Components c;
  std::vector<int> id(std::size_t(num_vertices), -1);
  c.of_vertex.resize(std::size_t(num_vertices));
  for (int v = 0; v < num_vertices; ++v) {
    int& r = id[std::size_t(find(v))];
    if (r < 0) r = c.count++;
    c.of_vertex[std::size_t(v)] = r;
  }
  return c;
}

// V - E + F of a closed mesh, per component (every edge has two faces: E = 3F / 2).
std::vector<int> euler_characteristics(const std::vector<std::int32_t>& tris, std::int32_t num_vertices) {
  const Components comp = components(tris, num_vertices);
  std::vector<int> vertices(std::size_t(comp.count), 0), faces(std::size_t(comp.count), 0), chi;
  for (int v = 0; v < num_vertices; ++v) ++vertices[std::size_t(comp.of_vertex[std::size_t(v)])];
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) ++faces[std::size_t(comp.of_vertex[std::size_t(tris[t])])];
  for (int c = 0; c < comp.count; ++c) chi.push_back(vertices[std::size_t(c)] - 3 * faces[std::size_t(c)] / 2 + faces[std::size_t(c)]);
  return chi;
}

template <class S>
std::vector<Vec3d> positions_d(const FlexiCubesMesh<S>& m) {
  std::vector<Vec3d> p;
  for (const auto& v : m.vertices) p.push_back(Vec3d(ad::value_of(v)));
  return p;
}

// Enclosed signed volume per component (positive when faces point outward).
std::vector<double> volumes(const std::vector<Vec3d>& p, const std::vector<std::int32_t>& tris) {
  const Components comp = components(tris, std::int32_t(p.size()));
  std::vector<double> vol(std::size_t(comp.count), 0.0);
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3)
    vol[std::size_t(comp.of_vertex[std::size_t(tris[t])])] +=
        glm::dot(p[std::size_t(tris[t])], glm::cross(p[std::size_t(tris[t + 1])], p[std::size_t(tris[t + 2])])) / 6.0;
  return vol;
}

// Every quad's vector area points from the inside end of its grid edge to the
// outside end (holds without deformation: each dual vertex lies in its cube).
template <class S>
int misoriented_quads(const FlexiCubesGrid& grid, const FlexiCubesMesh<S>& m, const std::vector<float>& sdf) {
  const auto p = positions_d(m);
  int bad = 0;
  for (std::int32_t q = 0; q < m.num_quads(); ++q) {
    const std::int32_t a = m.quad_edges[std::size_t(2 * q)], b = m.quad_edges[std::size_t(2 * q + 1)];
    const int V = grid.res + 1;
    const int axis = b - a == 1 ? 0 : (b - a == V ? 1 : 2);
    Vec3d area(0.0);
    for (int k = 0; k < 4; ++k)
      area += glm::cross(p[std::size_t(m.quads[std::size_t(4 * q + k)])],
                         p[std::size_t(m.quads[std::size_t(4 * q + (k + 1) % 4)])]) * 0.5;
    const double outward = sdf[std::size_t(a)] < 0.0f ? 1.0 : -1.0;
    bad += !(area[axis] * outward > 0.0);
  }
  return bad;
}

// Extracts with S = double and checks manifoldness; returns the problem text.
std::string check_grid(const GridData& g, const FlexiCubesOptions& opt = {}) {
  const auto mesh = flexicubes_extract<double>(g.grid, g.inputs(), opt);
  return manifold_problem(mesh.triangles, std::int32_t(mesh.vertices.size()));
}

// A res-`res` grid over [0, res]^3 whose vertices in [1, res - 1]^3 take the
// signs of `bits` (bit n for the n-th inner vertex in x-fastest order), with
// magnitudes from rng; every other vertex is +1.
GridData inner_pattern(int res, const int lo[3], const int hi[3], std::uint32_t bits, std::mt19937& rng) {
  GridData g(res, Vec3f(0.0f), Vec3f(float(res)));
  std::uniform_real_distribution<float> mag(0.1f, 1.0f);
  int n = 0;
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i, ++n)
        g.sdf[std::size_t(g.grid.vertex_index(i, j, k))] = ((bits >> n) & 1) ? -mag(rng) : mag(rng);
  return g;
}

double sphere_sdf(Vec3f p, float r) { return double(glm::length(p)) - r; }

double torus_sdf(Vec3f p, float big, float small) {
  const double q = std::sqrt(double(p.x) * p.x + double(p.y) * p.y) - big;
  return std::sqrt(q * q + double(p.z) * p.z) - small;
}

double box_sdf(Vec3f p, Vec3f half) {
  const Vec3f d = glm::abs(p) - half;
  return double(glm::length(glm::max(d, Vec3f(0.0f)))) + std::min(0.0, double(std::max(d.x, std::max(d.y, d.z))));
}

}  // namespace

// --------------------------------------------------------- small pieces

TEST_CASE("flexicubes: weight squashing and crossing formula") {
  for (double raw : {-50.0, -2.0, -0.3, 0.0, 0.7, 3.0, 50.0}) {
    const double a = flexicubes_squash_weight(raw), g = flexicubes_squash_gamma(raw);
    CHECK(a >= 0.01);
    CHECK(a <= 1.99);
    CHECK(g >= 0.005);
    CHECK(g <= 0.995);
    CHECK(a == doctest::Approx(0.99 * std::tanh(raw) + 1.0));
    CHECK(g == doctest::Approx(0.99 / (1.0 + std::exp(-raw)) + 0.005));
  }
  CHECK(flexicubes_squash_weight(0.0) == 1.0);
  // crossing = (s̃a xb - s̃b xa) / (s̃a - s̃b), the paper's form
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0), pos(0.05, 1.0), w(0.01, 1.99);
  for (int n = 0; n < 100; ++n) {
    const Vec3d xa(u(rng), u(rng), u(rng)), xb(u(rng), u(rng), u(rng));
    const double sa = -pos(rng), sb = pos(rng), aa = w(rng), ab = w(rng);
    const Vec3d c = flexicubes_crossing(xa, sa, aa, xb, sb, ab);
    const Vec3d paper = (aa * sa * xb - ab * sb * xa) / (aa * sa - ab * sb);
    CHECK(glm::length(c - paper) < 1e-12);
    // on the segment, and a larger α at a pushes the crossing away from a
    const double t = glm::length(c - xa) / glm::length(xb - xa);
    CHECK(t >= 0.0);
    CHECK(t <= 1.0);
    const Vec3d c2 = flexicubes_crossing(xa, sa, aa * 1.5, xb, sb, ab);
    CHECK(glm::length(c2 - xa) > glm::length(c - xa));
  }
}

// ------------------------------------------------- manifolds, case by case

TEST_CASE("flexicubes: each of the 256 cases in one cube gives closed oriented spheres") {
  std::mt19937 rng(1);
  const int lo[3] = {1, 1, 1}, hi[3] = {2, 2, 2};
  for (QuadSplit split : {QuadSplit::four_triangles, QuadSplit::two_triangles}) {
    for (std::uint32_t c = 0; c < 256; ++c) {
      CAPTURE(c);
      CAPTURE(int(split));
      GridData g = inner_pattern(3, lo, hi, c, rng);
      g.randomize_unknowns(rng, 0.0f, 2.0f);  // random weights, no deformation
      FlexiCubesOptions opt;
      opt.split = split;
      const auto m = flexicubes_extract<double>(g.grid, g.inputs(), opt);
      const std::int32_t nv = std::int32_t(m.vertices.size());
      CHECK(manifold_problem(m.triangles, nv) == "");
      if (c == 0) {
        CHECK(m.triangles.empty());
        continue;
      }
      // the centre cube has the dual vertices of its case
      const std::int32_t centre = g.grid.cube_index(1, 1, 1);
      const int expected = flexicubes_tables.configs[c].num_groups;
      CHECK(std::count(m.dual_vertex_cube.begin(), m.dual_vertex_cube.end(), centre) == expected);
      // one sphere per blob of inside corners, every quad facing outward
      for (int chi : euler_characteristics(m.triangles, nv)) CHECK(chi == 2);
      CHECK(misoriented_quads(g.grid, m, g.sdf) == 0);
      // with unit weights (random ones may fold a blob), each blob encloses a positive volume
      GridData plain = g;
      plain.alpha.clear();
      plain.beta.clear();
      const auto mp = flexicubes_extract<double>(plain.grid, plain.inputs(), opt);
      for (double v : volumes(positions_d(mp), mp.triangles)) CHECK(v > 0.0);
      CHECK(m.num_triangles() == m.num_quads() * m.triangles_per_quad);
    }
  }
}

TEST_CASE("flexicubes: every sign pattern of two face-adjacent cubes (4096 x 3 axes)") {
  std::mt19937 rng(2);
  int resolved = 0, broken_without = 0;
  for (int axis = 0; axis < 3; ++axis) {
    int lo[3] = {1, 1, 1}, hi[3] = {2, 2, 2};
    hi[axis] = 3;
    for (std::uint32_t bits = 0; bits < 4096; ++bits) {
      const GridData g = inner_pattern(4, lo, hi, bits, rng);
      CAPTURE(axis);
      CAPTURE(bits);
      const auto top = flexicubes_topology(g.grid, g.sdf.data());
      for (std::uint16_t cfg : top.config) resolved += cfg >= 256;
      const std::string problem = check_grid(g);
      CHECK(problem == "");
      FlexiCubesOptions off;
      off.resolve_ambiguous_faces = false;
      broken_without += check_grid(g, off) != "";
    }
  }
  MESSAGE("cubes that took the other split of an ambiguous face: " << resolved
          << "; patterns non-manifold without that check: " << broken_without);
  CHECK(resolved > 0);
  // the neighbour check is what makes those patterns manifold
  CHECK(broken_without > 0);
}

TEST_CASE("flexicubes: random sign patterns of 2x2x2 cubes") {
  std::mt19937 rng(5);
  const int lo[3] = {1, 1, 1}, hi[3] = {3, 3, 3};
  std::uniform_int_distribution<std::uint32_t> bits(0, (1u << 27) - 1);
  int failures = 0;
  for (int n = 0; n < 4000; ++n) {
    const std::uint32_t b = bits(rng);
    const GridData g = inner_pattern(4, lo, hi, b, rng);
    const std::string problem = check_grid(g);
    if (problem != "" && ++failures <= 5) FAIL_CHECK("pattern " << b << ": " << problem);
  }
  CHECK(failures == 0);
}

TEST_CASE("flexicubes: random SDF grids with random deformations and weights") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int n = 0; n < 60; ++n) {
    const int res = 6 + n % 7;
    GridData g(res);
    const float bias = 0.6f * u(rng);  // from mostly inside to mostly outside
    const int V = res + 1;
    for (int k = 0; k < V; ++k)
      for (int j = 0; j < V; ++j)
        for (int i = 0; i < V; ++i) {
          const bool border = i == 0 || j == 0 || k == 0 || i == res || j == res || k == res;
          g.sdf[std::size_t(g.grid.vertex_index(i, j, k))] = border ? 1.0f : bias + u(rng);
        }
    g.randomize_unknowns(rng, 3.0f, 3.0f);
    CAPTURE(n);
    for (QuadSplit split : {QuadSplit::four_triangles, QuadSplit::two_triangles}) {
      FlexiCubesOptions opt;
      opt.split = split;
      const auto m = flexicubes_extract<float>(g.grid, g.inputs(), opt);
      CHECK(manifold_problem(m.triangles, std::int32_t(m.vertices.size())) == "");
      for (const auto& p : m.vertices) CHECK(all_finite(p));
      for (int chi : euler_characteristics(m.triangles, std::int32_t(m.vertices.size()))) CHECK(chi % 2 == 0);
    }
    // without deformation every quad faces from inside to outside
    GridData flat = g;
    flat.deform.clear();
    const auto m = flexicubes_extract<double>(flat.grid, flat.inputs());
    CHECK(misoriented_quads(flat.grid, m, flat.sdf) == 0);
  }
}

// ------------------------------------------------------ shapes and topology

TEST_CASE_TEMPLATE("flexicubes: a sphere SDF gives a sphere within the resolution", S, float, double,
                   ad::Dual<double, 1>, ad::Var<float>) {
  const float r = 0.6f;
  GridData g(32);
  g.fill([&](Vec3f p) { return float(sphere_sdf(p, r)); });
  const double h = double(g.grid.cell().x);
  for (QuadSplit split : {QuadSplit::four_triangles, QuadSplit::two_triangles}) {
    FlexiCubesOptions opt;
    opt.split = split;
    const auto m = flexicubes_extract<S>(g.grid, g.inputs(), opt);
    const auto p = positions_d(m);
    REQUIRE(manifold_problem(m.triangles, std::int32_t(p.size())) == "");
    double worst = 0.0;
    for (const Vec3d& q : p) worst = std::max(worst, std::abs(glm::length(q) - double(r)));
    MESSAGE("sphere r = 0.6 at 32^3: worst |distance| = " << worst / h << " cells, " << p.size() << " vertices");
    CHECK(worst < 0.1 * h);
    const auto chi = euler_characteristics(m.triangles, std::int32_t(p.size()));
    REQUIRE(chi.size() == 1);
    CHECK(chi[0] == 2);
    const auto vol = volumes(p, m.triangles);
    const double exact = 4.0 / 3.0 * pi_v<double> * double(r) * r * r;
    CHECK(vol[0] == doctest::Approx(exact).epsilon(0.01));
  }
}

TEST_CASE("flexicubes: all scalars give the same positions") {
  std::mt19937 rng(11);
  GridData g(8);
  g.fill([&](Vec3f p) { return float(sphere_sdf(p, 0.55f)); });
  g.randomize_unknowns(rng, 1.0f, 1.0f);
  const auto ref = positions_d(flexicubes_extract<double>(g.grid, g.inputs()));
  auto close_to_ref = [&](const std::vector<Vec3d>& p, double tol) {
    REQUIRE(p.size() == ref.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < p.size(); ++i) worst = std::max(worst, glm::length(p[i] - ref[i]));
    CHECK(worst <= tol);
  };
  close_to_ref(positions_d(flexicubes_extract<float>(g.grid, g.inputs())), 1e-5);
  close_to_ref(positions_d(flexicubes_extract<ad::Dual<double, 2>>(g.grid, g.inputs())), 1e-12);
  close_to_ref(positions_d(flexicubes_extract<ad::Var<double>>(g.grid, g.inputs())), 1e-12);
  close_to_ref(positions_d(flexicubes_extract<ad::Var<float>>(g.grid, g.inputs())), 1e-5);
  // the same through a reader (every unknown a parameter buffer)
  ad::ParamSet set;
  const std::vector<float>* values[5] = {&g.sdf, &g.deform, &g.alpha, &g.beta, &g.gamma};
  for (int b = 0; b < 5; ++b) {
    set.buffers[b].values = values[b]->data();
    set.buffers[b].size = std::int32_t(values[b]->size());
  }
  ad::ParamReader<double> reader(&set);
  close_to_ref(positions_d(flexicubes_extract<double>(g.grid, g.inputs(true), reader)), 0.0);
  // and a grid with no unknowns but the SDF: weights 1, no deformation
  GridData bare = g;
  bare.deform.clear();
  bare.alpha.assign(bare.alpha.size(), 0.0f);
  bare.beta.clear();
  bare.gamma.clear();
  GridData zeros = bare;
  zeros.alpha.clear();
  zeros.deform.assign(g.deform.size(), 0.0f);
  zeros.beta.assign(g.beta.size(), 0.0f);
  zeros.gamma.assign(g.gamma.size(), 0.0f);
  const auto pb = positions_d(flexicubes_extract<double>(bare.grid, bare.inputs()));
  const auto pz = positions_d(flexicubes_extract<double>(zeros.grid, zeros.inputs()));
  REQUIRE(pb.size() == pz.size());
  for (std::size_t i = 0; i < pb.size(); ++i) CHECK(glm::length(pb[i] - pz[i]) < 1e-12);
}

TEST_CASE("flexicubes: genus from the Euler characteristic (sphere 0, torus 1, two-hole slab 2)") {
  std::mt19937 rng(13);
  struct Shape {
    const char* name;
    std::function<float(Vec3f)> sdf;
    int genus;
  };
  const Shape shapes[] = {
      {"sphere", [](Vec3f p) { return float(sphere_sdf(p - Vec3f(0.05f, -0.1f, 0.02f), 0.5f)); }, 0},
      {"torus", [](Vec3f p) { return float(torus_sdf(p, 0.5f, 0.22f)); }, 1},
      {"tilted torus", [](Vec3f p) { return float(torus_sdf(Vec3f(p.x, 0.8f * p.y + 0.6f * p.z, -0.6f * p.y + 0.8f * p.z), 0.55f, 0.2f)); }, 1},
      {"slab with two holes",
       [](Vec3f p) {
         const double slab = box_sdf(p, Vec3f(0.7f, 0.35f, 0.2f));
         const double hole1 = 0.15 - std::hypot(double(p.x) - 0.35, double(p.y));
         const double hole2 = 0.15 - std::hypot(double(p.x) + 0.35, double(p.y));
         return float(std::max(slab, std::max(hole1, hole2)));
       },
       2},
  };
  for (const Shape& s : shapes) {
    for (int variant = 0; variant < 2; ++variant) {
      CAPTURE(s.name);
      CAPTURE(variant);
      GridData g(32);
      g.fill(s.sdf);
      if (variant == 1) g.randomize_unknowns(rng, 2.0f, 2.0f);  // positions move, topology does not
      const auto m = flexicubes_extract<float>(g.grid, g.inputs());
      REQUIRE(manifold_problem(m.triangles, std::int32_t(m.vertices.size())) == "");
      const auto chi = euler_characteristics(m.triangles, std::int32_t(m.vertices.size()));
      REQUIRE(chi.size() == 1);
      CHECK((2 - chi[0]) / 2 == s.genus);
      CHECK(volumes(positions_d(m), m.triangles)[0] > 0.0);
    }
  }
}

// --------------------------------------------------------- the split rules

TEST_CASE("flexicubes: quad split rules (gamma picks the diagonal / weights the centre)") {
  std::mt19937 rng(17);
  GridData g(10);
  g.fill([&](Vec3f p) { return float(torus_sdf(p, 0.5f, 0.25f)); });
  g.randomize_unknowns(rng, 0.5f, 3.0f);
  FlexiCubesOptions two;
  two.split = QuadSplit::two_triangles;
  const auto m2 = flexicubes_extract<double>(g.grid, g.inputs(), two);
  const auto m4 = flexicubes_extract<double>(g.grid, g.inputs());
  REQUIRE(m2.num_quads() == m4.num_quads());
  REQUIRE(m2.num_quads() > 0);
  CHECK(m2.vertices.size() == std::size_t(m2.num_dual_vertices));
  CHECK(m4.vertices.size() == std::size_t(m4.num_dual_vertices + m4.num_quads()));
  auto gamma_of = [&](std::int32_t v) {
    return flexicubes_squash_gamma(double(g.gamma[std::size_t(m2.dual_vertex_cube[std::size_t(v)])]));
  };
  int diag02 = 0;
  for (std::int32_t q = 0; q < m2.num_quads(); ++q) {
    const std::int32_t* quad = &m2.quads[std::size_t(4 * q)];
    const double g02 = gamma_of(quad[0]) * gamma_of(quad[2]), g13 = gamma_of(quad[1]) * gamma_of(quad[3]);
    // which diagonal do the two triangles share?
    const std::int32_t* t = &m2.triangles[std::size_t(6 * q)];
    auto has = [&](const std::int32_t* tri, std::int32_t v) { return tri[0] == v || tri[1] == v || tri[2] == v; };
    const bool along02 = has(t, quad[0]) && has(t, quad[2]) && has(t + 3, quad[0]) && has(t + 3, quad[2]);
    const bool along13 = has(t, quad[1]) && has(t, quad[3]) && has(t + 3, quad[1]) && has(t + 3, quad[3]);
    CHECK(along02 != along13);
    CHECK(along02 == (g02 > g13));
    diag02 += along02;
    // the centre: γ-weighted mean of the two diagonal midpoints
    Vec3d v[4];
    for (int k = 0; k < 4; ++k) v[k] = m4.vertices[std::size_t(quad[k])];
    const Vec3d centre = (g02 * 0.5 * (v[0] + v[2]) + g13 * 0.5 * (v[1] + v[3])) / (g02 + g13);
    const Vec3d got = m4.vertices[std::size_t(m4.num_dual_vertices + q)];
    CHECK(glm::length(got - centre) < 1e-12);
    // the four triangles fan around the centre, in the quad's order
    for (int k = 0; k < 4; ++k) {
      const std::int32_t* tri = &m4.triangles[std::size_t(12 * q + 3 * k)];
      CHECK(tri[0] == quad[k]);
      CHECK(tri[1] == quad[(k + 1) % 4]);
      CHECK(tri[2] == m4.num_dual_vertices + q);
    }
  }
  // both diagonals occur with random γ
  CHECK(diag02 > 0);
  CHECK(diag02 < m2.num_quads());
}

TEST_CASE("flexicubes: deformation stays under half a cell, weights keep vertices in their cube") {
  std::mt19937 rng(19);
  GridData g(6);
  g.fill([&](Vec3f p) { return float(sphere_sdf(p, 0.6f)); });
  g.randomize_unknowns(rng, 0.0f, 50.0f);  // extreme weights, no deformation
  const Vec3d cell(g.grid.cell());
  auto cube_box = [&](std::int32_t c, Vec3d& lo, Vec3d& hi) {
    const int R = g.grid.res;
    lo = Vec3d(g.grid.vertex_position(c % R, (c / R) % R, c / (R * R)));
    hi = lo + cell;
  };
  auto m = flexicubes_extract<double>(g.grid, g.inputs());
  for (std::int32_t v = 0; v < m.num_dual_vertices; ++v) {
    Vec3d lo, hi;
    cube_box(m.dual_vertex_cube[std::size_t(v)], lo, hi);
    const Vec3d p = m.vertices[std::size_t(v)];
    for (int a = 0; a < 3; ++a) {
      CHECK(p[a] >= lo[a] - 1e-12);
      CHECK(p[a] <= hi[a] + 1e-12);
    }
  }
  // extreme deformations: within the cube grown by (just under) half a cell
  g.randomize_unknowns(rng, 50.0f, 50.0f);
  m = flexicubes_extract<double>(g.grid, g.inputs());
  double reach = 0.0;
  for (std::int32_t v = 0; v < m.num_dual_vertices; ++v) {
    Vec3d lo, hi;
    cube_box(m.dual_vertex_cube[std::size_t(v)], lo, hi);
    const Vec3d p = m.vertices[std::size_t(v)];
    for (int a = 0; a < 3; ++a) reach = std::max(reach, std::max(lo[a] - p[a], p[a] - hi[a]) / cell[a]);
  }
  CHECK(reach < 0.5);
  CHECK(reach > 0.4);  // the deformation does reach far
  CHECK(manifold_problem(m.triangles, std::int32_t(m.vertices.size())) == "");
}

// -------------------------------------------------------------- gradients

namespace {

// A small grid whose every unknown is differentiable, away from sign flips.
GridData gradient_grid(std::uint32_t seed) {
  std::mt19937 rng(seed);
  GridData g(4);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  g.fill([&](Vec3f p) {
    float s = float(sphere_sdf(p, 0.62f)) + 0.1f * u(rng);
    if (std::abs(s) < 0.03f) s = s < 0.0f ? -0.03f : 0.03f;
    return s;
  });
  g.randomize_unknowns(rng, 1.0f, 1.0f);
  return g;
}

// loss = Σ c_i · coordinate_i with fixed pseudo-random c (topology is fixed).
template <class S>
S weighted_sum(const FlexiCubesMesh<S>& m) {
  S loss(0);
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    for (int a = 0; a < 3; ++a) loss += std::sin(0.37 * double(3 * v + std::size_t(a)) + 0.5) * m.vertices[v][a];
  return loss;
}

struct Gradients {
  std::vector<float> buffer[5];
  double loss = 0.0;
};

template <class T>
Gradients reverse_mode(GridData& g) {
  Gradients out;
  ad::ParamSet set;
  std::vector<float>* values[5] = {&g.sdf, &g.deform, &g.alpha, &g.beta, &g.gamma};
  for (int b = 0; b < 5; ++b) {
    out.buffer[b].assign(values[b]->size(), 0.0f);
    set.buffers[b].values = values[b]->data();
    set.buffers[b].size = std::int32_t(values[b]->size());
    set.buffers[b].gradient = out.buffer[b].data();
  }
  ad::Tape<T> tape(1 << 20);
  std::vector<ad::LeafRecord> log(1 << 16);
  ad::ParamReader<ad::Var<T>> reader(&set, &tape, log.data(), std::int32_t(log.size()));
  const auto m = flexicubes_extract<ad::Var<T>>(g.grid, g.inputs(true), reader);
  const ad::Var<T> loss = weighted_sum(m);
  REQUIRE_FALSE(tape.overflowed());
  REQUIRE_FALSE(reader.overflowed());
  tape.backward(loss);
  reader.scatter();
  out.loss = double(loss.value);
  return out;
}

}  // namespace

TEST_CASE("flexicubes: gradients w.r.t. SDF, deformation and weights match central differences") {
  GridData g = gradient_grid(23);
  const Gradients ad_grad = reverse_mode<double>(g);
  std::vector<float>* values[5] = {&g.sdf, &g.deform, &g.alpha, &g.beta, &g.gamma};
  const std::string names[5] = {"sdf", "deform", "alpha", "beta", "gamma"};
  const std::size_t triangles = flexicubes_extract<double>(g.grid, g.inputs()).triangles.size();
  for (int b = 0; b < 5; ++b) {
    int nonzero = 0, checked = 0;
    double worst = 0.0;
    for (std::size_t i = 0; i < values[b]->size(); ++i) {
      // central differences at steps h and h / 2, Richardson-extrapolated
      // (the steps are the exact float differences of the perturbed inputs)
      float& x = (*values[b])[i];
      const float x0 = x;
      auto central = [&](float h) {
        const float xp = x0 + h, xm = x0 - h;
        x = xp;
        const auto mp = flexicubes_extract<double>(g.grid, g.inputs());
        x = xm;
        const auto mm = flexicubes_extract<double>(g.grid, g.inputs());
        x = x0;
        REQUIRE(mp.triangles.size() == triangles);  // no sign flipped
        REQUIRE(mm.triangles.size() == triangles);
        return (weighted_sum(mp) - weighted_sum(mm)) / (double(xp) - double(xm));
      };
      const double fd = (4.0 * central(5e-4f) - central(1e-3f)) / 3.0;
      const double got = double(ad_grad.buffer[b][i]);
      CAPTURE(names[b]);
      CAPTURE(i);
      CHECK(got == doctest::Approx(fd).epsilon(2e-5).scale(1.0));
      worst = std::max(worst, std::abs(got - fd) / std::max(1.0, std::abs(fd)));
      nonzero += fd != 0.0;
      ++checked;
    }
    MESSAGE(names[b] << ": " << checked << " checked, " << nonzero << " non-zero, worst relative error " << worst);
    CHECK(nonzero > 10);  // the loss does depend on this kind of unknown
  }
}

TEST_CASE("flexicubes: forward mode (Dual) agrees with reverse mode (Var), float and double") {
  GridData g = gradient_grid(29);
  const Gradients rev = reverse_mode<double>(g);
  const Gradients rev_f = reverse_mode<float>(g);
  // two random directions in parameter space as the two tangent lanes
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float>* values[5] = {&g.sdf, &g.deform, &g.alpha, &g.beta, &g.gamma};
  std::vector<float> dir[5][2];
  ad::ParamSet set;
  double expected[2] = {0.0, 0.0}, expected_f[2] = {0.0, 0.0};
  for (int b = 0; b < 5; ++b) {
    set.buffers[b].values = values[b]->data();
    set.buffers[b].size = std::int32_t(values[b]->size());
    for (int l = 0; l < 2; ++l) {
      dir[b][l].resize(values[b]->size());
      for (std::size_t i = 0; i < dir[b][l].size(); ++i) {
        dir[b][l][i] = u(rng);
        expected[l] += double(dir[b][l][i]) * double(rev.buffer[b][i]);
        expected_f[l] += double(dir[b][l][i]) * double(rev_f.buffer[b][i]);
      }
      set.buffers[b].tangents[l] = dir[b][l].data();
    }
  }
  ad::ParamReader<ad::Dual<double, 2>> reader(&set);
  const auto m = flexicubes_extract<ad::Dual<double, 2>>(g.grid, g.inputs(true), reader);
  const auto loss = weighted_sum(m);
  CHECK(loss.value == doctest::Approx(rev.loss).epsilon(1e-12));
  for (int l = 0; l < 2; ++l) {
    CHECK(loss.grad[l] == doctest::Approx(expected[l]).epsilon(1e-5));
    CHECK(expected_f[l] == doctest::Approx(expected[l]).epsilon(1e-3));
  }
  ad::ParamReader<ad::Dual<float, 2>> reader_f(&set);
  const auto loss_f = weighted_sum(flexicubes_extract<ad::Dual<float, 2>>(g.grid, g.inputs(true), reader_f));
  for (int l = 0; l < 2; ++l) CHECK(double(loss_f.grad[l]) == doctest::Approx(expected[l]).epsilon(1e-3));
}
