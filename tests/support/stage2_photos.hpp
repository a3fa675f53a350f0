// Photographs of a small host scene for the stage-2 tests: reference
// renders (depth 8, 2 x 2 samples per pixel) from cameras on a golden-angle
// spiral, masks from the silhouette, and the views stage 2 takes.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/silhouette.hpp"
#include "difftrans/scene/camera.hpp"
#include "pipeline/geometry.hpp"
#include "pipeline/materials.hpp"

namespace dt_test {

namespace dr = difftrans::render;
namespace ds = difftrans::scene;
namespace pipeline = difftrans::pipeline;
using difftrans::Vec3f;

struct Photos {
  std::vector<ds::Camera> cams;
  std::vector<std::vector<float>> images;
  std::vector<std::vector<std::uint8_t>> masks;
};

// Reference photographs of a scene: depth 8, 2×2 samples per pixel; masks from the silhouette.
inline Photos photograph(const dr::HostScene& truth, int views, int res) {
  Photos p;
  dr::PassOptions ref;
  ref.trace.max_depth = 8;
  ref.samples_per_axis = 2;
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < views; ++i) {
    const double y = 0.8 * (1.0 - 2.0 * (i + 0.5) / views), r = std::sqrt(1.0 - y * y), phi = golden * i;
    const ds::Camera cam = ds::protocol_camera(Vec3f(float(r * std::cos(phi)), float(y), float(r * std::sin(phi))), res, res);
    p.cams.push_back(cam);
    p.images.push_back(dr::render_image(truth, cam, ref));
    std::vector<float> m = dr::silhouette_mask<float>(truth.mesh, cam);
    std::vector<std::uint8_t> mask(m.size());
    for (std::size_t k = 0; k < m.size(); ++k) mask[k] = m[k] > 0.5f;
    p.masks.push_back(std::move(mask));
  }
  return p;
}

inline std::vector<pipeline::Stage2View> views_of(const Photos& p) {
  std::vector<pipeline::Stage2View> v;
  for (std::size_t i = 0; i < p.cams.size(); ++i) v.push_back({p.cams[i], p.images[i].data(), p.masks[i].data()});
  return v;
}

inline std::vector<pipeline::Stage1View> mask_views_of(const Photos& p) {
  std::vector<pipeline::Stage1View> v;
  for (std::size_t i = 0; i < p.cams.size(); ++i) {
    pipeline::Stage1View s;
    s.camera = p.cams[i];
    for (std::uint8_t m : p.masks[i]) s.target.push_back(m ? 1.0f : 0.0f);
    v.push_back(std::move(s));
  }
  return v;
}

}  // namespace dt_test
