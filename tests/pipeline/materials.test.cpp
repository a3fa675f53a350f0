// Stage 2 on a glass sphere whose photographs are rendered here (depth 8,
// 4 samples per pixel): from a wrong IoR and a faint absorption, the
// optimization (depth 4, pruning, one jittered ray per pixel) must find the
// true IoR and the absorption; the absorption regularizers' gradients must
// match finite differences.
#include "pipeline/materials.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <unistd.h>
#include <vector>

#include "support/shapes.hpp"
#include "support/stage2_photos.hpp"

namespace dr = difftrans::render;
namespace ds = difftrans::scene;
namespace losses = difftrans::losses;
namespace pipeline = difftrans::pipeline;
namespace dg = difftrans::geometry;
namespace io = difftrans::io;
using difftrans::Vec3f;
using dt_test::mask_views_of;
using dt_test::photograph;
using dt_test::Photos;
using dt_test::views_of;

namespace {

dr::HostScene glass_sphere(float ior, const Vec3f& sigma) {
  const dt_test::Shape ico = dt_test::make_icosphere(0.4f, 3);
  dr::HostScene s(ico.positions, ico.triangles, "sphere");
  s.ior = ior;
  s.set_environment_map(dt_test::smooth_sky(64, 32), 64, 32);
  if (sigma != Vec3f(0.0f)) s.set_homogeneous_absorption(sigma);
  return s;
}

// Stage 2 on a clear object with the vertices moving, 1024 rays a batch.
pipeline::Stage2Config clear_vertex_config() {
  pipeline::Stage2Config cfg;
  cfg.absorption_model = pipeline::AbsorptionModel::none;
  cfg.rays_per_iteration = 1024;
  cfg.optimize_positions = true;
  return cfg;
}

// The sphere with its upper half pushed out (radius up to 12 % larger at the top).
dr::HostScene dented_sphere() {
  dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
  for (std::size_t v = 0; v * 3 < s.mesh.positions.size(); ++v) {
    float* p = &s.mesh.positions[3 * v];
    const float bump = 1.0f + 0.12f * std::max(0.0f, p[1] / 0.4f);
    for (int c = 0; c < 3; ++c) p[c] *= bump;
  }
  s.positions_changed();
  return s;
}

}  // namespace

TEST_CASE("Stage2Config::total_iterations: the materials alone, the vertices' phase and its settling, or as given") {
  pipeline::Stage2Config cfg;
  REQUIRE(cfg.optimize_positions);  // the vertices move by default
  CHECK(cfg.total_iterations() ==
        cfg.freeze_geometry + cfg.geometry_iterations + pipeline::Stage2Config::settle_iterations);
  cfg.optimize_positions = false;
  CHECK(cfg.total_iterations() == pipeline::Stage2Config::materials_iterations);
  cfg.optimize_positions = true;
  cfg.freeze_geometry = 40;
  cfg.geometry_iterations = 70;
  CHECK(cfg.total_iterations() == 40 + 70 + pipeline::Stage2Config::settle_iterations);
  cfg.iterations = 0;
  CHECK(cfg.total_iterations() == 0);
  cfg.iterations = 12;
  CHECK(cfg.total_iterations() == 12);
}

TEST_CASE("absorption regularizers: values and gradients against finite differences") {
  const difftrans::Vec3i res(3, 2, 2);
  std::vector<float> raw(3 * 12);
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = 0.3f * std::sin(1.7f * float(i)) - 0.2f;
  std::vector<float> g(raw.size(), 0.0f);
  losses::absorption_regularizers(raw, res, 0.7f, 0.3f, g);
  const auto f = [&](const std::vector<float>& r) {
    std::vector<float> tmp(r.size(), 0.0f);
    const auto [tv, vol] = losses::absorption_regularizers(r, res, 0.7f, 0.3f, tmp);
    return 0.7 * tv + 0.3 * vol;
  };
  for (std::size_t i = 0; i < raw.size(); ++i) {
    std::vector<float> a = raw, b = raw;
    a[i] += 1e-3f;
    b[i] -= 1e-3f;
    CHECK(g[i] == doctest::Approx((f(a) - f(b)) / 2e-3).epsilon(2e-2).scale(1e-4));
  }
}

TEST_CASE("stage 2 recovers IoR and absorption on a glass sphere (geometry known)") {
  const Vec3f sigma_true(0.5f, 1.5f, 3.0f);
  const dr::HostScene truth = glass_sphere(1.45f, sigma_true);
  const Photos photos = photograph(truth, 10, 40);
  dr::HostScene s = glass_sphere(1.3f, Vec3f(0.0f));
  pipeline::Stage2Config cfg;
  cfg.absorption_model = pipeline::AbsorptionModel::grid;
  cfg.iterations = 600;
  cfg.ior_init = 1.55f;
  cfg.ior_scan = false;  // the fit from this start
  cfg.ior_warmup = 100;  // the IoR's slow warm-up (the paper's 1e-4) while the absorption finds its level
  cfg.freeze_geometry = 100;
  cfg.rays_per_iteration = 2048;
  cfg.optimize_positions = false;
  cfg.absorption_res = 4;
  cfg.box_lo = Vec3f(-0.45f);
  cfg.box_hi = Vec3f(0.45f);
  cfg.lr_ior_frozen = 1e-4f;
  cfg.lr_ior = 3e-3f;
  cfg.lr_absorption_grid = 5e-2f;
  cfg.lr_decay = 1e-3f;  // a short run: settle the noisy single-ray estimates
  bool searched = true;
  SUBCASE("the absorption starts from the grey value that fits best") {
    cfg.sigma_search = pipeline::Stage2Config::sigma_search_grid();
  }
  SUBCASE("the absorption starts from sigma_init") {
    cfg.sigma_search.clear();
    searched = false;
  }
  pipeline::Stage2 st(s, views_of(photos), {}, cfg);
  double first = 0.0, last = 0.0;
  while (!st.done()) {
    const pipeline::Stage2Stats x = st.step();
    if (x.iteration < 10) first += x.color / 10.0;
    if (x.iteration >= cfg.iterations - 10) last += x.color / 10.0;
  }
  // σ at the grid vertices inside the sphere (the 8 around the centre; the
  // others lie outside, where only the regularizers reach them)
  Vec3f sig(0.0f);
  int inside = 0;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        const Vec3f p = cfg.box_lo + (cfg.box_hi - cfg.box_lo) * Vec3f(float(i), float(j), float(k)) / 3.0f;
        if (glm::length(p) > 0.4f) continue;
        ++inside;
        for (int c = 0; c < 3; ++c) sig[c] += difftrans::ad::softplus(s.absorption_raw[std::size_t(((k * 4 + j) * 4 + i) * 3 + c)]);
      }
  REQUIRE(inside == 8);
  sig /= float(inside);
  const Vec3f start = st.searched_sigma();
  MESSAGE("IoR " << s.ior << " (averaged " << st.averaged_ior() << ", true 1.45, start 1.55), sigma inside " << sig.x
                 << ", " << sig.y << ", " << sig.z << " (true 0.5, 1.5, 3.0; start " << start.x << ", " << start.y
                 << ", " << start.z << "); colour loss " << first << " -> " << last);
  if (searched) {
    // the search matches the rendered light to the photographs' (measured:
    // 0.49, 1.51, 3.19); 35 % off is a wrong rule, not noise
    for (int c = 0; c < 3; ++c) CHECK(std::abs(start[c] - sigma_true[c]) <= 0.35f * sigma_true[c]);
    CHECK(last < 1e-3);
  } else {
    CHECK(std::isnan(start.x));
    CHECK(last < 0.1 * first);
  }
  // measured: IoR 1.4496 from sigma_init, 1.4522 after the search; before
  // each ray's IoR derivative was clipped, 1.43 and σ about 10 % low
  CHECK(std::abs(s.ior - 1.45f) < 0.01f);
  CHECK(std::abs(st.averaged_ior() - 1.45f) < 0.01f);
  CHECK(sig.x < sig.y);
  CHECK(sig.y < sig.z);
  for (int c = 0; c < 3; ++c) CHECK(std::abs(sig[c] - sigma_true[c]) < 0.2f * sigma_true[c]);
}

