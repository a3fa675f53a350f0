// The sub-pixel sample pattern every pass shares (render/pass_options.hpp):
// n × n stratum centres of the pixel, j-major, each weighted 1 / n².
#include <cmath>
#include <cstdint>
#include <vector>

#include "support/ad_check.hpp"

#include "difftrans/render/pass_options.hpp"

using difftrans::Vec3f;

TEST_CASE("for_each_pixel_sample: the stratum centres of one pixel, in order, weights summing to 1") {
  using namespace difftrans;
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.0f, 0.0f, 3.0f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.8f, 7, 5);
  for (const int n : {1, 2, 3}) {
    CAPTURE(n);
    const std::int64_t pix = 2 * 7 + 4;  // x 4, y 2
    std::vector<scene::Ray> rays;
    double weight = 0;
    render::for_each_pixel_sample(cam, n, pix, [&](const Vec3f& o, const Vec3f& d, float w) {
      rays.push_back(scene::Ray{o, d});
      weight += w;
    });
    REQUIRE(int(rays.size()) == n * n);
    CHECK(weight == doctest::Approx(1.0).epsilon(1e-6));
    const float inv = 1.0f / float(n);  // the offsets are (i + ½) · (1 / n), as the passes always took them
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const scene::Ray r = cam.generate_ray(4, 2, (float(i) + 0.5f) * inv, (float(j) + 0.5f) * inv);
        const scene::Ray& got = rays[std::size_t(j * n + i)];
        CHECK(got.origin == r.origin);
        CHECK(got.direction == r.direction);
      }
  }
}
