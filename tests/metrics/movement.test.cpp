// metrics::surface_movement against movements whose answer is known: a bumpy
// reference moved onto the true sphere (a full correction: gain 1, no offset),
// the reference blown up (an offset, no correction), the reference left as it
// is (nothing moved), and one region pushed out (the added error in a tenth of
// the vertices). Lengths in the truth's unit box: the unit sphere has radius
// 0.5 there.
#include "difftrans/metrics/movement.hpp"

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <vector>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
namespace metrics = difftrans::metrics;
using difftrans::Vec3d;
using difftrans::Vec3f;

namespace {

// the sphere's vertices pushed along the radius by amplitude · f(direction)
template <class F>
io::Mesh radial(const io::Mesh& sphere, double amplitude, F f) {
  io::Mesh m = sphere;
  for (Vec3f& p : m.positions) {
    const Vec3d d = glm::normalize(Vec3d(p));
    p = Vec3f(Vec3d(p) + amplitude * f(d) * d);
  }
  return m;
}

double bumps(const Vec3d& d) { return std::cos(3.0 * d.x) * std::sin(2.0 * d.y + 0.5) + 0.2 * d.z; }

}  // namespace

TEST_CASE("surface movement: a reference moved onto the truth is a full correction") {
  const io::Mesh truth = uv_sphere(1.0, 96, 192);
  const io::Mesh reference = radial(uv_sphere(1.0, 48, 96), 0.04, bumps);
  // the reference's vertices put back on the sphere
  io::Mesh corrected = reference;
  for (Vec3f& p : corrected.positions) p = Vec3f(glm::normalize(Vec3d(p)));
  const metrics::SurfaceMovement s = metrics::surface_movement(corrected, reference, truth);
  MESSAGE("gain " << s.gain << " offset " << s.offset << " residual " << s.residual_rms << " rms before "
                  << s.rms_before << " after " << s.rms_after);
  REQUIRE(s.before.size() == corrected.positions.size());
  // the bumps are 0.02 in the unit box at most, the truth's facets 1e-4 off the sphere
  CHECK(s.rms_before > 0.005);
  CHECK(s.rms_after < 0.05 * s.rms_before);
  CHECK(s.gain == doctest::Approx(1.0).epsilon(0.05));
  CHECK(std::abs(s.offset) < 0.02 * s.rms_before);
  CHECK(s.correlation > 0.99);
  CHECK(s.improved_fraction > 0.9);
  // after ≈ before + moved at every vertex
  for (std::size_t v = 0; v < s.before.size(); v += 37)
    CHECK(std::abs(s.after[v] - (s.before[v] + s.moved[v])) < 1e-3);
}

TEST_CASE("surface movement: a reference blown up is an offset, not a correction") {
  const io::Mesh truth = uv_sphere(1.0, 96, 192);
  const io::Mesh reference = radial(uv_sphere(1.0, 48, 96), 0.04, bumps);
  const io::Mesh inflated = radial(reference, 0.02, [](const Vec3d&) { return 1.0; });
  const metrics::SurfaceMovement s = metrics::surface_movement(inflated, reference, truth);
  MESSAGE("gain " << s.gain << " offset " << s.offset << " mean before " << s.mean_before << " after "
                  << s.mean_after);
  // 0.02 along the radius of a unit sphere, 0.01 in the unit box, outwards
  CHECK(s.mean_moved == doctest::Approx(0.01).epsilon(0.05));
  CHECK(s.offset == doctest::Approx(0.01).epsilon(0.1));
  CHECK(std::abs(s.gain) < 0.1);
  CHECK(s.mean_after - s.mean_before == doctest::Approx(0.01).epsilon(0.05));
  // and shrunk: the sign follows
  const io::Mesh shrunk = radial(reference, -0.02, [](const Vec3d&) { return 1.0; });
  const metrics::SurfaceMovement t = metrics::surface_movement(shrunk, reference, truth);
  CHECK(t.offset == doctest::Approx(-0.01).epsilon(0.1));
}

TEST_CASE("surface movement: a mesh left where it was moved nowhere") {
  const io::Mesh truth = uv_sphere(1.0, 96, 192);
  const io::Mesh reference = radial(uv_sphere(1.0, 48, 96), 0.04, bumps);
  const metrics::SurfaceMovement s = metrics::surface_movement(reference, reference, truth);
  CHECK(s.rms_moved < 1e-6);
  CHECK(std::abs(s.gain) < 1e-3);
  CHECK(s.rms_after == doctest::Approx(s.rms_before).epsilon(1e-4));
  CHECK(s.worst_tenth_share == 0.0);  // no error added anywhere
}

TEST_CASE("surface movement: one region pushed out adds its error in a tenth of the vertices") {
  const io::Mesh truth = uv_sphere(1.0, 96, 192);
  const io::Mesh reference = uv_sphere(1.0, 48, 96);
  // a cap around +x (about 5 % of the sphere's area) pushed out, the rest in place
  const io::Mesh dented = radial(reference, 0.05, [](const Vec3d& d) { return d.x > 0.9 ? 1.0 : 0.0; });
  const metrics::SurfaceMovement s = metrics::surface_movement(dented, reference, truth);
  MESSAGE("share " << s.worst_tenth_share << " improved " << s.improved_fraction);
  CHECK(s.worst_tenth_share > 0.95);
  // against an even push outwards of the whole sphere
  const io::Mesh blown = radial(reference, 0.05, [](const Vec3d&) { return 1.0; });
  const metrics::SurfaceMovement b = metrics::surface_movement(blown, reference, truth);
  CHECK(b.worst_tenth_share < 0.2);
}

TEST_CASE("surface movement: empty input is refused") {
  const io::Mesh sphere = uv_sphere(1.0, 8, 16);
  io::Mesh empty;
  CHECK_THROWS_AS(metrics::surface_movement(empty, sphere, sphere), std::invalid_argument);
  CHECK_THROWS_AS(metrics::surface_movement(sphere, empty, sphere), std::invalid_argument);
}
