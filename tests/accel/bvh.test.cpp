// Portable BVH against Embree (an independent implementation) on the same
// rays: spot and bunny from data/, rays from outside and inside, with
// tnear/tfar windows; the analytic cube; rays through edges and vertices of
// closed meshes never slip through; degenerate triangles never reported; bad
// input rejected; refit and rebuild; tree invariants; and the generic tracer
// gives the same radiance with either intersector. In a build without Embree
// only the comparisons with it are left out.
#include "support/ad_check.hpp"
#include "support/scenes.hpp"
#include "support/rays.hpp"
#include "support/shapes.hpp"

#include <algorithm>
#include <cstdio>
#include <random>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/render/passes.hpp"
#if DIFFTRANS_HAVE_EMBREE
#include "difftrans/accel/embree.hpp"
#endif

using namespace dt_test;
using difftrans::Vec3f;
using difftrans::accel::Bvh;
using difftrans::accel::BvhNode;
using difftrans::accel::RayHit;
#if DIFFTRANS_HAVE_EMBREE
using difftrans::accel::EmbreeScene;
#endif

namespace {

using Ray = IncoherentRay;

Bvh make_bvh(const Shape& s, const std::string& name = "mesh") {
  return Bvh(s.positions.data(), std::int32_t(s.positions.size() / 3), s.triangles.data(),
             std::int32_t(s.triangles.size() / 3), name);
}

Vec3f vertex(const Shape& s, std::int32_t i) {
  return Vec3f(s.positions[3 * std::size_t(i)], s.positions[3 * std::size_t(i) + 1], s.positions[3 * std::size_t(i) + 2]);
}

// The point the hit's barycentrics name on its triangle.
Vec3f hit_point(const Shape& s, const RayHit& h) {
  const std::int32_t* t = &s.triangles[3 * std::size_t(h.prim)];
  return (1.0f - h.u - h.v) * vertex(s, t[0]) + h.u * vertex(s, t[1]) + h.v * vertex(s, t[2]);
}

#if DIFFTRANS_HAVE_EMBREE
EmbreeScene* make_embree(const Shape& s) {
  return new EmbreeScene(s.positions.data(), std::int32_t(s.positions.size() / 3), s.triangles.data(),
                         std::int32_t(s.triangles.size() / 3), "mesh");
}

// How the BVH's answers compare with Embree's on the same rays.
struct Agreement {
  int rays = 0, hits = 0, hit_miss_differ = 0, other_prim = 0, bad_t = 0, bad_uv = 0, bad_point = 0;
};

Agreement compare_with_embree(const Shape& s, const Bvh& bvh, const EmbreeScene& em, const std::vector<Ray>& rays) {
  Agreement a;
  for (const Ray& r : rays) {
    const RayHit e = em.intersect(r.o, r.d, r.tnear, r.tfar);
    const RayHit b = bvh.intersect(r.o, r.d, r.tnear, r.tfar);
    ++a.rays;
    if (e.hit() != b.hit()) {
      ++a.hit_miss_differ;
      continue;
    }
    if (!e.hit()) continue;
    ++a.hits;
    const bool t_ok = std::abs(b.t - e.t) <= 1e-5f * std::max(1.0f, std::abs(e.t));
    a.bad_t += !t_ok;
    if (b.prim != e.prim) {
      ++a.other_prim;  // a tie at a shared edge or vertex: the same t is all that is asked
      continue;
    }
    // the barycentrics of a small triangle hit at a grazing angle amplify the
    // rounding of t (a 1e-2 triangle at cos 0.02 turns 2e-7 in t into 1e-4 in
    // u): ask for the same point on the triangle (2e-5 of the unit box) and
    // loosely for the same numbers
    RayHit bu = b;
    bu.u = e.u;
    bu.v = e.v;
    const bool uv_ok = glm::length(hit_point(s, b) - hit_point(s, bu)) <= 2e-5f &&
                       std::abs(b.u - e.u) <= 1e-3f && std::abs(b.v - e.v) <= 1e-3f;
    if (!uv_ok)
      std::printf("uv differ: o %.9g %.9g %.9g d %.9g %.9g %.9g prim %d t %.9g/%.9g u %.9g/%.9g v %.9g/%.9g\n", r.o.x,
                  r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, b.prim, b.t, e.t, b.u, e.u, b.v, e.v);
    a.bad_uv += !uv_ok;
    a.bad_point += !(glm::length(hit_point(s, b) - (r.o + b.t * r.d)) <= 1e-5f);
  }
  return a;
}
#endif  // DIFFTRANS_HAVE_EMBREE

// Rays through the vertices and edge midpoints of a closed mesh, which must
// cross the surface there (or earlier): from outside along the inward
// normal (the mean of the vertex normals) and, for a mesh that is star-shaped
// around `inside`, from that point out through them.
int slipping_rays(const Shape& s, const Bvh& bvh, const Vec3f* inside, int* total) {
  const difftrans::scene::TriangleMesh mesh(s.positions, s.triangles);
  const auto normal = [&](std::int32_t v) {
    return Vec3f(mesh.vertex_normals[3 * std::size_t(v)], mesh.vertex_normals[3 * std::size_t(v) + 1],
                 mesh.vertex_normals[3 * std::size_t(v) + 2]);
  };
  int missed = 0;
  const auto aim = [&](const Vec3f& target, const Vec3f& n) {
    const Vec3f from = target + 0.7f * n;
    missed += !bvh.intersect(from, glm::normalize(target - from)).hit();
    ++*total;
    if (inside) {
      missed += !bvh.intersect(*inside, glm::normalize(target - *inside)).hit();
      ++*total;
    }
  };
  for (std::int32_t v = 0; v < std::int32_t(s.positions.size() / 3); ++v) aim(vertex(s, v), normal(v));
  for (std::size_t f = 0; f < s.triangles.size(); f += 3)
    for (int k = 0; k < 3; ++k) {
      const std::int32_t a = s.triangles[f + std::size_t(k)], b = s.triangles[f + std::size_t((k + 1) % 3)];
      aim(0.5f * (vertex(s, a) + vertex(s, b)), glm::normalize(normal(a) + normal(b)));
    }
  return missed;
}

}  // namespace