TEST_CASE("a grid steps at lr_absorption_grid, a homogeneous absorption at lr_absorption") {
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.5f, 1.0f, 1.5f));
  const Photos photos = photograph(truth, 4, 24);
  const auto raw_after = [&](pipeline::AbsorptionModel model, float homogeneous_rate, float grid_rate) {
    dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
    pipeline::Stage2Config cfg;
    cfg.absorption_model = model;
    cfg.absorption_res = 3;
    cfg.optimize_positions = false;
    cfg.optimize_ior = false;
    cfg.ior_settle_batches = 0;
    cfg.sigma_search.clear();  // from sigma_init: the start is the same whatever the rates
    cfg.iterations = 4;
    cfg.rays_per_iteration = 256;
    cfg.lr_absorption = homogeneous_rate;
    cfg.lr_absorption_grid = grid_rate;
    pipeline::Stage2 st(s, views_of(photos), {}, cfg);
    const std::vector<float> start = s.absorption_raw;
    while (!st.done()) st.step();
    double moved = 0.0;
    REQUIRE(s.absorption_raw.size() == start.size());
    for (std::size_t k = 0; k < start.size(); ++k) moved += std::abs(double(s.absorption_raw[k]) - double(start[k]));
    return moved;
  };
  using M = pipeline::AbsorptionModel;
  CHECK(raw_after(M::grid, 0.0f, 2e-2f) > 0.0);
  CHECK(raw_after(M::grid, 2e-2f, 0.0f) == 0.0);  // a grid ignores the homogeneous rate
  CHECK(raw_after(M::homogeneous, 2e-2f, 0.0f) > 0.0);
  CHECK(raw_after(M::homogeneous, 0.0f, 2e-2f) == 0.0);  // and the homogeneous σ the grid's
}

TEST_CASE("stage 2 settles the IoR at the zero of the IoR gradient's line over fixed batches") {
  // The absorption is the true one; the IoR starts 0.04 off with no
  // iteration run (averaged_ior() is then the current IoR). The zero lies
  // outside the first five IoRs (0.01 apart), so the regression recentres,
  // and must end near the true IoR with a positive slope. Measured: 1.4581
  // and 1.4590 +- 0.003 from the two starts; with 128 batches 1.4648 and
  // 1.4625 +- 0.002, also with the tone term off, the IoR clip off or the
  // training depth at the photographs' 8: the zero of these 8 small
  // photographs' own loss lies about 0.012 above the true IoR (the fit of
  // the test above, with the absorption free, ends 0.002 from it).
  const Vec3f sigma_true(0.3f, 0.6f, 0.9f);
  const dr::HostScene truth = glass_sphere(1.45f, sigma_true);
  const Photos photos = photograph(truth, 8, 32);
  for (const float start : {1.41f, 1.49f}) {
    dr::HostScene s = glass_sphere(start, sigma_true);
    pipeline::Stage2Config cfg;
    cfg.optimize_positions = false;  // the materials alone
    cfg.iterations = 0;
    cfg.ior_init = start;
    cfg.ior_scan = false;  // the fit from this start
    cfg.rays_per_iteration = 2048;
    cfg.ior_settle_batches = 32;
    cfg.sigma_search.clear();
    pipeline::Stage2 st(s, views_of(photos), {}, cfg);
    s.set_homogeneous_absorption(sigma_true);  // the material known but the IoR
    const pipeline::Stage2::IorSettle r = st.settle_ior();
    MESSAGE("start " << start << " -> " << r.ior << " +- " << r.standard_error << " (true 1.45), slope " << r.slope
                     << " +- " << r.slope_standard_error << ", " << r.evaluations.size() << " IoRs evaluated");
    CHECK(r.start == doctest::Approx(start));
    REQUIRE(r.settled);
    CHECK(r.evaluations.size() >= 10);  // recentred at least once
    CHECK(r.evaluations.size() % 5 == 0);
    CHECK(r.slope > 2.0 * r.slope_standard_error);
    CHECK(r.standard_error < 0.005);
    CHECK(std::abs(r.ior - 1.45f) < 0.015f);
    CHECK(s.ior == r.ior);
    // the same batches from the same start: the same answer, bit for bit
    pipeline::Stage2 again(s, views_of(photos), {}, cfg);
    s.set_homogeneous_absorption(sigma_true);
    CHECK(again.settle_ior().ior == r.ior);
  }
}

TEST_CASE("Stage2Config::ior_settle_clip: the settle clips each ray's IoR derivative by its own bound, not the fit's") {
  // One round of five IoRs over 4 fixed batches; a clip of 0.01 clips
  // more rays than 10 does, so the two give other gradients.
  const Vec3f sigma_true(0.3f, 0.6f, 0.9f);
  const dr::HostScene truth = glass_sphere(1.45f, sigma_true);
  const Photos photos = photograph(truth, 8, 32);
  const auto settle = [&](float fit_clip, float settle_clip) {
    dr::HostScene s = glass_sphere(1.47f, sigma_true);
    pipeline::Stage2Config cfg;
    cfg.optimize_positions = false;
    cfg.iterations = 0;
    cfg.ior_init = 1.47f;
    cfg.ior_scan = false;
    cfg.rays_per_iteration = 1024;
    cfg.ior_settle_batches = 4;
    cfg.ior_settle_rounds = 1;
    cfg.clip_ior = fit_clip;
    cfg.ior_settle_clip = settle_clip;
    cfg.sigma_search.clear();
    pipeline::Stage2 st(s, views_of(photos), {}, cfg);
    s.set_homogeneous_absorption(sigma_true);
    return st.settle_ior();
  };
  const pipeline::Stage2::IorSettle wide = settle(0.01f, 10.0f), tight = settle(10.0f, 0.01f);
  REQUIRE(wide.evaluations.size() == 5);
  REQUIRE(tight.evaluations.size() == 5);
  // the fit's clip plays no part: the same settle under either
  const pipeline::Stage2::IorSettle wide_again = settle(10.0f, 10.0f), tight_again = settle(0.01f, 0.01f);
  for (std::size_t q = 0; q < 5; ++q) {
    CHECK(wide.evaluations[q].mean_gradient == wide_again.evaluations[q].mean_gradient);
    CHECK(tight.evaluations[q].mean_gradient == tight_again.evaluations[q].mean_gradient);
    MESSAGE("IoR " << wide.evaluations[q].ior << ": clip 10 " << wide.evaluations[q].mean_gradient << ", clip 0.01 "
                   << tight.evaluations[q].mean_gradient);
    // and the settle's own does (measured: 0.0008 against 0.0006 at 1.46, -0.0003 against +0.0011 at 1.47)
    CHECK(tight.evaluations[q].mean_gradient != wide.evaluations[q].mean_gradient);
  }
}

TEST_CASE("settle_before_vertices: the IoR settles once, before the first vertex step, and holds while they move") {
  // A clear sphere whose IoR starts 0.04 high and barely moves in the
  // freeze (its slow rate); the settle at the first vertex step starts from
  // the mean IoR of the last ior_settle_window iterations.
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.0f));
  const Photos photos = photograph(truth, 8, 32);
  pipeline::Stage2Config cfg = clear_vertex_config();
  cfg.rays_per_iteration = 2048;
  cfg.ior_init = 1.49f;
  cfg.ior_scan = false;  // the fit from this start
  cfg.freeze_geometry = 6;
  cfg.ior_warmup = 6;
  cfg.iterations = 9;
  cfg.ior_settle_batches = 64;
  cfg.ior_settle_window = 4;
  cfg.settle_before_vertices = true;
  cfg.ior_with_vertices = pipeline::IorWithVertices::off;  // held after the settle, to be seen
  dr::HostScene s = glass_sphere(1.49f, Vec3f(0.0f));
  pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), cfg);
  std::vector<pipeline::Stage2Stats> runs;
  while (st.iteration() < cfg.freeze_geometry) {
    runs.push_back(st.step());
    CHECK_FALSE(st.vertex_start_settle().has_value());
  }
  float recent = 0.0f;
  for (std::size_t i = runs.size() - 4; i < runs.size(); ++i) recent += runs[i].ior / 4.0f;
  const pipeline::Stage2Stats first = st.step();
  REQUIRE(first.geometry_moving);
  REQUIRE(st.vertex_start_settle().has_value());
  const pipeline::Stage2::IorSettle r = *st.vertex_start_settle();
  MESSAGE("before the vertices: " << r.start << " -> " << r.ior << " +- " << r.standard_error << " (true 1.45), "
                                  << r.evaluations.size() << " IoRs evaluated");
  CHECK(r.start == doctest::Approx(recent).epsilon(1e-6));
  CHECK(std::abs(r.start - 1.49f) < 0.005f);
  REQUIRE(r.settled);
  CHECK(std::abs(r.ior - 1.45f) < 0.015f);
  CHECK(first.ior == r.ior);  // the vertex steps see the settled IoR, held
  while (!st.done()) CHECK(st.step().ior == r.ior);
  CHECK(st.vertex_start_settle()->evaluations.size() == r.evaluations.size());  // once

  cfg.settle_before_vertices = false;  // off: no settle, the IoR the freeze left
  dr::HostScene u = glass_sphere(1.49f, Vec3f(0.0f));
  pipeline::Stage2 off(u, views_of(photos), mask_views_of(photos), cfg);
  while (!off.done()) off.step();
  CHECK_FALSE(off.vertex_start_settle().has_value());
  CHECK(std::abs(u.ior - 1.49f) < 0.005f);
}

