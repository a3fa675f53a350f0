// The shading-normal error (metrics/normals.hpp) against closed forms: a
// sphere against a finer tessellation of itself (the floor: the samples'
// spacing), an ellipsoid against the sphere (the angle between the
// ellipsoid's gradient and the radial direction, the nearest point of a
// sphere lying on the radius), a mesh turned inside out (180°), and bumps
// that leave the chamfer distance tiny and the normals tilted.
#include "difftrans/metrics/normals.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
namespace metrics = difftrans::metrics;
using difftrans::Vec3d;
using difftrans::Vec3f;

namespace {

constexpr double pi = 3.14159265358979323846;

io::Mesh scaled(io::Mesh m, const Vec3d& s) {
  for (Vec3f& p : m.positions) p = Vec3f(Vec3d(p) * s);
  return m;
}

}  // namespace

TEST_CASE("normal error: a sphere against a finer tessellation of itself reads the samples' spacing") {
  metrics::GeometryOptions options;
  options.samples = 100000;
  const metrics::NormalError e = metrics::normal_error(uv_sphere(1.0, 96, 192), uv_sphere(1.0, 128, 256), options);
  MESSAGE("mean " << e.mean_deg << " median " << e.median_deg << " p90 " << e.p90_deg);
  CHECK(e.samples == options.samples);
  // normalized radius 0.5, 1e5 samples over its area pi: nearest-sample
  // distances of about half the spacing sqrt(pi / 1e5) = 0.0056, i.e. 0.32°
  CHECK(e.mean_deg < 0.6);
  CHECK(e.p90_deg < 1.0);
  CHECK(e.median_deg <= e.p90_deg);
  CHECK(e.rms_deg >= e.mean_deg);
}

TEST_CASE("normal error: an ellipsoid against the sphere reads the angle between gradient and radius") {
  const Vec3d axes(1.15, 1.0, 0.85);
  const io::Mesh ellipsoid = scaled(uv_sphere(1.0, 128, 256), axes);
  const io::Mesh sphere = uv_sphere(1.0, 128, 256);
  metrics::GeometryOptions options;
  options.samples = 100000;
  options.normalize = false;  // the sphere's centre and frame as given: the nearest point lies on the radius
  const metrics::NormalError e = metrics::normal_error(ellipsoid, sphere, options);
  // the closed form at the same area-weighted points of the ellipsoid
  std::vector<double> exact;
  for (const metrics::SurfaceSample& s : metrics::sample_surface_at(ellipsoid, options.samples, options.seed)) {
    const Vec3d x = s.point;
    const Vec3d gradient = x / (axes * axes);
    exact.push_back(std::acos(std::clamp(glm::dot(glm::normalize(gradient), glm::normalize(x)), -1.0, 1.0)) * 180.0 /
                    pi);
  }
  const metrics::NormalError want = metrics::angle_statistics(exact);
  MESSAGE("mean " << e.mean_deg << " (closed form " << want.mean_deg << "), p90 " << e.p90_deg << " ("
                  << want.p90_deg << ")");
  CHECK(want.mean_deg > 4.0);  // a real tilt, far above the floor of the test above
  CHECK(std::abs(e.mean_deg - want.mean_deg) < 0.05 * want.mean_deg + 0.3);
  CHECK(std::abs(e.p90_deg - want.p90_deg) < 0.05 * want.p90_deg + 0.5);
}

TEST_CASE("normal error: a mesh turned inside out reads 180 degrees") {
  io::Mesh inside_out = uv_sphere(1.0, 48, 96);
  for (auto& t : inside_out.triangles) std::swap(t.y, t.z);
  metrics::GeometryOptions options;
  options.samples = 20000;
  const metrics::NormalError e = metrics::normal_error(inside_out, uv_sphere(1.0, 48, 96), options);
  CHECK(e.mean_deg > 179.0);
  CHECK(e.median_deg > 179.0);
}

TEST_CASE("normal error: bumps far below the chamfer distance's notice tilt the normals") {
  // A radial ripple of amplitude a and angular frequency k on a unit sphere:
  // the surface moves by at most a, its slope reaches a·k, so the normals tilt
  // by up to atan(a k): 0.004 × 24 ≈ 5.5°, about what stage 1 leaves on a
  // sphere from its silhouettes.
  const double a = 0.004, k = 24.0;
  io::Mesh rippled = uv_sphere(1.0, 192, 384);
  for (Vec3f& p : rippled.positions) {
    const Vec3d x = glm::normalize(Vec3d(p));
    const double theta = std::acos(std::clamp(x.y, -1.0, 1.0)), phi = std::atan2(x.z, x.x);
    p = Vec3f(x * (1.0 + a * std::sin(k * theta) * std::cos(k * phi)));
  }
  const io::Mesh sphere = uv_sphere(1.0, 192, 384), retessellated = uv_sphere(1.0, 160, 320);
  metrics::GeometryOptions options;
  options.samples = 100000;
  const metrics::NormalError e = metrics::normal_error(rippled, sphere, options);
  const metrics::NormalError e0 = metrics::normal_error(retessellated, sphere, options);
  const metrics::GeometryMetrics g = metrics::evaluate_geometry(rippled, sphere, options);
  const metrics::GeometryMetrics g0 = metrics::evaluate_geometry(retessellated, sphere, options);
  MESSAGE("chamfer " << g.chamfer << " (another tessellation of the sphere: " << g0.chamfer << "), normal error mean "
                     << e.mean_deg << " (" << e0.mean_deg << ") p90 " << e.p90_deg);
  // the chamfer distance hardly tells the ripple from a retessellation (its
  // floor is the samples' spacing), the normal error does
  CHECK(g.chamfer < 1.5 * g0.chamfer);
  CHECK(g.f1 > 0.99);
  CHECK(e.mean_deg > 2.0);
  CHECK(e.mean_deg > 5.0 * e0.mean_deg);
  CHECK(e.p90_deg < std::atan(a * k * std::sqrt(2.0)) * 180.0 / pi + 1.0);
}