TEST_CASE("closest hits on a cube: distance, barycentrics, inside rays, tnear and tfar") {
  const Shape c = make_box(0.5f, 0.5f, 0.5f);
  const Bvh bvh = make_bvh(c, "cube");
  const auto h = bvh.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1));
  REQUIRE(h.hit());
  CHECK(h.t == doctest::Approx(4.5f).epsilon(1e-6));
  CHECK(glm::length(hit_point(c, h) - Vec3f(0.1f, 0.2f, 0.5f)) < 1e-6f);
  // from inside, the far wall
  const auto in = bvh.intersect(Vec3f(0, 0, 0), Vec3f(1, 0, 0));
  REQUIRE(in.hit());
  CHECK(in.t == doctest::Approx(0.5f));
  CHECK(glm::length(hit_point(c, in) - Vec3f(0.5f, 0, 0)) < 1e-6f);
  // misses: beside the box, pointing away, window before the box
  CHECK_FALSE(bvh.intersect(Vec3f(0, 2, 5), Vec3f(0, 0, -1)).hit());
  CHECK_FALSE(bvh.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, 1)).hit());
  CHECK_FALSE(bvh.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, -1), 0.0f, 4.0f).hit());
  // tnear past the front face finds the back face; tfar between them the front
  const auto back = bvh.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1), 5.0f, 100.0f);
  REQUIRE(back.hit());
  CHECK(back.t == doctest::Approx(5.5f));
  CHECK(bvh.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1), 0.0f, 5.0f).t == doctest::Approx(4.5f));
  CHECK_FALSE(bvh.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1), 5.6f, 100.0f).hit());
  // a non-unit direction: t in units of |d|
  CHECK(bvh.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -2)).t == doctest::Approx(2.25f));
  // zero, NaN and infinite directions and empty windows hit nothing
  CHECK_FALSE(bvh.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, 0)).hit());
  CHECK_FALSE(bvh.intersect(Vec3f(0, 0, 5), Vec3f(0, std::nanf(""), -1)).hit());
  CHECK_FALSE(bvh.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, -std::numeric_limits<float>::infinity())).hit());
  CHECK_FALSE(bvh.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, -1), 3.0f, 2.0f).hit());
  // an axis-parallel ray in the plane of a face (direction components exactly 0)
  const auto along = bvh.intersect(Vec3f(-3.0f, 0.5f, 0.1f), Vec3f(1, 0, 0));
  REQUIRE(along.hit());
  CHECK(along.t == doctest::Approx(2.5f));
}