TEST_CASE("materials_pass_rays: while the vertices move, the IoR and absorption take a pass of their own") {
  // An absorbing sphere on its true surface, the IoR 0.05 high: with the
  // vertices moving from the first iteration (under a blurred sky), the IoR
  // and the absorption move on the gradient of a second batch, scored under
  // the sharp sky; the vertices' pass differentiates the vertices alone.
  // Measured: the IoR 1.5 -> 1.471 in 150 iterations (from the vertices'
  // own pass, materials_pass_rays 0: 1.506).
  const Vec3f sigma(0.6f, 0.3f, 0.9f);
  const dr::HostScene truth = glass_sphere(1.45f, sigma);
  const Photos photos = photograph(truth, 8, 32);
  pipeline::Stage2Config cfg;
  cfg.absorption_model = pipeline::AbsorptionModel::homogeneous;
  cfg.sigma_init = 0.45f;
  cfg.sigma_search.clear();
  cfg.rays_per_iteration = 1024;
  cfg.optimize_positions = true;
  cfg.freeze_geometry = 0;
  cfg.ior_warmup = 0;
  cfg.ior_init = 1.5f;
  cfg.ior_scan = false;  // the fit from this start
  cfg.lr_ior = 2e-3f;
  cfg.iterations = 150;
  cfg.ior_with_vertices = pipeline::IorWithVertices::on;
  cfg.absorption_with_vertices = true;
  cfg.materials_pass_rays = 2048;
  const std::vector<float> sky = dt_test::smooth_sky(64, 32);
  dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
  s.ior = 1.5f;
  const std::vector<float> start = s.mesh.positions;
  pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), cfg);
  Vec3f last_sigma(0.0f);
  for (int i = 0; i < cfg.iterations; ++i) {
    const pipeline::Stage2Stats r = st.step();
    REQUIRE(r.geometry_moving);
    REQUIRE(r.environment_blur > 0.0f);
    last_sigma = r.mean_sigma;
    CHECK(r.materials_pass_color > 0.0);
    CHECK(r.rays == 1024 + 2048);
    // the sky the vertices see is the blurred one again after the pass
    CHECK(s.environment == ds::blur_equirect(sky, 64, 32, r.environment_blur));
  }
  MESSAGE("IoR 1.5 -> " << s.ior << " (true 1.45); sigma (0.45) -> " << last_sigma.x << ", " << last_sigma.y << ", "
                        << last_sigma.z << " (true " << sigma.x << ", " << sigma.y << ", " << sigma.z << ")");
  CHECK(s.ior < 1.485f);
  CHECK(s.ior > 1.42f);
  // every channel nearer its truth than the start
  for (int c = 0; c < 3; ++c) CHECK(std::abs(last_sigma[c] - sigma[c]) < std::abs(cfg.sigma_init - sigma[c]));
  CHECK(s.mesh.positions != start);  // the vertices moved too

  // without the pass, no second batch
  cfg.materials_pass_rays = 0;
  cfg.iterations = 2;
  dr::HostScene u = glass_sphere(1.45f, Vec3f(0.0f));
  pipeline::Stage2 off(u, views_of(photos), mask_views_of(photos), cfg);
  const pipeline::Stage2Stats r = off.step();
  CHECK(r.materials_pass_color == 0.0);
  CHECK(r.rays == 1024);
}

TEST_CASE("stage 2 fits the sky no background pixel saw") {
  // The photographs are taken under the true sky; stage 2 is given a map
  // whose top rows (polar angle below 60 degrees), marked unseen, are twice
  // too bright, as the environment fit's fill was on horse-green. The IoR is
  // known; the absorption starts from its search. With the factor fitted it
  // must come back to about 1/2 and the absorption nearer the truth than
  // without it (measured: see the MESSAGE).
  const Vec3f sigma_true(0.5f, 1.0f, 1.5f);
  const dr::HostScene truth = glass_sphere(1.45f, sigma_true);
  const Photos photos = photograph(truth, 10, 32);
  const int W = 64, H = 32, unseen_rows = H / 3;
  std::vector<std::uint8_t> seen(std::size_t(W * H), 1);
  for (int t = 0; t < W * unseen_rows; ++t) seen[std::size_t(t)] = 0;
  const auto fit = [&](bool sky, Vec3f& scale) {
    dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
    for (int t = 0; t < W * unseen_rows; ++t)
      for (int c = 0; c < 3; ++c) s.environment[std::size_t(3 * t + c)] *= 2.0f;
    pipeline::Stage2Config cfg;
    cfg.optimize_positions = false;  // the materials alone
    cfg.absorption_model = pipeline::AbsorptionModel::grid;
    cfg.iterations = 300;
    cfg.ior_init = 1.45f;
    cfg.optimize_ior = false;
    cfg.ior_settle_batches = 0;
    cfg.rays_per_iteration = 1024;
    cfg.absorption_res = 4;
    cfg.box_lo = Vec3f(-0.45f);
    cfg.box_hi = Vec3f(0.45f);
    cfg.lr_absorption_grid = 2e-2f;
    cfg.lr_sky = 2e-2f;
    cfg.unseen_sky = sky ? pipeline::UnseenSky::on : pipeline::UnseenSky::off;
    pipeline::Stage2 st(s, views_of(photos), {}, cfg);
    st.set_seen_texels(seen);
    CHECK(st.sky_fitted() == sky);
    CHECK(st.unseen_solid_angle_fraction() == doctest::Approx(0.25).epsilon(0.05));  // 1 - cos 60 deg, over 2
    st.step();
    const Vec3f s0 = st.searched_sigma(), k0 = st.searched_sky();
    MESSAGE(std::string(sky ? "with" : "without") << " the factor: search start sigma " << s0.x << ", " << s0.y << ", " << s0.z
                                       << ", sky " << k0.x << ", " << k0.y << ", " << k0.z);
    while (!st.done()) st.step();
    scale = st.unseen_sky_scale();
    // σ at the 8 grid vertices inside the sphere
    Vec3f sig(0.0f);
    for (int k = 1; k < 3; ++k)
      for (int j = 1; j < 3; ++j)
        for (int i = 1; i < 3; ++i)
          for (int c = 0; c < 3; ++c)
            sig[c] += difftrans::ad::softplus(s.absorption_raw[std::size_t(((k * 4 + j) * 4 + i) * 3 + c)]) / 8.0f;
    return sig;
  };
  Vec3f with_scale, without_scale;
  const Vec3f with = fit(true, with_scale), without = fit(false, without_scale);
  MESSAGE("sky factor " << with_scale.x << ", " << with_scale.y << ", " << with_scale.z << " (ideal 0.5); sigma "
                        << with.x << ", " << with.y << ", " << with.z << " fitted with it, " << without.x << ", "
                        << without.y << ", " << without.z << " without (true 0.5, 1.0, 1.5)");
  CHECK(without_scale == Vec3f(1.0f));
  for (int c = 0; c < 3; ++c) {
    CHECK(std::abs(with_scale[c] - 0.5f) < 0.15f);
    CHECK(std::abs(with[c] - sigma_true[c]) < std::abs(without[c] - sigma_true[c]));
  }
}

