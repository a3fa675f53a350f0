// The radiance-field fit (coarse to fine, Adam on the host pool) overfits one
// small synthetic view: a camera inside a procedural room.
#include "difftrans/scene/radiance_field_fit.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "difftrans/scene/room.hpp"

namespace sc = difftrans::scene;
using difftrans::Vec3d;
using difftrans::Vec3f;

TEST_CASE("radiance field: the fit overfits one small view from inside a room") {
  // one 24 x 24 view from inside a 4 x 4 x 4 room, looking at a corner (three walls, two patterns)
  sc::Room room;
  room.half = 2.0f;
  room.panel_radiance = Vec3f(0.9f, 0.8f, 0.7f);  // radiance within [0, 1]: PSNR with peak 1
  room.ceiling_radiance = Vec3f(0.95f);
  const Vec3f eye(0.3f, -0.2f, 0.4f);
  const int W = 24, H = 24;
  const float fov = 1.1f;
  const Vec3f fwd = glm::normalize(Vec3f(1.0f, 0.6f, -1.0f));
  const Vec3f right = glm::normalize(glm::cross(fwd, Vec3f(0, 1, 0))), up = glm::cross(right, fwd);
  struct Obs {
    Vec3f origin, direction, radiance;
  };
  std::vector<Obs> obs;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float u = (2.0f * (x + 0.5f) / W - 1.0f) * std::tan(fov / 2), v = (1.0f - 2.0f * (y + 0.5f) / H) * std::tan(fov / 2);
      const Vec3f d = glm::normalize(fwd + u * right + v * up);
      obs.push_back({eye, d, room.radiance(eye, d)});
    }
  sc::FieldFitOptions opt;
  opt.resolutions = {16, 32};
  opt.iterations = {100, 300};
  opt.log_loss = false;  // the plain squared error that the PSNR below measures
  opt.batch = int(obs.size());
  opt.smoothness_density = opt.smoothness_colour = 0.0f;
  sc::FieldFitReport report;
  const sc::RadianceField field =
      sc::fit_radiance_field(obs, Vec3f(-2.2f), Vec3f(2.2f), opt, &report, [](int, int, double) {});
  CHECK(report.iterations == 400);
  double se = 0, var = 0;
  Vec3d mean(0.0);
  for (const Obs& o : obs) mean += Vec3d(o.radiance) / double(obs.size());
  for (const Obs& o : obs) {
    const Vec3f c = sc::field_radiance<float>(field.view(), o.origin, o.direction);
    for (int ch = 0; ch < 3; ++ch) {
      se += double(c[ch] - o.radiance[ch]) * double(c[ch] - o.radiance[ch]);
      var += (double(o.radiance[ch]) - mean[ch]) * (double(o.radiance[ch]) - mean[ch]);
    }
  }
  const double psnr = 10.0 * std::log10(1.0 / (se / (3.0 * obs.size())));  // radiance here lies in [0, 1]
  MESSAGE("overfit of one view: PSNR " << psnr << " dB, explained variance " << 1.0 - se / var);
  CHECK(psnr > 30.0);
  CHECK(se < 0.01 * var);
}
