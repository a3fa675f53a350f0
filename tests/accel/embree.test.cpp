// Embree intersector: closest hits on a cube against the analytic answer,
// edge and vertex hits land on a triangle (robust mode: no ray slips through
// a closed mesh), misses, rays Embree would refuse, position updates, and
// bad input rejected with a message that names the problem.
#include "support/ad_check.hpp"

#include <limits>

#include "difftrans/accel/embree.hpp"

using difftrans::Vec3f;
using difftrans::accel::EmbreeScene;

namespace {
// Unit cube [-0.5, 0.5]³, 12 outward-facing triangles.
struct Cube {
  std::vector<float> p{-.5f, -.5f, -.5f, .5f, -.5f, -.5f, .5f, .5f, -.5f, -.5f, .5f, -.5f,
                       -.5f, -.5f, .5f,  .5f, -.5f, .5f,  .5f, .5f, .5f,  -.5f, .5f, .5f};
  std::vector<std::int32_t> f{0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                              3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
};
}  // namespace

TEST_CASE("closest hits on a cube") {
  Cube c;
  EmbreeScene scene(c.p.data(), 8, c.f.data(), 12, "cube");
  const auto h = scene.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1));
  REQUIRE(h.hit());
  CHECK(h.t == doctest::Approx(4.5f));
  // the barycentrics reproduce the hit point
  const int* tri = &c.f[3 * h.prim];
  Vec3f q(0.0f);
  const float w[3] = {1 - h.u - h.v, h.u, h.v};
  for (int k = 0; k < 3; ++k) q += w[k] * Vec3f(c.p[3 * tri[k]], c.p[3 * tri[k] + 1], c.p[3 * tri[k] + 2]);
  CHECK(glm::length(q - Vec3f(0.1f, 0.2f, 0.5f)) < 1e-6f);
  // from inside, the far wall
  const auto in = scene.intersect(Vec3f(0, 0, 0), Vec3f(1, 0, 0));
  REQUIRE(in.hit());
  CHECK(in.t == doctest::Approx(0.5f));
  // misses and tfar
  CHECK_FALSE(scene.intersect(Vec3f(0, 2, 5), Vec3f(0, 0, -1)).hit());
  CHECK_FALSE(scene.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, -1), 0.0f, 4.0f).hit());
}

TEST_CASE("rays through edges and vertices never slip through") {
  Cube c;
  EmbreeScene scene(c.p.data(), 8, c.f.data(), 12, "cube");
  int missed = 0;
  // the diagonal of every face is a shared edge; sweep rays across it and
  // aim some exactly at vertices and at face diagonals
  for (int i = 0; i <= 200; ++i) {
    const float s = -0.5f + float(i) / 200.0f;
    missed += !scene.intersect(Vec3f(s, s, 3.0f), Vec3f(0, 0, -1)).hit();
    missed += !scene.intersect(Vec3f(s, -s, 3.0f), Vec3f(0, 0, -1)).hit();
    missed += !scene.intersect(Vec3f(3.0f, s, s), Vec3f(-1, 0, 0)).hit();
  }
  CHECK(missed == 0);
}

TEST_CASE("rays Embree would refuse miss instead of aborting") {
  // Embree's own assertions abort on a ray that is not valid (a build with
  // them, as Debian's): the intersector answers a miss first
  Cube c;
  EmbreeScene scene(c.p.data(), 8, c.f.data(), 12, "cube");
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  CHECK_FALSE(scene.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(nan, 0, -1)).hit());
  CHECK_FALSE(scene.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, inf, -1)).hit());
  CHECK_FALSE(scene.intersect(Vec3f(nan, 0.2f, 5.0f), Vec3f(0, 0, -1)).hit());
  CHECK_FALSE(scene.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1), nan).hit());
  CHECK_FALSE(scene.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1), -1.0f).hit());
  // and the same ray, valid, hits
  CHECK(scene.intersect(Vec3f(0.1f, 0.2f, 5.0f), Vec3f(0, 0, -1)).hit());
}

TEST_CASE("positions can be updated") {
  Cube c;
  EmbreeScene scene(c.p.data(), 8, c.f.data(), 12, "cube");
  for (float& x : c.p) x *= 2.0f;
  scene.update_positions(c.p.data());
  CHECK(scene.intersect(Vec3f(0, 0, 5), Vec3f(0, 0, -1)).t == doctest::Approx(4.0f));
}

TEST_CASE("bad input is rejected before Embree sees it") {
  Cube c;
  c.p[3 * 5 + 1] = std::numeric_limits<float>::quiet_NaN();
  CHECK_THROWS_WITH_AS(EmbreeScene(c.p.data(), 8, c.f.data(), 12, "cube.obj"),
                       doctest::Contains("cube.obj: vertex 5 has a non-finite coordinate"), std::invalid_argument);
  Cube d;
  d.f[3 * 7 + 2] = 8;
  CHECK_THROWS_WITH_AS(EmbreeScene(d.p.data(), 8, d.f.data(), 12, "cube.obj"),
                       doctest::Contains("triangle 7 refers to vertex 8"), std::invalid_argument);
  Cube e;
  EmbreeScene scene(e.p.data(), 8, e.f.data(), 12, "cube");
  e.p[0] = std::numeric_limits<float>::infinity();
  CHECK_THROWS_AS(scene.update_positions(e.p.data()), std::invalid_argument);
}

TEST_CASE("a degenerate triangle is accepted and never reported as hit") {
  std::vector<float> p{0, 0, 0, 1, 0, 0, 2, 0, 0};  // collinear
  std::vector<std::int32_t> f{0, 1, 2};
  EmbreeScene scene(p.data(), 3, f.data(), 1, "flat");
  CHECK_FALSE(scene.intersect(Vec3f(1, 0, 1), Vec3f(0, 0, -1)).hit());
  CHECK_FALSE(scene.intersect(Vec3f(1, 1, 0), Vec3f(0, -1, 0)).hit());
}
