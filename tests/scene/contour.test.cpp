// Which points the masks pin: the distance from a pixel point to a mask's
// outline on hand-drawn masks, and the views whose rim passes through points
// of a sphere seen by six cameras along the axes.
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/scene/contour.hpp"

using namespace difftrans;
using scene::Camera;

namespace {

// The mask of a sphere of radius r at the origin: a pixel is inside when the
// ray through its centre meets the sphere.
std::vector<std::uint8_t> sphere_mask(const Camera& c, float r) {
  std::vector<std::uint8_t> mask(std::size_t(c.width) * std::size_t(c.height), 0);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const scene::Ray ray = c.generate_ray(x, y);
      const double b = glm::dot(Vec3d(ray.origin), Vec3d(ray.direction));
      const double q = glm::dot(Vec3d(ray.origin), Vec3d(ray.origin)) - double(r) * double(r);
      mask[std::size_t(y) * std::size_t(c.width) + std::size_t(x)] = b * b - q >= 0.0 ? 1 : 0;
    }
  return mask;
}

}  // namespace

TEST_CASE("distance_to_outline: the pixel edges between inside and outside, not the image's frame") {
  // a 2 x 2 block of inside pixels at columns 1..2, rows 1..2 of a 4 x 4 mask
  std::vector<std::uint8_t> m(16, 0);
  for (int y = 1; y <= 2; ++y)
    for (int x = 1; x <= 2; ++x) m[std::size_t(4 * y + x)] = 1;
  CHECK(std::abs(scene::distance_to_outline(m.data(), 4, 4, 2.0f, 2.0f, 3.0f) - 1.0f) < 1e-6f);   // the block's centre
  CHECK(std::abs(scene::distance_to_outline(m.data(), 4, 4, 1.0f, 2.0f, 3.0f)) < 1e-6f);          // on its left edge
  CHECK(std::abs(scene::distance_to_outline(m.data(), 4, 4, 2.0f, 0.25f, 3.0f) - 0.75f) < 1e-6f);  // above it
  CHECK(std::abs(scene::distance_to_outline(m.data(), 4, 4, 0.5f, 0.5f, 3.0f) - std::sqrt(0.5f)) < 1e-6f);  // corner
  // nothing within the radius: a value above it
  CHECK(scene::distance_to_outline(m.data(), 4, 4, 2.0f, 2.0f, 0.5f) > 0.5f);
  // a mask that fills the image has no outline: the frame is not one
  const std::vector<std::uint8_t> full(16, 1);
  CHECK(scene::distance_to_outline(full.data(), 4, 4, 0.1f, 0.1f, 3.0f) > 3.0f);
  CHECK(scene::distance_to_outline(full.data(), 4, 4, 2.0f, 2.0f, 3.0f) > 3.0f);
}

TEST_CASE("contour_views: a sphere's rim points count the views that see them on the outline") {
  const float r = 0.5f;
  const std::vector<Vec3f> axes{{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::vector<Camera> cameras;
  std::vector<std::vector<std::uint8_t>> masks;
  for (const Vec3f& a : axes) {
    // the protocol camera looks from 3 units along a; along ±y its up vector is degenerate, so tilt it a hair
    cameras.push_back(scene::protocol_camera(a + Vec3f(0.0f, 0.0f, 1e-3f), 128, 128));
    masks.push_back(sphere_mask(cameras.back(), r));
  }
  std::vector<scene::SilhouetteView> views;
  for (std::size_t k = 0; k < cameras.size(); ++k) views.push_back({cameras[k], masks[k].data()});

  const Vec3f diagonal = r * glm::normalize(Vec3f(1, 1, 1));
  const std::vector<float> points{
      0.0f, 0.0f, r,                        // a pole: on the rim of the four side views, at the centre of ±z
      r, 0.0f, 0.0f,                        // another pole: ±y and ±z
      diagonal.x, diagonal.y, diagonal.z,   // 3 px inside the outlines of +x, +y, +z, 8 px inside the others
      0.6f, 0.0f, 0.0f,                     // 5 px outside the ±y and ±z outlines
  };
  const std::vector<int> n = scene::contour_views(points, views, 1.0f);
  REQUIRE(n.size() == 4);
  CHECK(n[0] == 4);
  CHECK(n[1] == 4);
  CHECK(n[2] == 0);
  CHECK(n[3] == 0);
  // a band of 4 pixels reaches the diagonal point in the three views it faces, not the three behind it
  CHECK(scene::contour_views(points, views, 4.0f)[2] == 3);
  // views without a mask count for nothing
  std::vector<scene::SilhouetteView> blind = views;
  for (scene::SilhouetteView& v : blind) v.mask = nullptr;
  CHECK(scene::contour_views(points, blind, 1.0f) == std::vector<int>(4, 0));
}