TEST_CASE("unseen_sky homogeneous: the sky's factor is fitted when the absorption fitted is one sigma") {
  // The map's top third marked unseen (as above). Given a model, the factor
  // follows it; chosen, the choice sees the map as it is and the factor
  // starts after it, from the split search, when the choice is homogeneous.
  const int W = 64, H = 32, unseen_rows = H / 3;
  std::vector<std::uint8_t> seen(std::size_t(W * H), 1);
  for (int t = 0; t < W * unseen_rows; ++t) seen[std::size_t(t)] = 0;
  pipeline::Stage2Config cfg;
  cfg.optimize_positions = false;  // the materials alone
  cfg.unseen_sky = pipeline::UnseenSky::homogeneous;
  cfg.rays_per_iteration = 1024;
  cfg.selection_iterations = 40;
  cfg.absorption_res = 4;
  cfg.box_lo = Vec3f(-0.45f);
  cfg.box_hi = Vec3f(0.45f);
  const auto model = [&](pipeline::AbsorptionModel m) {
    pipeline::Stage2Config c = cfg;
    c.absorption_model = m;
    return c;
  };
  const Photos absorbing = photograph(glass_sphere(1.45f, Vec3f(0.5f, 1.0f, 1.5f)), 10, 32);
  const Photos clear = photograph(glass_sphere(1.45f, Vec3f(0.0f)), 10, 32);
  dr::HostScene a = glass_sphere(1.45f, Vec3f(0.0f)), b = glass_sphere(1.45f, Vec3f(0.0f)),
                c = glass_sphere(1.45f, Vec3f(0.0f)), d = glass_sphere(1.45f, Vec3f(0.0f));
  pipeline::Stage2 grid(a, views_of(absorbing), {}, model(pipeline::AbsorptionModel::grid));
  pipeline::Stage2 homogeneous(b, views_of(absorbing), {}, model(pipeline::AbsorptionModel::homogeneous));
  pipeline::Stage2 chosen(c, views_of(absorbing), {}, model(pipeline::AbsorptionModel::automatic));
  pipeline::Stage2 none(d, views_of(clear), {}, model(pipeline::AbsorptionModel::automatic));
  for (pipeline::Stage2* st : {&grid, &homogeneous, &chosen, &none}) st->set_seen_texels(seen);
  CHECK_FALSE(grid.sky_fitted());
  CHECK(homogeneous.sky_fitted());
  CHECK_FALSE(chosen.sky_fitted());  // not before the choice
  chosen.step();
  MESSAGE("absorbing sphere: " << chosen.absorption_choice()["summary"].get<std::string>() << "; sky start "
                               << chosen.searched_sky().x << ", " << chosen.searched_sky().y << ", "
                               << chosen.searched_sky().z);
  REQUIRE(chosen.absorption_choice()["chosen"] == "homogeneous");
  CHECK(chosen.sky_fitted());
  CHECK(std::isfinite(chosen.searched_sky().x));  // the split search ran after the choice
  none.step();
  REQUIRE(none.absorption_choice()["chosen"] == "none");
  CHECK_FALSE(none.sky_fitted());
  CHECK(none.unseen_sky_scale() == Vec3f(1.0f));
}

TEST_CASE("unseen_sky absorbing: the sky's factor is fitted with any absorption, a grid too, and never without one") {
  const int W = 64, H = 32, unseen_rows = H / 3;
  std::vector<std::uint8_t> seen(std::size_t(W * H), 1);
  for (int t = 0; t < W * unseen_rows; ++t) seen[std::size_t(t)] = 0;
  pipeline::Stage2Config cfg;
  cfg.optimize_positions = false;
  cfg.unseen_sky = pipeline::UnseenSky::absorbing;
  cfg.rays_per_iteration = 512;
  cfg.absorption_res = 4;
  cfg.box_lo = Vec3f(-0.45f);
  cfg.box_hi = Vec3f(0.45f);
  const auto model = [&](pipeline::AbsorptionModel m) {
    pipeline::Stage2Config c = cfg;
    c.absorption_model = m;
    return c;
  };
  const Photos photos = photograph(glass_sphere(1.45f, Vec3f(0.5f, 1.0f, 1.5f)), 6, 24);
  dr::HostScene a = glass_sphere(1.45f, Vec3f(0.0f)), b = glass_sphere(1.45f, Vec3f(0.0f)),
                c = glass_sphere(1.45f, Vec3f(0.0f)), d = glass_sphere(1.45f, Vec3f(0.0f));
  pipeline::Stage2 grid(a, views_of(photos), {}, model(pipeline::AbsorptionModel::grid));
  pipeline::Stage2 homogeneous(b, views_of(photos), {}, model(pipeline::AbsorptionModel::homogeneous));
  pipeline::Stage2 none(c, views_of(photos), {}, model(pipeline::AbsorptionModel::none));
  pipeline::Stage2 chosen(d, views_of(photos), {}, model(pipeline::AbsorptionModel::automatic));
  for (pipeline::Stage2* st : {&grid, &homogeneous, &none, &chosen}) st->set_seen_texels(seen);
  CHECK(grid.sky_fitted());
  CHECK(homogeneous.sky_fitted());
  CHECK_FALSE(none.sky_fitted());
  CHECK_FALSE(chosen.sky_fitted());  // not before the choice
  grid.step();
  CHECK(std::isnan(grid.searched_sky().x));  // a grid: no split search, the factor starts at 1
  homogeneous.step();
  CHECK(std::isfinite(homogeneous.searched_sky().x));  // one σ: the split search starts the factor
  for (int i = 0; i < 3; ++i) grid.step();
  CHECK(grid.unseen_sky_scale() != Vec3f(1.0f));  // and the factor moves with the materials
  // the same grid under unseen_sky homogeneous keeps the map as it is
  pipeline::Stage2Config h = model(pipeline::AbsorptionModel::grid);
  h.unseen_sky = pipeline::UnseenSky::homogeneous;
  dr::HostScene e = glass_sphere(1.45f, Vec3f(0.0f));
  pipeline::Stage2 grid_h(e, views_of(photos), {}, h);
  grid_h.set_seen_texels(seen);
  for (int i = 0; i < 4; ++i) grid_h.step();
  CHECK_FALSE(grid_h.sky_fitted());
  CHECK(grid_h.unseen_sky_scale() == Vec3f(1.0f));
}

TEST_CASE("Stage2::fixed_loss: the same rays at every call, lower on the true surface, the scene left as it was") {
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.0f));
  const Photos photos = photograph(truth, 8, 32);
  pipeline::Stage2Config cfg = clear_vertex_config();
  cfg.freeze_geometry = 0;
  cfg.geometry_blur = 8.0f;  // the vertex phase blurs the map: the loss must not
  dr::HostScene right = glass_sphere(1.45f, Vec3f(0.0f)), dented = dented_sphere();
  pipeline::Stage2 on_right(right, views_of(photos), mask_views_of(photos), cfg);
  pipeline::Stage2 on_dented(dented, views_of(photos), mask_views_of(photos), cfg);
  on_dented.step();  // a vertex step: the map is blurred now
  const std::vector<float> blurred = dented.environment;
  bool flags[sizeof(dented.differentiate) / sizeof(dented.differentiate[0])];
  std::copy(std::begin(dented.differentiate), std::end(dented.differentiate), flags);
  const pipeline::Stage2::FixedLoss a = on_dented.fixed_loss(6), b = on_dented.fixed_loss(6);
  const pipeline::Stage2::FixedLoss r = on_right.fixed_loss(6);
  MESSAGE("fixed loss: dented " << a.mean << " +- " << a.standard_error << ", true " << r.mean << " +- "
                                << r.standard_error);
  CHECK(a.mean == b.mean);
  CHECK(a.standard_error == b.standard_error);
  CHECK(a.standard_error > 0.0);
  CHECK(a.mean > r.mean + 3.0 * (a.standard_error + r.standard_error));
  CHECK(dented.environment == blurred);
  CHECK(std::equal(std::begin(flags), std::end(flags), std::begin(dented.differentiate)));
}

