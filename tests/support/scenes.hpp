// Small host scenes shared by tests of different parts (BVH, device kernels).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/scene/absorption.hpp"
#include "support/shapes.hpp"

namespace dt_test {

// A glass icosphere (radius 0.5, 1280 triangles, IoR 1.5) with homogeneous
// absorption under the smooth test sky.
inline difftrans::render::HostScene sphere_scene() {
  const Shape ico = make_icosphere(0.5f, 3);
  difftrans::render::HostScene s(ico.positions, ico.triangles, "sphere");
  s.ior = 1.5f;
  s.set_environment_map(smooth_sky(32, 16), 32, 16);
  s.set_homogeneous_absorption(difftrans::Vec3f(0.3f, 0.6f, 1.2f));
  return s;
}

// The sphere with a grid of res³ absorption cells over [-0.55, 0.55]³ instead,
// sigma 0.2, 0.35, ... 0.8 repeating.
inline difftrans::render::HostScene absorbing_sphere_scene(int res) {
  difftrans::render::HostScene s = sphere_scene();
  std::vector<float> raw(std::size_t(res) * std::size_t(res) * std::size_t(res) * 3);
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = difftrans::scene::raw_from_sigma(0.2f + 0.15f * float(i % 5));
  s.set_grid_absorption(difftrans::Vec3i(res), difftrans::Vec3f(-0.55f), difftrans::Vec3f(0.55f), raw);
  return s;
}

// Spot (the data folder's mesh, normalized), IoR 1.45, homogeneous
// absorption, under the smooth test sky.
inline difftrans::render::HostScene spot_scene() {
  const Shape shape = load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj");
  difftrans::render::HostScene s(shape.positions, shape.triangles, "spot");
  s.ior = 1.45f;
  s.set_environment_map(smooth_sky(32, 16), 32, 16);
  s.set_homogeneous_absorption(difftrans::Vec3f(0.3f, 0.6f, 1.2f));
  return s;
}

}  // namespace dt_test
