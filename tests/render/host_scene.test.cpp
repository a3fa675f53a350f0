// The host scene: which buffers the views expose to the reader, parameter
// and gradient arrays that match in size, and a BVH that follows the mesh.
#include "support/ad_check.hpp"
#include "support/shapes.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/render/host_scene.hpp"

using namespace dt_test;
namespace dr = difftrans::render;

TEST_CASE("views, parameters and gradients line up") {
  const Shape box = make_box(0.5f, 0.5f, 0.5f);
  dr::HostScene s(box.positions, box.triangles, "box");
  s.set_homogeneous_absorption(Vec3f(1.0f, 2.0f, 3.0f));
  const dr::SceneView plain = s.view(false);
  CHECK_FALSE(plain.mesh.positions.differentiable());
  CHECK_FALSE(plain.ior.differentiable());
  s.differentiate[dr::param_environment] = false;
  const dr::SceneView ad_view = s.view(true);
  CHECK(ad_view.mesh.positions.buffer == dr::param_positions);
  CHECK(ad_view.ior.buffer == dr::param_ior);
  CHECK(ad_view.absorption.params.buffer == dr::param_absorption);
  CHECK(ad_view.environment.texels.buffer == -1);
  const ad::ParamSet set = s.params();
  CHECK(set.buffers[dr::param_positions].size == 24);
  CHECK(set.buffers[dr::param_absorption].size == 3);
  dr::SceneGradient g(s);
  CHECK(g.positions.size() == 24);
  CHECK(g.absorption.size() == 3);
  ad::ParamSet with = set;
  g.attach(with);
  CHECK(with.buffers[dr::param_ior].gradient == g.ior.data());
  // absorption is stored raw: softplus(raw) is the coefficient
  CHECK(difftrans::softplus(s.absorption_raw[2]) == doctest::Approx(3.0f));
}

TEST_CASE("the BVH follows the positions") {
  const Shape box = make_box(0.5f, 0.5f, 0.5f);
  dr::HostScene s(box.positions, box.triangles, "box");
  CHECK(s.accel().intersect(Vec3f(0, 0, 3), Vec3f(0, 0, -1)).t == doctest::Approx(2.5f));
  for (float& x : s.mesh.positions) x *= 2.0f;
  s.positions_changed();
  CHECK(s.accel().intersect(Vec3f(0, 0, 3), Vec3f(0, 0, -1)).t == doctest::Approx(2.0f));
  CHECK(s.mesh.vertex_normals[1] == doctest::Approx(-1.0f / std::sqrt(3.0f)));
}

TEST_CASE("HostScene::view makes the softplus table again when the raw absorption changes in place") {
  dr::HostScene s;
  const Vec3i res(3, 4, 2);
  std::vector<float> raw(std::size_t(res.x * res.y * res.z * 3));
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = -1.0f + 0.1f * float(i);
  s.set_grid_absorption(res, Vec3f(-0.5f), Vec3f(0.5f), raw);
  const auto read = [&](std::int32_t i) {
    const dr::SceneView v = s.view(false);
    REQUIRE(v.absorption.softplus_table != nullptr);
    ad::ParamReader<float> r(nullptr);  // the grid's buffer is frozen in a plain view
    return scene::detail::sigma_of_parameter<float>(r, v.absorption, i);
  };
  CHECK(read(7) == ad::softplus(s.absorption_raw[7]));
  s.absorption_raw[7] += 1.5f;  // as an optimizer step writes it
  CHECK(read(7) == ad::softplus(s.absorption_raw[7]));
  s.set_homogeneous_absorption(Vec3f(0.25f, 1.0f, 3.0f));  // fewer values
  CHECK(std::abs(read(2) - 3.0f) < 1e-5f);
}
