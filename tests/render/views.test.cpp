// Whole views: a HostScene from io types, the centre-ray mask against the
// projected square of a cube, radiance of clear glass under a constant sky
// (energy conservation), absorption darkening, grid materials.
#include <doctest/doctest.h>

#include <cmath>

#include "difftrans/render/views.hpp"
#include "support/shapes.hpp"

namespace dr = difftrans::render;
namespace io = difftrans::io;
namespace sc = difftrans::scene;
using difftrans::Vec3f;
using difftrans::Vec3i;

namespace {
io::Mesh cube_mesh(float half) {
  const auto s = dt_test::make_box(half, half, half);
  io::Mesh m;
  for (size_t i = 0; i < s.positions.size(); i += 3) m.positions.emplace_back(s.positions[i], s.positions[i + 1], s.positions[i + 2]);
  for (size_t i = 0; i < s.triangles.size(); i += 3) m.triangles.emplace_back(s.triangles[i], s.triangles[i + 1], s.triangles[i + 2]);
  return m;
}
io::Mesh sphere_mesh() {
  const auto s = dt_test::make_icosphere(0.5f, 3);
  io::Mesh m;
  for (size_t i = 0; i < s.positions.size(); i += 3) m.positions.emplace_back(s.positions[i], s.positions[i + 1], s.positions[i + 2]);
  for (size_t i = 0; i < s.triangles.size(); i += 3) m.triangles.emplace_back(s.triangles[i], s.triangles[i + 1], s.triangles[i + 2]);
  return m;
}
}  // namespace

TEST_CASE("make_host_scene carries mesh, IoR and absorption; set_material replaces them") {
  io::Material m;
  m.ior = 1.6;
  m.absorption = io::AbsorptionType::homogeneous;
  m.sigma = Vec3f(1.0f, 2.0f, 3.0f);
  const dr::HostScene s = dr::make_host_scene(cube_mesh(0.5f), m);
  CHECK(s.mesh.num_vertices() == 8);
  CHECK(s.mesh.num_triangles() == 12);
  CHECK(s.ior == doctest::Approx(1.6));
  CHECK(s.absorption_kind == sc::AbsorptionKind::homogeneous);
  CHECK(std::log1p(std::exp(double(s.absorption_raw[2]))) == doctest::Approx(3.0).epsilon(1e-5));

  m.absorption = io::AbsorptionType::grid;
  m.grid = io::bands_absorption_grid();
  const dr::HostScene g = dr::make_host_scene(cube_mesh(0.5f), m);
  CHECK(g.absorption_kind == sc::AbsorptionKind::grid);
  CHECK(g.absorption_res == m.grid.res);
  CHECK(g.absorption_raw.size() == m.grid.sigma.size());
  CHECK(std::log1p(std::exp(double(g.absorption_raw[0]))) == doctest::Approx(m.grid.sigma[0]).epsilon(1e-5));

  // set_material replaces what a scene had: the grid scene made clear, then homogeneous again
  dr::HostScene r = dr::make_host_scene(cube_mesh(0.5f), m);  // the grid
  io::Material clear;
  clear.ior = 1.3;
  dr::set_material(r, clear);
  CHECK(r.ior == doctest::Approx(1.3));
  CHECK(r.absorption_kind == sc::AbsorptionKind::none);
  CHECK(r.absorption_raw.empty());
  m.absorption = io::AbsorptionType::homogeneous;
  dr::set_material(r, m);
  CHECK(r.absorption_kind == sc::AbsorptionKind::homogeneous);
  CHECK(std::log1p(std::exp(double(r.absorption_raw[1]))) == doctest::Approx(2.0).epsilon(1e-5));
}

TEST_CASE("object_mask: the projected square of a cube seen face on") {
  const float half = 0.5f;
  const dr::HostScene s = dr::make_host_scene(cube_mesh(half), io::Material{});
  const int n = 64;
  const sc::Camera cam = sc::protocol_camera(Vec3f(0.0f, 0.0f, 1.0f), n, n);
  const io::Mask mask = dr::object_mask(s, cam);
  // the front face at depth 3 - half projects to a square of half-size f half / (3 - half)
  const double r = double(cam.fx) * half / (3.0 - half);
  int side = 0;
  for (int x = 0; x < n; ++x) side += std::abs(x + 0.5 - 0.5 * n) < r;
  CHECK(mask.count() == size_t(side * side));
  CHECK(mask.at(n / 2, n / 2));
  CHECK(!mask.at(0, 0));
}

TEST_CASE("render_view: clear glass under a constant sky returns the sky (energy conservation)") {
  dr::HostScene s = dr::make_host_scene(sphere_mesh(), io::Material{});
  s.ior = 1.5f;
  s.set_constant_environment(Vec3f(0.25f, 0.5f, 1.0f));
  const sc::Camera cam = sc::protocol_camera(Vec3f(0.3f, 0.5f, 1.0f), 16, 16);
  dr::PassStats stats;
  const io::Image im = dr::render_view(s, cam, dr::reference_pass_options(16, 2), &stats);
  CHECK(stats.rays == 16 * 16 * 4);
  const io::Mask mask = dr::object_mask(s, cam);
  CHECK(mask.count() > 20);
  // R + T = 1 at every interface: what does not reach the camera is the
  // weight of the branches cut at depth 16 (grazing paths trapped by TIR)
  double mean_blue = 0.0;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      const Vec3f c = im.at(x, y);
      CHECK(c.x == doctest::Approx(0.25 * c.z).epsilon(1e-5));  // grey throughput
      CHECK(c.z <= 1.0f + 1e-5f);
      CHECK(c.z > 0.9f);
      bool near_object = false;  // a sub-pixel sample may hit the object next to the mask
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          near_object = near_object || (x + dx >= 0 && x + dx < 16 && y + dy >= 0 && y + dy < 16 && mask.at(x + dx, y + dy));
      if (!near_object) CHECK(c.z == 1.0f);
      mean_blue += c.z / 256.0;
    }
  CHECK(stats.trace.cut_weight > 0.0);
  CHECK(mean_blue == doctest::Approx(1.0 - stats.trace.cut_weight / double(stats.rays)).epsilon(1e-5));
  // absorption darkens the object's pixels only, red (sigma large) the most
  io::Material green;
  green.ior = 1.5;
  green.absorption = io::AbsorptionType::homogeneous;
  green.sigma = Vec3f(4.0f, 0.4f, 4.0f);
  dr::HostScene a = dr::make_host_scene(sphere_mesh(), green);
  a.set_constant_environment(Vec3f(1.0f));
  const io::Image ia = dr::render_view(a, cam, dr::reference_pass_options(16, 1));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      const Vec3f c = ia.at(x, y);
      if (mask.at(x, y) && x > 4 && x < 12 && y > 4 && y < 12) {
        CHECK(c.x < 0.6f);
        CHECK(c.y > c.x);
      }
      if (x == 0 && y == 0) CHECK(c.x == doctest::Approx(1.0));
    }
}

TEST_CASE("camera_from matches the float camera of the same matrix") {
  const sc::Camera a = sc::protocol_camera(Vec3f(1.0f, 0.4f, -0.3f), 32, 24);
  const difftrans::Mat4<double> m(a.camera_to_world);
  const sc::Camera b = dr::camera_from(m, a.fx, a.fy, a.cx, a.cy, 32, 24);
  const auto ra = a.generate_ray(5, 7), rb = b.generate_ray(5, 7);
  CHECK(glm::length(ra.direction - rb.direction) < 1e-6f);
  CHECK(glm::length(ra.origin - rb.origin) < 1e-6f);
}
