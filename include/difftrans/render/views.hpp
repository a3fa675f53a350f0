// Rendering whole views for programs: a HostScene from an io mesh, material and
// environment image; the box-filtered image and the centre-ray object mask of a
// camera; the reference settings of docs/benchmark-scenes.md.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "difftrans/io/dataset.hpp"
#include "difftrans/io/image.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh.hpp"
#include "difftrans/render/passes.hpp"

namespace difftrans::render {

// The material's IoR and absorption on a scene, replacing what it had.
inline void set_material(HostScene& s, const io::Material& material) {
  s.ior = float(material.ior);
  switch (material.absorption) {
    case io::AbsorptionType::none:
      s.absorption_kind = scene::AbsorptionKind::none;
      s.absorption_raw.clear();
      break;
    case io::AbsorptionType::homogeneous: s.set_homogeneous_absorption(material.sigma); break;
    case io::AbsorptionType::grid: {
      const io::AbsorptionGrid& g = material.grid;
      std::vector<float> raw(g.sigma.size());
      for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = scene::raw_from_sigma(g.sigma[i]);
      s.set_grid_absorption(g.res, g.lo, g.hi, std::move(raw));
      break;
    }
  }
}

// A host scene owning the mesh (its positions as given: normalize first if
// the frame asks for it) with the material's IoR and absorption; the
// environment is a constant white until set_environment is called.
inline HostScene make_host_scene(const io::Mesh& mesh, const io::Material& material, const std::string& name = "mesh") {
  HostScene s(io::flat_positions(mesh), io::flat_triangles(mesh), name);
  set_material(s, material);
  return s;
}

// An equirectangular environment (docs/conventions.md, row 0 = +Y).
inline void set_environment(HostScene& s, const io::Image& equirect) {
  s.set_environment_map(equirect.rgb, equirect.width, equirect.height);
}

// docs/benchmark-scenes.md reference renders: depth 16, no pruning, exact absorption
// integration, n x n stratified samples per pixel (n = 4: 16 samples).
inline PassOptions reference_pass_options(int max_depth = 16, int samples_per_axis = 4) {
  PassOptions o;
  o.trace.max_depth = max_depth;
  o.trace.prune_throughput = 0.0f;
  o.trace.integration.samples = 0;
  o.samples_per_axis = samples_per_axis;
  return o;
}

// The view's linear radiance: each pixel the box-filtered mean over the
// pass's stratified samples.
inline io::Image render_view(const HostScene& s, const scene::Camera& camera, const PassOptions& options,
                             PassStats* stats = nullptr) {
  io::Image image(camera.width, camera.height);
  image.rgb = render_image<float>(s, camera, options, stats);
  return image;
}

// The same with an explicit escape for rays that leave the object (e.g. a
// procedural room: render::fixed_escape(scene::Room{...})).
template <class Escape>
io::Image render_view_with(const HostScene& s, const scene::Camera& camera, const PassOptions& options,
                           const Escape& escape, PassStats* stats = nullptr) {
  io::Image image(camera.width, camera.height);
  image.rgb = render_image_with<float>(s, camera, options, escape, stats);
  return image;
}

// The object mask: inside where the ray through the pixel's centre hits the mesh.
inline io::Mask object_mask(const HostScene& s, const scene::Camera& camera) {
  io::Mask mask(camera.width, camera.height);
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const scene::Ray r = camera.generate_ray(x, y);
      mask.inside[std::size_t(y) * std::size_t(camera.width) + std::size_t(x)] =
          s.accel().intersect(r.origin, r.direction, 0.0f, 3.4e38f).hit() ? 1 : 0;
    }
  return mask;
}

// A float camera from a camera-to-world matrix in double and pinhole intrinsics.
inline scene::Camera camera_from(const Mat4<double>& camera_to_world, double fx, double fy, double cx, double cy,
                                 int width, int height) {
  return scene::Camera::from_intrinsics(Mat4<float>(camera_to_world), float(fx), float(fy), float(cx), float(cy),
                                        width, height);
}

// The camera of a frame (pinhole intrinsics, camera-to-world).
inline scene::Camera camera_of(const io::Frame& f) {
  const auto& k = f.intrinsics;
  return camera_from(f.camera_to_world, k.fx, k.fy, k.cx, k.cy, k.width, k.height);
}

}  // namespace difftrans::render