TEST_CASE("pixel_order epochs: every view and every pixel once per pass, the same pixels whatever the generator") {
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.0f));
  Photos photos = photograph(truth, 5, 24);
  // each photograph's pixel says which view and pixel it is
  for (std::size_t v = 0; v < photos.images.size(); ++v)
    for (std::size_t i = 0; i * 3 < photos.images[v].size(); ++i) {
      photos.images[v][3 * i] = float(v);
      photos.images[v][3 * i + 1] = float(i);
      photos.images[v][3 * i + 2] = 1.0f;
    }
  std::vector<std::size_t> object(photos.masks.size());
  for (std::size_t v = 0; v < photos.masks.size(); ++v)
    object[v] = std::size_t(std::count(photos.masks[v].begin(), photos.masks[v].end(), std::uint8_t(1)));
  pipeline::Stage2Config cfg = clear_vertex_config();
  cfg.views_per_iteration = 2;  // 5 views: a pass over them every 2.5 batches
  cfg.pixel_samples = 2;
  cfg.rays_per_iteration = 2 * 2 * 7;  // 7 pixels per view and batch
  dr::HostScene scene = glass_sphere(1.45f, Vec3f(0.0f));
  const auto counts = [&](pipeline::PixelOrder order, int batches) {
    cfg.pixel_order = order;
    pipeline::Stage2 stage(scene, views_of(photos), mask_views_of(photos), cfg);
    std::vector<std::vector<int>> seen(photos.images.size());
    for (std::size_t v = 0; v < seen.size(); ++v) seen[v].assign(photos.masks[v].size(), 0);
    std::vector<int> views(photos.images.size(), 0);
    for (int b = 0; b < batches; ++b) {
      std::mt19937_64 rng = stage.batch_generator(b);
      std::vector<dr::BatchRay> rays;
      std::vector<Vec3f> target;
      stage.draw_batch(rng, rays, target, false, 0, b);
      REQUIRE(rays.size() == 2 * target.size());
      for (std::size_t p = 0; p < target.size(); p += 7) ++views[std::size_t(target[p].x)];
      for (const Vec3f& t : target) {
        REQUIRE(photos.masks[std::size_t(t.x)][std::size_t(t.y)] == 1);
        ++seen[std::size_t(t.x)][std::size_t(t.y)];
      }
    }
    // the largest difference between two views' counts, and between two object pixels' of one view
    int view_spread = *std::max_element(views.begin(), views.end()) - *std::min_element(views.begin(), views.end());
    int pixel_spread = 0;
    for (std::size_t v = 0; v < seen.size(); ++v) {
      int lo = 1 << 30, hi = 0;
      for (std::size_t i = 0; i < seen[v].size(); ++i)
        if (photos.masks[v][i]) lo = std::min(lo, seen[v][i]), hi = std::max(hi, seen[v][i]);
      pixel_spread = std::max(pixel_spread, hi - lo);
    }
    return std::pair<int, int>(view_spread, pixel_spread);
  };
  const std::size_t fewest = *std::min_element(object.begin(), object.end());
  REQUIRE(fewest > 14);
  for (const int batches : {1, 3, 7, 40, 101}) {
    const auto [views, pixels] = counts(pipeline::PixelOrder::epochs, batches);
    CHECK(views <= 1);
    CHECK(pixels <= 1);
  }
  // drawn at random, the counts spread
  const auto [random_views, random_pixels] = counts(pipeline::PixelOrder::random, 101);
  MESSAGE("random order after 101 batches: views differ by " << random_views << ", pixels by " << random_pixels);
  CHECK(random_views > 1);
  CHECK(random_pixels > 1);
  // the pixels are the batch number's, whatever generator the jitter comes from
  cfg.pixel_order = pipeline::PixelOrder::epochs;
  pipeline::Stage2 stage(scene, views_of(photos), mask_views_of(photos), cfg);
  std::mt19937_64 g1(1), g2(2);
  std::vector<dr::BatchRay> r1, r2;
  std::vector<Vec3f> t1, t2;
  stage.draw_batch(g1, r1, t1, false, 0, 12);
  stage.draw_batch(g2, r2, t2, false, 0, 12);
  CHECK(t1 == t2);
  CHECK(r1[0].direction != r2[0].direction);  // the jitter is the generator's
}

TEST_CASE("keep_best_level: vertices that make the loss worse go back to the best level and stop") {
  // The true sphere with a vertex rate far too high: the steps throw the
  // surface about, the loss on the fixed batches rises, and the vertices
  // return to where they started; without keep_best_level they stay wrong.
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.0f));
  const Photos photos = photograph(truth, 8, 32);
  pipeline::Stage2Config cfg = clear_vertex_config();
  cfg.optimize_ior = false;
  cfg.freeze_geometry = 2;
  cfg.geometry_iterations = 12;
  cfg.blur_halving = 6;
  cfg.iterations = 16;
  cfg.lr_positions = 0.2f;
  cfg.level_loss_batches = 4;
  for (const bool keep : {true, false}) {  // (off by default)
    CAPTURE(keep);
    pipeline::Stage2Config c = cfg;
    c.keep_best_level = keep;
    dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
    const std::vector<float> start = s.mesh.positions;
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    while (!st.done()) st.step();
    const io::Json& levels = st.vertex_levels();
    MESSAGE(levels.dump());
    REQUIRE(levels.size() >= 2);
    CHECK(levels[0]["iteration"] == 2);
    CHECK(levels[0]["decision"] == "start");
    CHECK(levels[1]["loss"].get<double>() > levels[0]["loss"].get<double>());
    if (keep) {
      CHECK(st.vertices_stopped_at() == 8);  // the first level's end
      CHECK(levels.size() == 2);
      CHECK(levels[1]["decision"].get<std::string>().rfind("back to iteration 2", 0) == 0);
      CHECK(s.mesh.positions == start);
    } else {
      CHECK(st.vertices_stopped_at() == -1);
      CHECK(levels.size() == 3);  // the start, the first level's end, the phase's end
      CHECK(s.mesh.positions != start);
    }
  }
}

