// ray_batch_gradient: the per-ray fused pass gives the same loss and gradient
// as render_image followed by render_gradient with the loss's pixel adjoints.
#include "difftrans/render/ray_batch.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "support/scenes.hpp"

namespace dr = difftrans::render;
namespace ds = difftrans::scene;
using difftrans::Vec3f;

namespace {

double rel_l2(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += double(a[i] - b[i]) * double(a[i] - b[i]);
    den += double(b[i]) * double(b[i]);
  }
  return std::sqrt(num / std::max(den, 1e-30));
}

}  // namespace

TEST_CASE("ray_batch_gradient agrees with render_image + render_gradient under an L2 loss") {
  dr::HostScene s = dt_test::sphere_scene();
  const ds::Camera cam = ds::protocol_camera(Vec3f(0.3f, 0.4f, 0.87f), 24, 24);
  dr::PassOptions opt;
  opt.trace.max_depth = 4;
  const std::vector<float> image = dr::render_image(s, cam, opt);
  // target: the image, slightly changed, so the L2 loss has a gradient
  std::vector<float> target(image.size());
  for (std::size_t i = 0; i < image.size(); ++i) target[i] = 0.9f * image[i] + 0.02f * float(i % 7);
  std::vector<float> adjoint(image.size());
  double loss_ref = 0.0;
  for (std::size_t i = 0; i < image.size(); ++i) {
    const float d = image[i] - target[i];
    loss_ref += double(d) * d;
    adjoint[i] = 2.0f * d;
  }
  dr::SceneGradient g_ref(s);
  dr::render_gradient(s, cam, adjoint.data(), g_ref, opt);

  std::vector<dr::BatchRay> rays;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const ds::Ray r = cam.generate_ray(x, y);
      rays.push_back({r.origin, r.direction});
    }
  dr::SceneGradient g(s);
  const dr::RayBatchResult rb = dr::ray_batch_gradient(
      s, rays,
      [&](std::int32_t i, const Vec3f& L, Vec3f& dL) {
        double l = 0.0;
        for (int c = 0; c < 3; ++c) {
          const float d = L[c] - target[std::size_t(i) * 3 + std::size_t(c)];
          l += double(d) * d;
          dL[c] = 2.0f * d;
        }
        return l;
      },
      g, opt, true);
  CHECK(rb.stats.rays == std::int64_t(rays.size()));
  CHECK(rb.stats.overflowed_rays == 0);
  CHECK(rb.loss == doctest::Approx(loss_ref).epsilon(1e-5));
  for (std::size_t i = 0; i < rays.size(); ++i)
    for (int c = 0; c < 3; ++c) REQUIRE(rb.radiance[i][c] == doctest::Approx(image[3 * i + std::size_t(c)]).epsilon(1e-6));
  CHECK(g.ior[0] == doctest::Approx(g_ref.ior[0]).epsilon(1e-4));
  CHECK(std::abs(g_ref.ior[0]) > 0.0f);
  CHECK(rel_l2(g.positions, g_ref.positions) < 1e-4);
  CHECK(rel_l2(g.absorption, g_ref.absorption) < 1e-4);
  CHECK(rel_l2(g.environment, g_ref.environment) < 1e-4);

  SUBCASE("a zero adjoint adds nothing; rays still counted and their loss summed") {
    dr::SceneGradient z(s);
    const dr::RayBatchResult r0 = dr::ray_batch_gradient(
        s, rays, [](std::int32_t, const Vec3f&, Vec3f& dL) { dL = Vec3f(0.0f); return 1.0; }, z, opt);
    CHECK(r0.loss == doctest::Approx(double(rays.size())));
    CHECK(z.ior[0] == 0.0f);
    for (float v : z.positions) REQUIRE(v == 0.0f);
  }
}

