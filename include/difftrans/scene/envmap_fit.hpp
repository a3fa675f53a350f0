// Fits a distant equirectangular environment to background observations
// (a direction and the radiance seen along it): each observation reads the
// map bilinearly (scene/envmap.hpp), so the fit is a sparse linear least-
// squares problem, solved exactly (sparse Cholesky) with a smoothness prior
// that fills the directions no camera saw. Host only; needs Eigen.
#pragma once

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/ad/params.hpp"
#include "difftrans/scene/envmap.hpp"

namespace difftrans::scene {

struct EnvObservation {
  Vec3f direction;  // away from the scene (need not be unit)
  Vec3f radiance;   // linear RGB
  float weight = 1.0f;
  Vec3f origin{0.0f};  // where the ray starts (the camera): near-field fits use it, the distant fit does not
};

struct EnvFitOptions {
  int width = 256, height = 128;  // the map's resolution (height = width / 2 is the usual shape)
  // Weight of the smoothness prior: Σ over neighbouring texels (u wraps) of
  // smoothness · (x_a − x_b)², against Σ over observations of weight ·
  // (lookup − radiance)². Small values interpolate the data; unseen texels
  // get the harmonic (smoothest) fill either way.
  double smoothness = 1e-3;
};

struct EnvFit {
  std::vector<float> texels;  // width · height · 3, the EnvMap layout
  int width = 0, height = 0;
  std::int64_t observations = 0;
  std::vector<std::uint8_t> seen;  // per texel: 1 where observations touch it
  double seen_fraction = 0;   // fraction of the sphere's solid angle covered by texels that data touches
  double rms_residual = 0;    // over the observations, linear radiance
};

// Smallest map whose texels are no larger than the pixels that observe them:
// 2π / (angle one pixel subtends), rounded up to even, clamped to [16, max_width].
inline int envmap_width_for(double pixel_angle_radians, int max_width = 1024) {
  int w = int(std::ceil(2.0 * 3.14159265358979323846 / std::max(pixel_angle_radians, 1e-6)));
  w += w & 1;
  return std::clamp(w, 16, max_width);
}

inline EnvFit fit_environment(const std::vector<EnvObservation>& obs, const EnvFitOptions& opt = {}) {
  const int W = opt.width, H = opt.height;
  if (W < 3 || H < 2) throw std::invalid_argument("fit_environment: the map must be at least 3 x 2 texels");
  if (obs.empty()) throw std::invalid_argument("fit_environment: no background observations");
  const std::int64_t n = std::int64_t(W) * H;
  // Normal equations AᵀA x = Aᵀb: a footprint couples a texel only with its
  // 8 neighbours, so AᵀA is accumulated in 9 slots per texel, not triplets.
  std::vector<double> ata(std::size_t(n) * 9, 0.0), atb(std::size_t(n) * 3, 0.0), data_weight(std::size_t(n), 0.0);
  const auto slot = [&](std::int32_t a, std::int32_t b) {
    const int ra = a / W, ca = a % W, rb = b / W, cb = b % W;
    int dc = cb - ca;
    if (dc > 1) dc -= W;
    if (dc < -1) dc += W;
    return (rb - ra + 1) * 3 + (dc + 1);
  };
  std::int64_t used = 0;
  for (const EnvObservation& o : obs) {
    if (!(o.weight > 0) || !std::isfinite(o.radiance.x + o.radiance.y + o.radiance.z)) continue;
    const Footprint<float> f = bilinear_footprint(W, H, direction_to_uv(o.direction));
    if (!f.valid) continue;
    ++used;
    for (int i = 0; i < 4; ++i) {
      const double wi = double(f.weight[i]) * o.weight;
      if (wi == 0) continue;
      data_weight[std::size_t(f.texel[i])] += wi;
      for (int c = 0; c < 3; ++c) atb[std::size_t(f.texel[i]) * 3 + c] += wi * o.radiance[c];
      for (int j = 0; j < 4; ++j)
        ata[std::size_t(f.texel[i]) * 9 + std::size_t(slot(f.texel[i], f.texel[j]))] += wi * f.weight[j];
    }
  }
  if (used == 0) throw std::invalid_argument("fit_environment: no finite observation with positive weight");
  // The smoothness prior: λ Σ (x_a − x_b)² over right and lower neighbours,
  // plus a tiny ridge so that the system is positive definite in any case.
  const double lambda = opt.smoothness, ridge = 1e-9;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(std::size_t(n) * 9);
  for (std::int32_t t = 0; t < n; ++t) {
    const int r = t / W, c = t % W;
    double* row = &ata[std::size_t(t) * 9];
    row[4] += ridge;
    const std::int32_t right = r * W + (c + 1) % W;
    row[4] += lambda;
    ata[std::size_t(right) * 9 + 4] += lambda;
    row[std::size_t(slot(t, right))] -= lambda;
    ata[std::size_t(right) * 9 + std::size_t(slot(right, t))] -= lambda;
    if (r + 1 < H) {
      const std::int32_t down = (r + 1) * W + c;
      row[4] += lambda;
      ata[std::size_t(down) * 9 + 4] += lambda;
      row[std::size_t(slot(t, down))] -= lambda;
      ata[std::size_t(down) * 9 + std::size_t(slot(down, t))] -= lambda;
    }
  }
  for (std::int32_t t = 0; t < n; ++t) {
    const int r = t / W, c = t % W;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const double v = ata[std::size_t(t) * 9 + std::size_t((dr + 1) * 3 + dc + 1)];
        if (v == 0 || r + dr < 0 || r + dr >= H) continue;
        trip.emplace_back(t, (r + dr) * W + (c + dc + W) % W, v);
      }
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(trip.begin(), trip.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  if (solver.info() != Eigen::Success) throw std::runtime_error("fit_environment: the normal equations are singular");
  EnvFit fit;
  fit.width = W;
  fit.height = H;
  fit.observations = used;
  fit.texels.assign(std::size_t(n) * 3, 0.0f);
  for (int c = 0; c < 3; ++c) {
    Eigen::VectorXd b(n);
    for (std::int64_t t = 0; t < n; ++t) b[t] = atb[std::size_t(t) * 3 + c];
    const Eigen::VectorXd x = solver.solve(b);
    for (std::int64_t t = 0; t < n; ++t) fit.texels[std::size_t(t) * 3 + c] = float(x[t]);
  }
  // coverage: solid angle of the texels the data touches (a texel row at
  // polar angle θ spans sin θ of it)
  double seen = 0, total = 0;
  fit.seen.assign(std::size_t(n), 0);
  for (std::int32_t t = 0; t < n; ++t) {
    const double theta = 3.14159265358979323846 * ((t / W) + 0.5) / H, a = std::sin(theta);
    total += a;
    fit.seen[std::size_t(t)] = data_weight[std::size_t(t)] > 1e-6;
    if (fit.seen[std::size_t(t)]) seen += a;
  }
  fit.seen_fraction = seen / total;
  // residual over the observations
  const EnvMap map = equirect_environment(fit.texels.data(), W, H);
  ad::ParamReader<float> reader(nullptr);
  double sum = 0;
  for (const EnvObservation& o : obs) {
    if (!(o.weight > 0) || !std::isfinite(o.radiance.x + o.radiance.y + o.radiance.z)) continue;
    const Vec3f d = lookup(reader, map, o.direction) - o.radiance;
    sum += glm::dot(d, d) / 3.0;
  }
  fit.rms_residual = std::sqrt(sum / double(used));
  return fit;
}

}  // namespace difftrans::scene