#if DIFFTRANS_HAVE_EMBREE
TEST_CASE("spot and bunny: the same hits as Embree on incoherent rays") {
  for (const char* name : {"spot.obj", "bunny.obj"}) {
    CAPTURE(name);
    const Shape s = load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/" + name);
    const Bvh bvh = make_bvh(s, name);
    const std::unique_ptr<EmbreeScene> em(make_embree(s));
    const auto rays = incoherent_rays(40000, 11, true);
    const Agreement a = compare_with_embree(s, bvh, *em, rays);
    std::printf("%s: %d rays, %d hits, %d hit/miss differ, %d other triangle (tie), %d t, %d uv, %d point off\n",
                name, a.rays, a.hits, a.hit_miss_differ, a.other_prim, a.bad_t, a.bad_uv, a.bad_point);
    CHECK(a.hits > a.rays / 4);  // the ray set does hit the mesh
    CHECK(a.hits < a.rays);      // and misses it
    CHECK(a.hit_miss_differ <= a.rays / 20000);  // only where a ray grazes a silhouette within rounding
    CHECK(a.other_prim <= a.hits / 5000);
    CHECK(a.bad_t == 0);
    CHECK(a.bad_uv == 0);
    CHECK(a.bad_point == 0);
  }
}
#endif

TEST_CASE("rays through edges and vertices of closed meshes never slip through") {
  // the cube: sweeps across the diagonals (shared edges) of every face, and
  // rays aimed at the corners, the edge midpoints and the face centres
  const Shape c = make_box(0.5f, 0.5f, 0.5f);
  const Bvh cube = make_bvh(c, "cube");
  int missed = 0, total = 0;
  for (int i = 0; i <= 400; ++i) {
    const float s = -0.5f + float(i) / 400.0f;
    const Vec3f sweeps[6][2] = {{{s, s, 3.0f}, {0, 0, -1}},  {{s, -s, 3.0f}, {0, 0, -1}}, {{3.0f, s, s}, {-1, 0, 0}},
                                {{3.0f, s, -s}, {-1, 0, 0}}, {{s, 3.0f, s}, {0, -1, 0}},  {{-s, 3.0f, s}, {0, -1, 0}}};
    for (const auto& r : sweeps) {
      missed += !cube.intersect(r[0], r[1]).hit();
      missed += !cube.intersect(-r[0], -r[1]).hit();
      total += 2;
    }
  }
  CHECK(missed == 0);
  total = 0;
  const Vec3f cube_inside(0.01f, -0.02f, 0.03f);
  CHECK(slipping_rays(c, cube, &cube_inside, &total) == 0);
  CHECK(total == 2 * (8 + 36));
  // an icosphere (many valences, shared vertices at odd angles) and spot
  const Shape ico = make_icosphere(0.5f, 3);
  const Vec3f ico_inside(0.02f, 0.01f, -0.03f);
  total = 0;
  CHECK(slipping_rays(ico, make_bvh(ico), &ico_inside, &total) == 0);
  CHECK(total > 2000);
  const Shape spot = load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj");
  total = 0;
  CHECK(slipping_rays(spot, make_bvh(spot, "spot"), nullptr, &total) == 0);
  CHECK(total > 20000);
  // from inside spot (its body contains the origin) in random directions
  const Bvh spot_bvh = make_bvh(spot, "spot");
  std::mt19937 rng(8);
  missed = 0;
  for (int i = 0; i < 20000; ++i) missed += !spot_bvh.intersect(Vec3f(0.0f), random_unit(rng)).hit();
  CHECK(missed == 0);
}