TEST_CASE("stage 2 with geometry: a dented sphere moves towards the truth") {
  // Colour (+ tone) through the tracer and the silhouette term every 5
  // iterations, vertices through large steps after a frozen start, each ray's
  // vertex gradient clipped (clip_geometry). Measured: clipped 0.0120 ->
  // 0.0023; not clipped 0.0120 -> 0.0133 (worse: a few rays carry huge
  // vertex derivatives); silhouette term alone 0.0034. Since the vertices
  // step on neighbouring pixels' log residuals (geometry_neighbours):
  // clipped 0.0018 (each pixel's L2 residual 0.0020).
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.0f));
  const Photos photos = photograph(truth, 12, 40);
  const auto dented = dented_sphere;
  const auto radius_error = [](const dr::HostScene& s) {
    double e = 0.0;
    const std::size_t n = s.mesh.positions.size() / 3;
    for (std::size_t v = 0; v < n; ++v) {
      const float* p = &s.mesh.positions[3 * v];
      e += std::abs(std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]) - 0.4);
    }
    return e / double(n);
  };
  pipeline::Stage2Config cfg;
  cfg.absorption_model = pipeline::AbsorptionModel::grid;
  cfg.iterations = 120;
  cfg.freeze_geometry = 20;
  cfg.rays_per_iteration = 1024;
  cfg.optimize_positions = true;
  cfg.lr_ior = 1e-3f;
  cfg.optimize_ior = false;
  cfg.optimize_absorption = false;
  cfg.lr_positions = 3e-3f;
  const double before = radius_error(dented());

  SUBCASE("default losses with clipping") {
    dr::HostScene s = dented();
    const std::vector<float> start = s.mesh.positions;
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), cfg);
    std::int64_t clipped = 0, rays = 0;
    for (int i = 0; i < cfg.freeze_geometry; ++i) st.step();
    CHECK(s.mesh.positions == start);  // frozen
    while (!st.done()) {
      const pipeline::Stage2Stats x = st.step();
      clipped += x.clipped_rays;
      rays += x.rays;
    }
    const double after = radius_error(s);
    MESSAGE("clipped: mean |r - 0.4| " << before << " -> " << after << ", " << clipped << " of " << rays
                                       << " rays clipped");
    CHECK(clipped > 0);
    CHECK(after < 0.3 * before);
    CHECK(dg::mesh_genus(s.mesh.triangles, s.mesh.num_vertices()).closed);
  }
  SUBCASE("vertex_rays: the batch while the vertices move has its own ray count") {
    dr::HostScene s = dented();
    pipeline::Stage2Config c = cfg;
    c.iterations = 24;
    c.vertex_rays = 512;
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    while (!st.done()) {
      const pipeline::Stage2Stats x = st.step();
      CAPTURE(x.iteration);
      // every drawn pixel's ray (one sample per pixel here), give or take a view's rounding
      const std::int64_t expected = x.geometry_moving ? 512 : 1024;
      CHECK(x.rays <= expected);
      CHECK(x.rays > expected * 9 / 10);
    }
  }
  SUBCASE("vertex_average: the vertices end at the mean of their last steps' positions") {
    // the same fit twice (one worker: bit for bit the same steps): without
    // the average, summing the positions after each of the last 30 steps
    // (iterations 90 .. 119); with it, whose result must be their mean
    dr::HostScene plain = dented(), averaged = dented();
    std::vector<double> sum(plain.mesh.positions.size(), 0.0);
    pipeline::Stage2 a(plain, views_of(photos), mask_views_of(photos), cfg);
    while (!a.done()) {
      const pipeline::Stage2Stats x = a.step();
      if (x.iteration >= cfg.iterations - 30)
        for (std::size_t k = 0; k < sum.size(); ++k) sum[k] += plain.mesh.positions[k];
    }
    pipeline::Stage2Config c = cfg;
    c.vertex_average = 30;
    pipeline::Stage2 b(averaged, views_of(photos), mask_views_of(photos), c);
    while (!b.done()) b.step();
    double off = 0.0, from_last = 0.0;
    for (std::size_t k = 0; k < sum.size(); ++k) {
      off = std::max(off, std::abs(double(averaged.mesh.positions[k]) - sum[k] / 30.0));
      from_last = std::max(from_last, std::abs(double(averaged.mesh.positions[k]) - double(plain.mesh.positions[k])));
    }
    MESSAGE("mean |r - 0.4| " << before << " -> " << radius_error(plain) << " (last step), " << radius_error(averaged)
                              << " (mean of the last 30)");
    CHECK(off < 1e-6);
    CHECK(from_last > 1e-5);  // the steps did differ: the mean is not the last step
    CHECK(radius_error(averaged) < 0.3 * before);
  }
  SUBCASE("large steps' lambda from coarse to fine (19 -> 4.4 -> 1 over the 100 moving iterations)") {
    dr::HostScene s = dented();
    pipeline::Stage2Config c = cfg;
    c.geometry_iterations = 100;
    c.blur_halving = 34;
    c.lambda_final = 1.0;
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    while (!st.done()) st.step();
    const double after = radius_error(s);
    // Measured: 0.0120 -> 0.0051 (λ 19 throughout: 0.0022); with the vertex
    // gradient stopped at 4 interactions 0.0043 (0.0020). The dent is a
    // coarse error, which a small λ moves slowly (its steps are normalized
    // by the noisiest vertex); stage 1's errors are fine detail, where the
    // schedule wins (docs/stage2-diagnostics.md, "coarse to fine"). With
    // neighbouring pixels' log residuals 0.0025.
    MESSAGE("lambda 19 -> 1: mean |r - 0.4| " << before << " -> " << after);
    CHECK(st.history()[20].lambda == 19.0);
    CHECK(st.history()[119].lambda == 1.0);
    CHECK(after < 0.5 * before);
    CHECK(dg::mesh_genus(s.mesh.triangles, s.mesh.num_vertices()).closed);
  }
  SUBCASE("the anchor holds the vertices to the surface they started on (Stage2Config::anchor)") {
    // how far the vertices moved along the starting normals, mean |(p - p0) . n0|
    const auto normal_motion = [](const dr::HostScene& start, const dr::HostScene& s) {
      double m = 0.0;
      const std::size_t n = s.mesh.positions.size() / 3;
      for (std::size_t v = 0; v < n; ++v) {
        double d = 0.0;
        for (int c = 0; c < 3; ++c)
          d += double(s.mesh.positions[3 * v + c] - start.mesh.positions[3 * v + c]) *
               double(start.mesh.vertex_normals[3 * v + c]);
        m += std::abs(d);
      }
      return m / double(n);
    };
    const dr::HostScene start = dented();
    double moved[2] = {0.0, 0.0};
    for (int k = 0; k < 2; ++k) {
      dr::HostScene s = dented();
      pipeline::Stage2Config c = cfg;
      c.anchor = k == 0 ? 0.0f : 100.0f;
      pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
      while (!st.done()) st.step();
      moved[k] = normal_motion(start, s);
    }
    MESSAGE("mean motion along the starting normals: free " << moved[0] << ", anchor 100 " << moved[1]);
    CHECK(moved[0] > 0.005);  // the dent (0.012 on average) is mostly removed ...
    CHECK(moved[1] < 0.3 * moved[0]);  // ... unless the anchor holds the surface
  }
  // Two fits that differ in one setting of the vertex phase, the IoR moving
  // before the freeze ends: the IoR when the vertices start, the IoR and the
  // vertices at the end.
  struct VertexPhase {
    float ior_at_freeze = 0.0f, ior_at_end = 0.0f;
    std::vector<float> positions;
  };
  const auto vertex_phase = [&](const std::function<void(pipeline::Stage2Config&)>& set) {
    dr::HostScene s = dented();
    pipeline::Stage2Config c = cfg;
    c.optimize_ior = true;
    c.iterations = cfg.freeze_geometry + 10;
    set(c);
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    for (int i = 0; i < c.freeze_geometry; ++i) st.step();
    VertexPhase out;
    out.ior_at_freeze = s.ior;
    while (!st.done()) REQUIRE(st.step().geometry_moving);
    out.ior_at_end = s.ior;
    out.positions = s.mesh.positions;
    return out;
  };
  SUBCASE("brightness weights (Stage2Config::vertex_brightness_power) act while the vertices move, and only then") {
    const VertexPhase off = vertex_phase([](pipeline::Stage2Config& c) { c.vertex_brightness_power = 0.0f; });
    const VertexPhase on = vertex_phase([](pipeline::Stage2Config& c) { c.vertex_brightness_power = 2.0f; });
    CHECK(off.ior_at_freeze == on.ior_at_freeze);  // the materials-only iterations bit for bit as they were
    CHECK(off.positions != on.positions);          // the weighted vertex steps go elsewhere
  }
  SUBCASE("the IoR holds still while the vertices move, unless it moves with them (Stage2Config::ior_with_vertices)") {
    using pipeline::IorWithVertices;
    const VertexPhase held = vertex_phase([](pipeline::Stage2Config& c) { c.ior_with_vertices = IorWithVertices::off; });
    const VertexPhase with = vertex_phase([](pipeline::Stage2Config& c) { c.ior_with_vertices = IorWithVertices::on; });
    MESSAGE("IoR change over the vertex iterations: held " << held.ior_at_end - held.ior_at_freeze << ", with the vertices "
                                                           << with.ior_at_end - with.ior_at_freeze);
    CHECK(held.ior_at_end == held.ior_at_freeze);
    CHECK(with.ior_at_end != with.ior_at_freeze);
    CHECK(held.positions != with.positions);  // the vertices see the IoR move
    // `clear`: held for this absorbing fit (a grid), moving for a clear one
    const VertexPhase clear_absorbing =
        vertex_phase([](pipeline::Stage2Config& c) { c.ior_with_vertices = IorWithVertices::clear; });
    CHECK(clear_absorbing.positions == held.positions);
    CHECK(clear_absorbing.ior_at_end == held.ior_at_end);
    const auto clear_object = [](IorWithVertices mode) {
      return [mode](pipeline::Stage2Config& c) {
        c.absorption_model = pipeline::AbsorptionModel::none;
        c.ior_with_vertices = mode;
      };
    };
    const VertexPhase clear_on = vertex_phase(clear_object(IorWithVertices::on));
    const VertexPhase clear_auto = vertex_phase(clear_object(IorWithVertices::clear));
    const VertexPhase clear_off = vertex_phase(clear_object(IorWithVertices::off));
    CHECK(clear_auto.positions == clear_on.positions);
    CHECK(clear_auto.ior_at_end == clear_on.ior_at_end);
    CHECK(clear_auto.ior_at_end != clear_auto.ior_at_freeze);
    CHECK(clear_off.ior_at_end == clear_off.ior_at_freeze);
  }
  SUBCASE("the vertices' own colour loss (Stage2Config::geometry_colour_loss) acts while they move, and only then") {
    const VertexPhase plain =
        vertex_phase([](pipeline::Stage2Config& c) { c.geometry_colour_loss = losses::ColourLoss::l2; });
    const VertexPhase log_loss =
        vertex_phase([](pipeline::Stage2Config& c) { c.geometry_colour_loss = losses::ColourLoss::log_l2; });
    CHECK(plain.ior_at_freeze == log_loss.ior_at_freeze);  // the materials-only iterations bit for bit as they were
    CHECK(plain.positions != log_loss.positions);          // the vertices follow another loss
  }
  SUBCASE("neighbouring pixels (Stage2Config::geometry_neighbours) act while the vertices move, and only then") {
    const VertexPhase one = vertex_phase([](pipeline::Stage2Config& c) { c.geometry_neighbours = false; });
    const VertexPhase two = vertex_phase([](pipeline::Stage2Config& c) { c.geometry_neighbours = true; });
    CHECK(one.ior_at_freeze == two.ior_at_freeze);  // the materials-only iterations bit for bit as they were
    CHECK(one.positions != two.positions);          // the vertices see other pixels and another residual
  }
  SUBCASE("each pixel's own L2 residual (the vertex loss before neighbours) takes the dent out too") {
    dr::HostScene s = dented();
    pipeline::Stage2Config c = cfg;
    c.geometry_neighbours = false;
    c.geometry_colour_loss = losses::ColourLoss::l2;
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    while (!st.done()) st.step();
    const double after = radius_error(s);
    MESSAGE("each pixel, L2: mean |r - 0.4| " << before << " -> " << after);
    CHECK(after < 0.5 * before);
    CHECK(dg::mesh_genus(s.mesh.triangles, s.mesh.num_vertices()).closed);
  }
  SUBCASE("the silhouette term alone (the plumbing: freeze, large steps, BVH refit)") {
    dr::HostScene s = dented();
    pipeline::Stage2Config c = cfg;
    c.weights.color = c.weights.tone = 0.0f;
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    while (!st.done()) st.step();
    const double after = radius_error(s);
    MESSAGE("silhouettes alone: mean |r - 0.4| " << before << " -> " << after);
    CHECK(after < 0.5 * before);
  }
}

