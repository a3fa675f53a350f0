// A FlexiCubes grid with its raw unknowns as float arrays, for tests of the
// extraction and of the stage-1 terms that read it.
#pragma once

#include <functional>
#include <random>
#include <vector>

#include "difftrans/geometry/flexicubes.hpp"

namespace dt_test {

struct GridData {
  using FlexiCubesGrid = difftrans::geometry::FlexiCubesGrid;
  using FlexiCubesInputs = difftrans::geometry::FlexiCubesInputs;
  using Vec3f = difftrans::Vec3f;
  FlexiCubesGrid grid;
  std::vector<float> sdf, deform, alpha, beta, gamma;

  explicit GridData(int res, Vec3f lo = Vec3f(-1.0f), Vec3f hi = Vec3f(1.0f)) {
    grid.res = res;
    grid.lo = lo;
    grid.hi = hi;
    sdf.assign(std::size_t(grid.num_vertices()), 1.0f);
  }
  void fill(const std::function<float(Vec3f)>& f) {
    const int V = grid.res + 1;
    for (int k = 0; k < V; ++k)
      for (int j = 0; j < V; ++j)
        for (int i = 0; i < V; ++i) sdf[std::size_t(grid.vertex_index(i, j, k))] = f(grid.vertex_position(i, j, k));
  }
  void randomize_unknowns(std::mt19937& rng, float deform_scale, float weight_scale) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    deform.resize(3 * sdf.size());
    alpha.resize(8 * std::size_t(grid.num_cubes()));
    beta.resize(12 * std::size_t(grid.num_cubes()));
    gamma.resize(std::size_t(grid.num_cubes()));
    for (float& x : deform) x = deform_scale * u(rng);
    for (auto* v : {&alpha, &beta, &gamma})
      for (float& x : *v) x = weight_scale * u(rng);
  }
  // buffer ids 0..4 when differentiable (and not empty), else constants
  FlexiCubesInputs inputs(bool differentiable = false) const {
    auto src = [&](const std::vector<float>& v, int id) {
      return difftrans::ad::ParamSource{v.empty() ? nullptr : v.data(), std::int32_t(v.size()),
                                differentiable && !v.empty() ? id : -1};
    };
    return FlexiCubesInputs{src(sdf, 0), src(deform, 1), src(alpha, 2), src(beta, 3), src(gamma, 4)};
  }
  std::vector<float>* buffer(int b) {
    std::vector<float>* all[5] = {&sdf, &deform, &alpha, &beta, &gamma};
    return all[b];
  }
  const std::vector<float>* buffer(int b) const { return const_cast<GridData*>(this)->buffer(b); }
};

}  // namespace dt_test
