// Which absorption model stage 2 fits: none (clear), homogeneous (one RGB σ)
// or a grid, and the parts of choosing one from the photographs (Stage2's
// choose_absorption): a candidate's field carried onto a finer grid; the
// comparison of two candidates is model_choice.hpp's.
//
// The rule: candidates are tried in order of cost (none, homogeneous, then
// grids of 2, 4, 8, ... vertices per axis up to the configured resolution),
// each fitted on the training views less a held-out few, and the richer of
// two neighbours is kept only when it lowers the held-out loss measurably
// (model_choice.hpp; the same rays and pixels for both: common random
// numbers, so the rendering noise largely cancels). The minimum gain is
// there because the held-out pixels are many: a richer absorption always
// explains a little of what the stage-1 mesh and the recovered environment
// get wrong, and that gain is "significant" with thousands of pixels yet is
// not the object's colour.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/scene/absorption.hpp"
#include "pipeline/model_choice.hpp"

namespace difftrans::pipeline {

enum class AbsorptionModel : int { none, homogeneous, grid, automatic };
inline const std::array<const char*, 4>& enum_names(AbsorptionModel) {
  static const std::array<const char*, 4> names{"none", "homogeneous", "grid", "auto"};
  return names;
}

// σ (RGB) of an absorption at a point: homogeneous raw (3 values) or a grid
// of res³ vertices over [lo, hi], read as the tracer reads it
// (scene::sigma_at), the point clamped to the box; none: 0.
inline Vec3f absorption_sigma_at(scene::AbsorptionKind kind, const std::vector<float>& raw, const Vec3i& res,
                                 const Vec3f& lo, const Vec3f& hi, const Vec3f& p) {
  if (kind == scene::AbsorptionKind::none || raw.empty()) return Vec3f(0.0f);
  const scene::AbsorptionField field = kind == scene::AbsorptionKind::homogeneous
                                           ? scene::homogeneous_absorption(raw.data())
                                           : scene::grid_absorption(raw.data(), res, lo, hi);
  ad::ParamReader<float> reader(nullptr);
  return scene::sigma_at(reader, field, glm::clamp(p, lo, hi));
}

// The raw parameters of a grid of `res` vertices over [lo, hi] whose
// vertices take the given absorption's σ at their positions: a homogeneous
// field exactly, a coarser grid's trilinear field at the new vertices.
inline std::vector<float> resample_absorption(scene::AbsorptionKind kind, const std::vector<float>& raw,
                                              const Vec3i& from_res, const Vec3f& lo, const Vec3f& hi,
                                              const Vec3i& res) {
  std::vector<float> out(std::size_t(res.x) * std::size_t(res.y) * std::size_t(res.z) * 3);
  for (int k = 0; k < res.z; ++k)
    for (int j = 0; j < res.y; ++j)
      for (int i = 0; i < res.x; ++i) {
        const Vec3f q(float(i) / float(res.x - 1), float(j) / float(res.y - 1), float(k) / float(res.z - 1));
        const Vec3f sigma = absorption_sigma_at(kind, raw, from_res, lo, hi, lo + q * (hi - lo));
        for (int ch = 0; ch < 3; ++ch)
          out[std::size_t(scene::grid_index(res, i, j, k, ch))] = scene::raw_from_sigma(std::max(sigma[ch], 1e-4f));
      }
  return out;
}

}  // namespace difftrans::pipeline