TEST_CASE("degenerate triangles are never reported") {
  // collinear, repeated vertex, all three equal, next to a proper triangle
  std::vector<float> p{0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0, -1, 1, 0, -1, 0, 1, -1};
  std::vector<std::int32_t> f{0, 1, 2, 0, 0, 3, 3, 3, 3, 4, 5, 6};
  const Bvh bvh(p.data(), 7, f.data(), 4, "flat");
  int reported = 0;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.5f, 2.5f);
  for (int i = 0; i < 2000; ++i) {
    // rays crossing the degenerate triangles' lines and points from every side
    const Vec3f target = i % 3 == 0 ? Vec3f(u(rng), 0.0f, 0.0f) : (i % 3 == 1 ? Vec3f(0, 0, 0) : Vec3f(0, 1, 0));
    const Vec3f from = target + 2.0f * random_unit(rng);
    const auto h = bvh.intersect(from, glm::normalize(target - from));
    reported += h.hit() && h.prim != 3;
  }
  CHECK(reported == 0);
  // along the segment's own line, and the proper triangle still answers
  CHECK_FALSE(bvh.intersect(Vec3f(-1, 0, 0), Vec3f(1, 0, 0)).hit());
  const auto h = bvh.intersect(Vec3f(0.2f, 0.2f, 1.0f), Vec3f(0, 0, -1));
  REQUIRE(h.hit());
  CHECK(h.prim == 3);
  CHECK(h.t == doctest::Approx(2.0f));
  // a sliver whose 2D projection is not exactly flat after the shear
  std::vector<float> q{0, 0, 0, 1, 1e-9f, 0, 2, 0, 0};
  std::vector<std::int32_t> g{0, 1, 2};
  const Bvh sliver(q.data(), 3, g.data(), 1, "sliver");
  int sliver_hits = 0;
  for (int i = 0; i < 500; ++i) {
    const Vec3f target(u(rng) * 0.6f + 0.2f, 0.0f, 0.0f);
    const Vec3f from = target + random_unit(rng);
    sliver_hits += sliver.intersect(from, glm::normalize(target - from)).hit();
  }
  CHECK(sliver_hits == 0);
}

TEST_CASE("bad input is rejected with a message naming it") {
  Shape c = make_box(0.5f, 0.5f, 0.5f);
  c.positions[3 * 5 + 1] = std::numeric_limits<float>::quiet_NaN();
  CHECK_THROWS_WITH_AS(make_bvh(c, "cube.obj"), doctest::Contains("cube.obj: vertex 5 has a non-finite coordinate"),
                       std::invalid_argument);
  Shape d = make_box(0.5f, 0.5f, 0.5f);
  d.triangles[3 * 7 + 2] = 8;
  CHECK_THROWS_WITH_AS(make_bvh(d, "cube.obj"), doctest::Contains("triangle 7 refers to vertex 8"),
                       std::invalid_argument);
  d.triangles[3 * 7 + 2] = -1;
  CHECK_THROWS_WITH_AS(make_bvh(d, "cube.obj"), doctest::Contains("triangle 7 refers to vertex -1"),
                       std::invalid_argument);
  Shape e = make_box(0.5f, 0.5f, 0.5f);
  Bvh bvh = make_bvh(e, "cube");
  e.positions[0] = std::numeric_limits<float>::infinity();
  CHECK_THROWS_WITH_AS(bvh.refit(e.positions.data()), doctest::Contains("vertex 0 has a non-finite"),
                       std::invalid_argument);
  CHECK_THROWS_AS(bvh.update_positions(e.positions.data()), std::invalid_argument);
  // an empty mesh is valid and hits nothing
  const Bvh empty(nullptr, 0, nullptr, 0, "empty");
  CHECK_FALSE(empty.intersect(Vec3f(0, 0, 1), Vec3f(0, 0, -1)).hit());
}