TEST_CASE("ray_batch_gradient clip_geometry: one ray's vertex gradient is scaled to the cap, other buffers untouched") {
  dr::HostScene s = dt_test::sphere_scene();
  s.two_level_normals = false;  // normals from the one-ring: the whole vertex gradient is in `positions`
  const ds::Camera cam = ds::protocol_camera(Vec3f(0.3f, 0.4f, 0.87f), 24, 24);
  const ds::Ray r = cam.generate_ray(12, 11);
  const std::vector<dr::BatchRay> rays{{r.origin, r.direction}};
  const auto loss = [](std::int32_t, const Vec3f& L, Vec3f& dL) {
    dL = 2.0f * L;
    return double(glm::dot(L, L));
  };
  dr::PassOptions opt;
  opt.trace.max_depth = 4;
  dr::SceneGradient free(s), capped(s), loose(s);
  dr::ray_batch_gradient(s, rays, loss, free, opt);
  double norm = 0.0;
  for (float g : free.positions) norm += double(g) * g;
  norm = std::sqrt(norm);
  REQUIRE(norm > 0.0);
  const float cap = float(0.25 * norm);
  const dr::RayBatchResult rc = dr::ray_batch_gradient(s, rays, loss, capped, opt, false, cap);
  CHECK(rc.clipped_rays == 1);
  for (std::size_t i = 0; i < free.positions.size(); ++i)
    REQUIRE(capped.positions[i] == doctest::Approx(0.25 * free.positions[i]).epsilon(1e-4).scale(1e-12));
  CHECK(capped.ior[0] == doctest::Approx(free.ior[0]));
  CHECK(rel_l2(capped.absorption, free.absorption) < 1e-6);
  const dr::RayBatchResult rl = dr::ray_batch_gradient(s, rays, loss, loose, opt, false, float(4.0 * norm));
  CHECK(rl.clipped_rays == 0);
  CHECK(rel_l2(loose.positions, free.positions) < 1e-6);
}

TEST_CASE("ray_batch_gradient clip_ior: each ray's IoR derivative is capped in magnitude, the rest untouched") {
  dr::HostScene s = dt_test::sphere_scene();
  const ds::Camera cam = ds::protocol_camera(Vec3f(0.3f, 0.4f, 0.87f), 24, 24);
  std::vector<dr::BatchRay> rays;
  for (int x : {9, 12, 15}) {
    const ds::Ray r = cam.generate_ray(x, 11);
    rays.push_back({r.origin, r.direction});
  }
  const auto loss = [](std::int32_t, const Vec3f& L, Vec3f& dL) {
    dL = 2.0f * L;
    return double(glm::dot(L, L));
  };
  dr::PassOptions opt;
  opt.trace.max_depth = 4;
  // each ray's own IoR derivative
  std::vector<float> each;
  for (const dr::BatchRay& r : rays) {
    dr::SceneGradient g(s);
    dr::ray_batch_gradient(s, std::vector<dr::BatchRay>{r}, loss, g, opt);
    each.push_back(g.ior[0]);
  }
  std::vector<float> mags;
  for (float d : each) mags.push_back(std::abs(d));
  std::sort(mags.begin(), mags.end());
  REQUIRE(mags[0] > 0.0f);
  REQUIRE(mags[1] < 0.9f * mags[2]);  // a cap between the two largest clips one ray
  const float cap = 0.5f * (mags[1] + mags[2]);
  double expected = 0.0;
  for (float d : each) expected += std::abs(d) > cap ? (d > 0.0f ? cap : -cap) : d;
  dr::SceneGradient free(s), capped(s);
  dr::ray_batch_gradient(s, rays, loss, free, opt);
  const dr::RayBatchResult rc = dr::ray_batch_gradient(s, rays, loss, capped, opt, false, 0.0f, cap);
  CHECK(rc.clipped_ior_rays == 1);
  CHECK(rc.clipped_rays == 0);
  CHECK(capped.ior[0] == doctest::Approx(expected).epsilon(1e-4));
  CHECK(capped.ior[0] != doctest::Approx(free.ior[0]).epsilon(1e-3));
  CHECK(rel_l2(capped.positions, free.positions) < 1e-6);
  CHECK(rel_l2(capped.absorption, free.absorption) < 1e-6);
}