TEST_CASE("Stage2::neighbour_loss: blind to a residual shared by the two pixels; adjoints against differences") {
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.0f));
  const Photos photos = photograph(truth, 2, 16);
  dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
  const Vec3f tp(0.30f, 0.55f, 0.12f), tq(0.80f, 0.20f, 0.45f);
  for (const losses::ColourLoss kind : {losses::ColourLoss::l2, losses::ColourLoss::log_l2}) {
    for (const pipeline::PixelLoss mode : {pipeline::PixelLoss::mean, pipeline::PixelLoss::pairs}) {
      CAPTURE(int(kind));
      CAPTURE(int(mode));
      pipeline::Stage2Config c;
      c.pixel_loss = mode;
      c.iterations = 1;
      pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
      const int k = 2;
      // both pixels off by the same per-channel amount: additive for l2,
      // a gain on 1 + x for log_l2 (what an absorption's factor becomes)
      const Vec3f shift(0.07f, -0.05f, 0.11f), gain(0.85f, 1.3f, 0.95f);  // every sample stays above 0
      const auto shared = [&](const Vec3f& t, float wobble) {
        return kind == losses::ColourLoss::l2 ? t + shift + wobble : gain * (Vec3f(1.0f) + t) - Vec3f(1.0f) + wobble;
      };
      // samples scattered symmetrically around the shared residual: their
      // means carry it exactly
      std::vector<Vec3f> L = {shared(tp, 0.0f), shared(tp, 0.0f), shared(tq, 0.0f), shared(tq, 0.0f)};
      std::vector<Vec3f> adjoint(2 * k);
      const pipeline::Stage2::RayLoss blind = st.neighbour_loss(L.data(), k, tp, tq, 1.0f, adjoint.data(), kind);
      CHECK(std::abs(blind.colour) < 1e-10);
      for (const Vec3f& a : adjoint) CHECK(glm::length(a) < 1e-5f);
      // a residual at one pixel only is seen
      L = {shared(tp, 0.05f), shared(tp, 0.03f), shared(tq, 0.0f), shared(tq, -0.01f)};
      const pipeline::Stage2::RayLoss seen = st.neighbour_loss(L.data(), k, tp, tq, 1.0f, adjoint.data(), kind);
      CHECK(seen.colour > 1e-4);
      // adjoints against central differences of the value
      for (int q = 0; q < 2 * k; ++q)
        for (int ch = 0; ch < 3; ++ch) {
          std::vector<Vec3f> up = L, down = L, scratch(2 * k);
          const float h = 1e-3f;
          up[std::size_t(q)][ch] += h;
          down[std::size_t(q)][ch] -= h;
          const double fd = (st.neighbour_loss(up.data(), k, tp, tq, 1.0f, scratch.data(), kind).value -
                             st.neighbour_loss(down.data(), k, tp, tq, 1.0f, scratch.data(), kind).value) /
                            (2.0 * h);
          CHECK(adjoint[std::size_t(q)][ch] == doctest::Approx(fd).epsilon(2e-2).scale(1e-3));
        }
    }
  }
}

TEST_CASE("stage 2 with geometry: refraction finds a pit that the silhouettes cannot see") {
  // The truth: a glass sphere with a pit at its top (radius scaled down by up
  // to 25 % where y/|p| > 0.85, a smoothstep in y/|p|): a bowl 0.04 deep
  // inside a rim. No silhouette touches a concave point: the masks see a
  // flat lid over the bowl. Stage 2 starts from the round
  // sphere; only the refracted colour can tell the vertices to sink.
  const float r0 = 0.4f, depth = 0.25f, edge = 0.85f;
  const auto true_radius = [&](const Vec3f& dir) {
    const float t = std::max(0.0f, (dir.y - edge) / (1.0f - edge));
    return r0 * (1.0f - depth * t * t * (3.0f - 2.0f * t));
  };
  const auto pitted = [&](dr::HostScene s) {
    for (std::size_t v = 0; v * 3 < s.mesh.positions.size(); ++v) {
      float* p = &s.mesh.positions[3 * v];
      const Vec3f q(p[0], p[1], p[2]);
      const Vec3f d = q / std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z);
      for (int c = 0; c < 3; ++c) p[c] = d[c] * true_radius(d);
    }
    s.positions_changed();
    return s;
  };
  // mean |radius − true radius| over the vertices of the pit and its rim
  const auto pit_error = [&](const dr::HostScene& s) {
    double e = 0.0;
    int n = 0;
    for (std::size_t v = 0; v * 3 < s.mesh.positions.size(); ++v) {
      const float* p = &s.mesh.positions[3 * v];
      const Vec3f q(p[0], p[1], p[2]);
      const float len = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z);
      if (q.y / len <= 0.7f) continue;
      e += std::abs(double(len) - double(true_radius(q / len)));
      ++n;
    }
    REQUIRE(n > 20);
    return e / n;
  };
  const dr::HostScene truth = pitted(glass_sphere(1.45f, Vec3f(0.0f)));
  const Photos photos = photograph(truth, 12, 48);
  pipeline::Stage2Config cfg;
  cfg.absorption_model = pipeline::AbsorptionModel::grid;
  cfg.iterations = 160;
  cfg.freeze_geometry = 10;
  cfg.geometry_iterations = 500;  // the λ and the blur fall once, after 100 vertex steps
  cfg.blur_halving = 100;
  cfg.rays_per_iteration = 1024;
  cfg.optimize_positions = true;
  cfg.optimize_ior = false;
  cfg.optimize_absorption = false;
  cfg.ior_init = 1.45f;
  cfg.sigma_init = 0.0f;
  cfg.lr_positions = 1e-2f;
  cfg.lambda = 4.0;
  const double before = pit_error(glass_sphere(1.45f, Vec3f(0.0f)));
  const auto run = [&](const pipeline::Stage2Config& c) {
    dr::HostScene s = glass_sphere(1.45f, Vec3f(0.0f));
    pipeline::Stage2 st(s, views_of(photos), mask_views_of(photos), c);
    while (!st.done()) st.step();
    CHECK(dg::mesh_genus(s.mesh.triangles, s.mesh.num_vertices()).closed);
    return pit_error(s);
  };
  // Measured (48² photographs, 2×2 samples each; mean error 0.0234 at the
  // start): the silhouettes alone 0.0158 (they flatten the cap to the lid);
  // one jittered ray per pixel, colour alone, 0.0221 (the ray's variance
  // inside the pixel is part of its loss, and the fit flattens the refracted
  // image); two rays per pixel in pairs, colour alone 0.0160, with the
  // silhouettes 0.0126. Since λ falls at each blur halving (here 4, then 2.8
  // for the last 50 iterations): silhouettes 0.0155, one ray 0.0211, colour
  // alone 0.0106, both 0.0092. Since the vertex gradient stops at 4
  // interactions (geometry_depth): colour alone 0.0109, both 0.0072, one ray
  // 0.0115 — the deep, chaotic derivatives were most of what one ray's
  // variance cost, so the pairs are compared with one ray at every depth.
  // With neighbouring pixels' log residuals (geometry_neighbours): colour
  // alone 0.0099, both 0.0091; every depth colour alone 0.0157, one ray
  // 0.0192 (each pixel's L2 residual: 0.0109, 0.0072; 0.0106, 0.0211).
  pipeline::Stage2Config masks = cfg, colour = cfg, both = cfg, cfg_one = cfg;
  cfg_one.weights.mask = 0.0f;
  cfg_one.pixel_samples = 1;
  masks.weights.color = masks.weights.tone = 0.0f;
  colour.weights.mask = 0.0f;
  for (pipeline::Stage2Config* c : {&colour, &both}) {
    c->pixel_samples = 2;
    c->pixel_loss = pipeline::PixelLoss::pairs;
  }
  pipeline::Stage2Config colour_every_depth = colour, one_every_depth = cfg_one;
  colour_every_depth.geometry_depth = one_every_depth.geometry_depth = 0;
  const double by_masks = run(masks), by_colour = run(colour), by_both = run(both);
  const double pairs_every = run(colour_every_depth), one_every = run(one_every_depth);
  MESSAGE("pit error: start " << before << ", silhouettes alone " << by_masks << ", colour alone " << by_colour
                              << ", both " << by_both << "; every depth: colour alone " << pairs_every
                              << ", with one ray per pixel " << one_every);
  CHECK(by_colour < 0.8 * before);
  CHECK(pairs_every < 0.85 * one_every);
  CHECK(by_both < 0.85 * by_masks);
}