TEST_CASE("tree invariants: every triangle once, boxes enclose, bounded depth") {
  const auto check_tree = [](const Bvh& bvh, const Shape& s) {
    const auto& nodes = bvh.nodes();
    std::vector<int> seen(s.triangles.size() / 3, 0);
    int leaves = 0;
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      const BvhNode& n = nodes[i];
      if (n.leaf()) {
        ++leaves;
        CHECK(n.count <= 4);
        for (std::int32_t k = n.index; k < n.index + n.count; ++k) {
          ++seen[std::size_t(bvh.prims()[std::size_t(k)])];
          for (int j = 0; j < 9; ++j) {
            const float x = bvh.vertices()[9 * std::size_t(k) + std::size_t(j)];
            CHECK((x >= n.lo[j % 3] && x <= n.hi[j % 3]));
          }
        }
      } else {
        REQUIRE(n.index > std::int32_t(i) + 1);
        REQUIRE(n.index < std::int32_t(nodes.size()));
        for (const BvhNode* c : {&nodes[i + 1], &nodes[std::size_t(n.index)]})
          for (int k = 0; k < 3; ++k) CHECK((c->lo[k] >= n.lo[k] && c->hi[k] <= n.hi[k]));
      }
    }
    CHECK(std::all_of(seen.begin(), seen.end(), [](int x) { return x == 1; }));
    CHECK(bvh.depth() <= difftrans::accel::bvh_max_depth);
    return leaves;
  };
  const Shape spot = load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj");
  const Bvh b = make_bvh(spot);
  CHECK(check_tree(b, spot) >= int(spot.triangles.size() / 3 / 4));
  CHECK(b.depth() < 30);
  // the SAH does better than a random ray testing every triangle
  CHECK(b.sah_cost() < 0.02 * double(spot.triangles.size() / 3));
  // 3000 identical triangles: no split separates them, median splits bound the depth
  Shape same;
  same.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  for (int i = 0; i < 3000; ++i) same.triangles.insert(same.triangles.end(), {0, 1, 2});
  const Bvh sb = make_bvh(same);
  check_tree(sb, same);
  CHECK(sb.depth() <= 14);
  CHECK(sb.intersect(Vec3f(0.2f, 0.2f, 1), Vec3f(0, 0, -1)).hit());
}

