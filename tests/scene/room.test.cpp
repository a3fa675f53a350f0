// The procedural room of synth --room: rays from inside leave through the
// wall they point at, at the right place; each wall shows its own pattern;
// what a direction shows depends on where the ray starts (parallax, the
// reason a distant map cannot represent it).
#include "support/ad_check.hpp"

#include "difftrans/scene/room.hpp"

using namespace dt_test;
namespace sc = difftrans::scene;

TEST_CASE("room: exit wall and point") {
  sc::Room room;
  room.half = 3.0f;
  int wall = -1;
  Vec3f p;
  REQUIRE(room.exit_point(Vec3f(0.5f, 0.0f, 0.0f), Vec3f(1.0f, 0.2f, 0.1f), wall, p));
  CHECK(wall == 1);
  CHECK(p.x == doctest::Approx(3.0f));
  CHECK(p.y == doctest::Approx(0.5f));
  CHECK(p.z == doctest::Approx(0.25f));
  REQUIRE(room.exit_point(Vec3f(0.0f), Vec3f(0.0f, -2.0f, 0.0f), wall, p));
  CHECK(wall == 2);
  CHECK(p.y == doctest::Approx(-3.0f));
  REQUIRE(room.exit_point(Vec3f(0.0f), Vec3f(0.1f, 0.0f, -1.0f), wall, p));
  CHECK(wall == 4);
  // a centred room elsewhere: coordinates are relative to its centre
  room.centre = Vec3f(10.0f, 0.0f, 0.0f);
  REQUIRE(room.exit_point(Vec3f(10.0f, 0.0f, 0.0f), Vec3f(0.0f, 0.0f, 1.0f), wall, p));
  CHECK(wall == 5);
  CHECK(p.z == doctest::Approx(3.0f));
  CHECK(p.x == doctest::Approx(0.0f));
  // the box behind the ray (an origin outside, pointing away): nothing
  CHECK(!room.exit_point(Vec3f(20.0f, 0.0f, 0.0f), Vec3f(1.0f, 0.0f, 0.0f), wall, p));
  CHECK(room.radiance(Vec3f(20.0f, 0.0f, 0.0f), Vec3f(1.0f, 0.0f, 0.0f)) == Vec3f(0.0f));
}

TEST_CASE("room: patterns, lights and parallax") {
  sc::Room room;
  room.half = 4.0f;
  // the panel on the −z wall and the ceiling light
  CHECK(room.radiance(Vec3f(0.0f), Vec3f(0.0f, 0.05f, -1.0f)) == room.panel_radiance);
  CHECK(room.radiance(Vec3f(0.0f), Vec3f(0.0f, 1.0f, 0.0f)) == room.ceiling_radiance);
  // floor: a checkerboard of cells of 1 (neighbouring cells differ, cells two apart agree)
  const Vec3f down(0.0f, -1.0f, 0.0f);
  const Vec3f a = room.radiance(Vec3f(0.5f, 0.0f, 0.5f), down), b = room.radiance(Vec3f(1.5f, 0.0f, 0.5f), down);
  const Vec3f c = room.radiance(Vec3f(2.5f, 0.0f, 0.5f), down);
  CHECK(a != b);
  CHECK(a == c);
  // +x: vertical stripes of width 0.5 along z
  const Vec3f px(1.0f, 0.0f, 0.0f);
  CHECK(room.radiance(Vec3f(0.0f, 0.0f, 0.25f), px) != room.radiance(Vec3f(0.0f, 0.0f, 0.75f), px));
  // every value finite and non-negative, over many directions
  for (int i = 0; i < 500; ++i) {
    const float t = 0.1f * float(i);
    const Vec3f d(std::sin(t) * std::cos(0.37f * t), std::cos(t), std::sin(t) * std::sin(0.37f * t) + 1e-3f);
    const Vec3f L = room.radiance(Vec3f(0.3f, -0.2f, 0.1f), d);
    for (int ch = 0; ch < 3; ++ch) {
      CHECK(std::isfinite(L[ch]));
      CHECK(L[ch] >= 0.0f);
    }
  }
  // parallax: the same direction from two origins lands on different stripes
  const Vec3f d = glm::normalize(Vec3f(1.0f, 0.0f, 0.1f));
  CHECK(room.radiance(Vec3f(0.0f, 0.0f, 0.0f), d) != room.radiance(Vec3f(0.0f, 0.0f, 0.5f), d));
}