TEST_CASE("stage 2 checkpoint: a resumed fit repeats the uninterrupted one, and another run's file is refused") {
  // one worker (CTest sets DIFFTRANS_THREADS=1 here): the gradient sums are then in a fixed order
  const dr::HostScene truth = glass_sphere(1.45f, Vec3f(0.3f, 0.6f, 0.9f));
  const Photos photos = photograph(truth, 6, 24);
  pipeline::Stage2Config cfg;
  cfg.iterations = 16;
  cfg.ior_warmup = 6;
  cfg.freeze_geometry = 6;  // the vertices move from iteration 6: their optimizer's state goes through the file too
  // λ 19 for iterations 6-8, ~4.4 for 9-11, 1 for 12-13: the stop at 10 lands inside the second level
  cfg.geometry_iterations = 8;
  cfg.blur_halving = 3;
  cfg.lambda_final = 1.0;
  cfg.optimize_positions = true;
  cfg.vertex_average = 5;  // iterations 9 .. 13 averaged: the stop at 10 lands inside, the sum goes through the file
  cfg.lr_ior = 1e-3f;
  cfg.rays_per_iteration = 256;
  cfg.absorption_res = 3;
  bool grid = true;
  SUBCASE("a grid") { cfg.absorption_model = pipeline::AbsorptionModel::grid; }
  SUBCASE("the absorption model chosen before the first iteration: the choice goes through the file") {
    cfg.absorption_model = pipeline::AbsorptionModel::automatic;
    cfg.selection_iterations = 3;
    cfg.selection_batches = 1;
    cfg.selection_holdout = 3;
    cfg.choose_depth = true;  // and the training depth: it goes through the file too
    cfg.depth_batches = 1;
    grid = false;
  }
  const auto fresh = [] { return glass_sphere(1.3f, Vec3f(0.0f)); };
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("difftrans-stage2-" + std::to_string(::getpid()) + ".bin");

  dr::HostScene a = fresh();
  pipeline::Stage2 straight(a, views_of(photos), mask_views_of(photos), cfg);
  while (!straight.done()) straight.step();
  {  // the λ of each iteration: 0 while the vertices hold still, then 19 -> 1 by levels of blur_halving
    const auto& h = straight.history();
    REQUIRE(h.size() == 16);
    const double mid = 19.0 * std::sqrt(1.0 / 19.0);
    const double expected[16] = {0, 0, 0, 0, 0, 0, 19, 19, 19, mid, mid, mid, 1, 1, 0, 0};
    for (int i = 0; i < 16; ++i) CHECK(h[std::size_t(i)].lambda == doctest::Approx(expected[i]));
  }

  for (const int stop : {3, 10}) {  // before and after the vertices start moving
    CAPTURE(stop);
    {
      dr::HostScene b = fresh();
      pipeline::Stage2 first(b, views_of(photos), mask_views_of(photos), cfg);
      while (first.iteration() < stop) first.step();
      first.save(file, "run 1");
    }
    dr::HostScene c = fresh();
    pipeline::Stage2 second(c, views_of(photos), mask_views_of(photos), cfg);
    CHECK_FALSE(second.load(file, "run 2"));  // another run's checkpoint changes nothing
    CHECK(second.iteration() == 0);
    REQUIRE(second.load(file, "run 1"));
    CHECK(second.iteration() == stop);
    CHECK(second.history().size() == std::size_t(stop));
    while (!second.done()) second.step();
    CHECK(c.ior == a.ior);
    CHECK(c.absorption_raw == a.absorption_raw);
    CHECK(c.mesh.positions == a.mesh.positions);
    CHECK(c.mesh.positions != fresh().mesh.positions);  // the vertices did move
    CHECK(second.history().back().color == straight.history().back().color);
    // the level checks' records, their step moments included (a level's sum goes through the file)
    CHECK(second.vertex_levels() == straight.vertex_levels());
    CHECK(c.absorption_kind == a.absorption_kind);
    if (!grid) {
      REQUIRE(second.absorption_choice().is_object());
      CHECK(second.absorption_choice()["summary"] == straight.absorption_choice()["summary"]);
      CHECK(second.absorption_choice()["candidates"].size() == straight.absorption_choice()["candidates"].size());
      REQUIRE(second.depth_choice().is_object());
      CHECK(second.training_trace().max_depth == straight.training_trace().max_depth);
      CHECK(second.training_trace().prune_throughput == straight.training_trace().prune_throughput);
    }
  }
  if (grid) {  // a checkpoint of another grid size is refused
    pipeline::Stage2Config other = cfg;
    other.absorption_res = 4;
    dr::HostScene d = fresh();
    pipeline::Stage2 third(d, views_of(photos), mask_views_of(photos), other);
    CHECK_FALSE(third.load(file, "run 1"));
  }
  std::filesystem::remove(file);
}

TEST_CASE("stage 2 chooses the training depth where the image stops changing beyond its noise") {
  // The same sphere clear and strongly absorbing (σ 6 per unit length): the
  // light beyond a few interactions is lost inside the absorbing one, so its
  // depth must come out shallower, both within the bounds; the pruning
  // threshold is one of the candidates.
  const auto chosen = [](const Vec3f& sigma) {
    const dr::HostScene truth = glass_sphere(1.5f, sigma);
    const Photos photos = photograph(truth, 8, 32);
    dr::HostScene s = glass_sphere(1.5f, sigma);
    pipeline::Stage2Config cfg;
    cfg.optimize_positions = false;  // the materials alone
    cfg.absorption_model = sigma == Vec3f(0.0f) ? pipeline::AbsorptionModel::none : pipeline::AbsorptionModel::homogeneous;
    cfg.sigma_search.clear();
    cfg.iterations = 1;
    cfg.rays_per_iteration = 4096;
    cfg.choose_depth = true;
    cfg.depth_min = 2;
    cfg.trace.max_depth = 12;
    cfg.depth_batches = 2;
    cfg.ior_settle_batches = 0;
    pipeline::Stage2 st(s, views_of(photos), {}, cfg);
    if (sigma != Vec3f(0.0f)) s.set_homogeneous_absorption(sigma);  // the material known: the depth is the question
    st.step();
    const auto& d = st.depth_choice();
    REQUIRE(d.is_object());
    MESSAGE("sigma " << sigma.x << ": depth " << d["depth"] << ", prune " << d["prune"] << ", depths tried "
                     << d["depths"].size());
    CHECK(st.training_trace().max_depth == d["depth"].get<int>());
    CHECK(st.training_trace().tree_depth <= st.training_trace().max_depth);
    CHECK(d["depth"].get<int>() >= 2);
    CHECK(d["depth"].get<int>() <= 12);
    const float prune = st.training_trace().prune_throughput;
    CHECK(std::find(cfg.prune_candidates.begin(), cfg.prune_candidates.end(), prune) != cfg.prune_candidates.end());
    return d["depth"].get<int>();
  };
  const int clear = chosen(Vec3f(0.0f)), absorbing = chosen(Vec3f(6.0f));
  CHECK(absorbing < clear);
}