TEST_CASE("refit and rebuild follow moved vertices") {
  const Shape spot = load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj");
  Bvh bvh = make_bvh(spot);
#if DIFFTRANS_HAVE_EMBREE
  const std::unique_ptr<EmbreeScene> em(make_embree(spot));
#endif
  // a smooth deformation: twist and stretch, so boxes must grow and shrink
  Shape moved = spot;
  for (std::size_t i = 0; i < moved.positions.size(); i += 3) {
    float& x = moved.positions[i];
    float& y = moved.positions[i + 1];
    float& z = moved.positions[i + 2];
    const float a = 1.2f * y, cx = std::cos(a), sx = std::sin(a);
    const float nx = cx * x - sx * z, nz = sx * x + cx * z;
    x = 1.3f * nx;
    z = 0.7f * nz;
    y = y + 0.1f * x;
  }
  bvh.refit(moved.positions.data());
  CHECK(bvh.sah_cost() > bvh.built_sah_cost());  // the old tree fits the new shape worse
#if DIFFTRANS_HAVE_EMBREE
  em->update_positions(moved.positions.data());
  const auto rays = incoherent_rays(20000, 21, true);
  Agreement a = compare_with_embree(moved, bvh, *em, rays);
  CHECK(a.hits > a.rays / 4);
  CHECK(a.hit_miss_differ <= 2);
  CHECK(a.bad_t == 0);
  CHECK(a.bad_point == 0);
#endif
  bvh.rebuild(moved.positions.data());
  CHECK(bvh.sah_cost() == bvh.built_sah_cost());
#if DIFFTRANS_HAVE_EMBREE
  a = compare_with_embree(moved, bvh, *em, rays);
  CHECK(a.hit_miss_differ <= 2);
  CHECK(a.bad_t == 0);
#endif
  // update_positions: 2000 small separate triangles, each moved to another
  // place; the refitted boxes then span everything, so it rebuilds
  Shape soup, shuffled;
  std::mt19937 rng(9);
  std::vector<int> cells(2000);
  for (int i = 0; i < 2000; ++i) cells[std::size_t(i)] = i;
  std::shuffle(cells.begin(), cells.end(), rng);
  for (int i = 0; i < 2000; ++i) {
    const auto place = [](Shape& sh, int cell) {
      const float x = float(cell % 20) / 20.0f - 0.5f, y = float(cell / 20 % 10) / 10.0f - 0.5f,
                  z = float(cell / 200) / 10.0f - 0.5f;
      const auto base = std::int32_t(sh.positions.size() / 3);
      sh.positions.insert(sh.positions.end(), {x, y, z, x + 0.04f, y, z, x, y + 0.04f, z + 0.02f});
      sh.triangles.insert(sh.triangles.end(), {base, base + 1, base + 2});
    };
    place(soup, i);
    place(shuffled, cells[std::size_t(i)]);
  }
  Bvh up = make_bvh(soup), only_refit = make_bvh(soup);
  up.update_positions(shuffled.positions.data());
  only_refit.refit(shuffled.positions.data());
  CHECK(up.sah_cost() == up.built_sah_cost());
  CHECK(only_refit.sah_cost() > 3.0 * up.sah_cost());
  // both answer right; the rebuilt tree does so with less work
#if DIFFTRANS_HAVE_EMBREE
  const std::unique_ptr<EmbreeScene> es(make_embree(shuffled));
  const auto soup_rays = incoherent_rays(5000, 22, true);
  const Agreement s1 = compare_with_embree(shuffled, up, *es, soup_rays);
  const Agreement s2 = compare_with_embree(shuffled, only_refit, *es, soup_rays);
  CHECK(s1.hits > 100);
  CHECK(s1.hit_miss_differ + s1.bad_t + s1.bad_point == 0);
  CHECK(s2.hit_miss_differ + s2.bad_t + s2.bad_point == 0);
#endif
}


// (Without Embree, HostScene itself traces with a Bvh: nothing to compare.)
#if DIFFTRANS_HAVE_EMBREE
TEST_CASE("the tracer renders the same with the BVH as with Embree") {
  using namespace difftrans;
  const render::HostScene s = sphere_scene();
  const Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
                "sphere");
  const render::SceneView view = s.view(false);
  const ad::ParamSet params = s.params();
  ad::ParamReader<float> reader(&params);
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 48, 48);
  render::TraceSettings ts;
  ts.max_depth = 6;
  int differ = 0, hit_pixels = 0;
  double max_diff = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const scene::Ray r = cam.generate_ray(x, y);
      render::TraceStats se, sb;
      const Vec3f le = render::trace<float>(view, s.accel(), reader, r.origin, r.direction, ts, &se);
      const Vec3f lb = render::trace<float>(view, bvh, reader, r.origin, r.direction, ts, &sb);
      hit_pixels += se.hits > 0;
      const float d = glm::length(le - lb);
      max_diff = std::max(max_diff, double(d));
      differ += !(d <= 1e-4f) || se.hits != sb.hits;
    }
  std::printf("tracer with BVH vs Embree: %d of %d pixels hit the sphere, %d differ, max |diff| %.3g\n", hit_pixels,
              cam.width * cam.height, differ, max_diff);
  CHECK(hit_pixels > cam.width * cam.height / 5);
  CHECK(differ == 0);
}
#endif
