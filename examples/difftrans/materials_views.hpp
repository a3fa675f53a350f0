// The training views of stage 2 from a loaded scene: per frame with an image
// and a mask, its camera, pixels and mask (pipeline::Stage2View) and the same
// mask as a silhouette target (pipeline::Stage1View). Shared by
// `difftrans reconstruct --stages materials` and the stage-2 diagnostics.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <vector>

#include "command.hpp"

#include "difftrans/io/dataset.hpp"
#include "difftrans/render/views.hpp"
#include "pipeline/materials.hpp"

namespace difftrans::cli {

struct MaterialsViews {
  std::vector<pipeline::Stage2View> views;       // point into the scene's images and masks
  std::vector<pipeline::Stage1View> mask_views;  // the masks as 0 / 1 silhouette targets
};

// Frames without a mask are left out (with a warning), environment-only
// frames silently; throws when no frame is left or a size disagrees.
inline MaterialsViews materials_training_views(const io::Scene& scene) {
  MaterialsViews out;
  for (const io::Frame& f : scene.train.frames) {
    if (f.environment_only) continue;
    if (f.mask.width == 0) {
      warn("materials: frame " + f.name + " has no mask; it is not used");
      continue;
    }
    pipeline::Stage2View v;
    v.camera = render::camera_of(f);
    if (f.image.width != v.camera.width || f.image.height != v.camera.height || f.mask.width != v.camera.width ||
        f.mask.height != v.camera.height)
      throw std::runtime_error("materials: frame " + f.name + ": image or mask size differs from its camera");
    v.image = f.image.rgb.data();
    v.mask = f.mask.inside.data();
    out.views.push_back(v);
    pipeline::Stage1View m;
    m.camera = v.camera;
    m.target.resize(f.mask.inside.size());
    for (std::size_t p = 0; p < m.target.size(); ++p) m.target[p] = f.mask.inside[p] ? 1.0f : 0.0f;
    out.mask_views.push_back(std::move(m));
  }
  if (out.views.empty()) throw std::runtime_error("materials: no training frame has an image and a mask");
  return out;
}

}  // namespace difftrans::cli
