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
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/math.hpp"
#include "difftrans/scene/absorption.hpp"
#include "pipeline/model_choice.hpp"

namespace difftrans::pipeline {

enum class AbsorptionModel : int { none, homogeneous, grid, automatic };
inline const std::array<const char*, 4>& enum_names(AbsorptionModel) {
  static const std::array<const char*, 4> names{"none", "homogeneous", "grid", "auto"};
  return names;
}

// σ (RGB) of an absorption at a point: homogeneous raw (3 values) or a grid
// of res³ vertices over [lo, hi], trilinear in σ (as the tracer reads it;
// points outside the box are clamped to it); none: 0.
inline Vec3f absorption_sigma_at(scene::AbsorptionKind kind, const std::vector<float>& raw, const Vec3i& res,
                                 const Vec3f& lo, const Vec3f& hi, const Vec3f& p) {
  if (kind == scene::AbsorptionKind::none || raw.empty()) return Vec3f(0.0f);
  if (kind == scene::AbsorptionKind::homogeneous)
    return Vec3f(ad::softplus(raw[0]), ad::softplus(raw[1]), ad::softplus(raw[2]));
  int cell[3];
  float t[3];
  for (int a = 0; a < 3; ++a) {
    const float g = std::clamp((p[a] - lo[a]) / (hi[a] - lo[a]), 0.0f, 1.0f) * float(res[a] - 1);
    cell[a] = std::min(int(g), res[a] - 2);
    t[a] = g - float(cell[a]);
  }
  Vec3f s(0.0f);
  for (int c = 0; c < 8; ++c) {
    const int i = cell[0] + (c & 1), j = cell[1] + ((c >> 1) & 1), k = cell[2] + ((c >> 2) & 1);
    const float w = ((c & 1) ? t[0] : 1.0f - t[0]) * (((c >> 1) & 1) ? t[1] : 1.0f - t[1]) *
                    (((c >> 2) & 1) ? t[2] : 1.0f - t[2]);
    for (int ch = 0; ch < 3; ++ch)
      s[ch] += w * ad::softplus(raw[std::size_t(scene::grid_index(res, i, j, k, ch))]);
  }
  return s;
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
