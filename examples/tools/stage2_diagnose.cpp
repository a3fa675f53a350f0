// stage2_diagnose: measurements of why stage 2's joint refinement of the
// vertices (pipeline::Stage2 with optimize_positions) makes the stage-1 mesh
// worse, on the loss stage 2 actually optimizes: its batches of jittered
// object-pixel rays, its colour + tone loss, its tracer settings (depth 4,
// pruning 0.01) and its vertex gradient (ray_batch_gradient, normals folded
// into the positions, optionally clipped per ray).
//
//   gradcheck  the directional derivative of the loss on one fixed batch
//              along smooth displacement fields (normal offsets by smooth
//              functions of position): reverse mode (double and float
//              tapes, unclipped and clipped) and forward mode per ray
//              against central differences of the primal (double), in
//              total and ray by ray — by ray class (miss, TIR, number of
//              surface hits), for rays whose path counts changed across the
//              difference or not, and for the paths of at most 1 and 2
//              interactions (adjoints held at x). --check makes it a test:
//              exit status 1 when too few rays agree.
//   home       does the gradient point home? Δ = nearest point of the true
//              mesh − vertex; cosines of −∇L (raw, clipped as stage 2 does,
//              large-steps preconditioned (I + λL)^-2) with Δ per batch and
//              of the batch mean; the gradient's noise split by path length,
//              TIR and target brightness; the deterministic loss along
//              x + tΔ; all at several blurs of the environment, against the
//              photographs or against the true object traced along the same
//              rays (targets that share the blur and carry no pixel filter).
//   ior        where the loss is lowest in the IoR (and, with --sigmas, a
//              grey absorption): the loss over fixed batches on a grid,
//              the parabola through its lowest points, and the spread of
//              dL/dIoR over batches at the material's IoR.
//   ior-noise  the fit's own IoR gradient (its pixel samples, pair loss, tracer
//              and clip) split by pixel class: glinting photographs, glinting
//              samples, dim / middle / bright; per class its slope across
//              three IoRs (the signal) and its spread over batches (the noise).
//   movement   how the refined mesh moved from the stage-1 mesh, read
//              against the truth (metrics::surface_movement): correction,
//              common offset or wandering, and where; with --contours,
//              split by how many masks' outlines pin each vertex; with
//              --bands, by slabs along an axis (a base the silhouettes
//              miss); with --write-map, pictures of the signed movement
//              and of the error it added.
//
// Results are JSON on stdout, progress on stderr.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "../difftrans/materials_views.hpp"
#include "../difftrans/stage_output.hpp"
#include "../difftrans/views.hpp"
#include "difftrans/geometry/remesh.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/metrics/absorption.hpp"
#include "difftrans/io/png.hpp"
#include "difftrans/metrics/movement.hpp"
#include "difftrans/render/mesh_picture.hpp"
#include "difftrans/scene/contour.hpp"
#include "difftrans/optim/large_steps.hpp"
#include "pipeline/environment.hpp"
#include "pipeline/materials.hpp"

namespace {

using namespace difftrans;
namespace fs = std::filesystem;
using render::BatchRay;
using render::HostScene;
using render::TraceSettings;
using render::TraceStats;

// ------------------------------------------------------------------ inputs

struct CommonOptions {
  fs::path scene;
  fs::path mesh;          // the mesh being refined (default: none; required)
  fs::path material;      // default: SCENE/gt/material.json
  std::string env;        // map, folder or constant:R,G,B; default SCENE/gt/envmap.hdr
  int rays = 8192, views = 8, depth = 4;
  float prune = 0.01f;
  std::uint64_t seed = 1;
  int iteration = 0;      // the first batch is Stage2's batch of this iteration
  losses::ColourLoss colour_loss = losses::ColourLoss::l2;
  int pixel_samples = 1;  // rays per pixel (1: the rays one by one; ior-noise: the fit's 2)
};

void add_common(CLI::App* cmd, CommonOptions& o) {
  cmd->add_option("scene", o.scene, "Scene directory (train images and masks)")->required();
  cmd->add_option("--mesh", o.mesh, "Mesh to differentiate (e.g. a stage-1 mesh_stage1.obj)")->required();
  cmd->add_option("--material", o.material, "Material (IoR, absorption); default SCENE/gt/material.json");
  cmd->add_option("--env", o.env, "Environment: a map, a reconstruct folder or constant:R,G,B; default SCENE/gt/envmap.hdr");
  cmd->add_option("--rays", o.rays, "Rays per batch (Stage2Config::rays_per_iteration)")->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--views", o.views, "Views per batch")->capture_default_str()->check(CLI::PositiveNumber);
  cmd->add_option("--depth", o.depth, "Training depth")->capture_default_str()->check(CLI::Range(1, render::max_trace_depth));
  cmd->add_option("--prune", o.prune, "Pruning threshold on a branch's throughput")->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--seed", o.seed, "Stage 2's seed (draws the batches)")->capture_default_str();
  cmd->add_option("--colour-loss", o.colour_loss, "Colour loss per ray: l2, relative_l2, log_l2")
      ->transform(CLI::CheckedTransformer(std::map<std::string, losses::ColourLoss>{
          {"l2", losses::ColourLoss::l2}, {"relative_l2", losses::ColourLoss::relative_l2},
          {"log_l2", losses::ColourLoss::log_l2}}));
  cmd->add_option("--iteration", o.iteration, "Batch k is Stage2's batch of iteration ITERATION + k")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
}

// A separable Gaussian blur of an equirectangular map, sigma in texels
// (wrapping around in longitude, clamped at the poles); sigma <= 0: a copy.
io::Image blur_equirect(const io::Image& in, double sigma) {
  if (sigma <= 0.0) return in;
  const int radius = int(std::ceil(3.0 * sigma));
  std::vector<double> k(std::size_t(2 * radius + 1));
  double sum = 0.0;
  for (int i = -radius; i <= radius; ++i) sum += k[std::size_t(i + radius)] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (double& v : k) v /= sum;
  const int w = in.width, h = in.height;
  io::Image row(w, h), out(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Vec3d acc(0.0);
      for (int i = -radius; i <= radius; ++i) acc += k[std::size_t(i + radius)] * Vec3d(in.at(((x + i) % w + w) % w, y));
      row.set(x, y, Vec3f(acc));
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Vec3d acc(0.0);
      for (int i = -radius; i <= radius; ++i)
        acc += k[std::size_t(i + radius)] * Vec3d(row.at(x, std::clamp(y + i, 0, h - 1)));
      out.set(x, y, Vec3f(acc));
    }
  return out;
}

// A scene's material (IoR and absorption), kept to be put back.
struct MaterialState {
  float ior;
  scene::AbsorptionKind kind;
  std::vector<float> raw;
  Vec3i res;
  Vec3f lo, hi;
  explicit MaterialState(const HostScene& s)
      : ior(s.ior), kind(s.absorption_kind), raw(s.absorption_raw), res(s.absorption_res), lo(s.absorption_lo),
        hi(s.absorption_hi) {}
  void restore(HostScene& s) const {
    s.ior = ior;
    s.absorption_kind = kind;
    s.absorption_raw = raw;
    s.absorption_res = res;
    s.absorption_lo = lo;
    s.absorption_hi = hi;
  }
};

// The scene, the mesh with its material and environment, and a Stage2 that
// draws the batches and evaluates the per-ray loss exactly as the fit does.
class Setup {
 public:
  explicit Setup(const CommonOptions& o) : options_(o) {
    if (!fs::is_directory(o.scene)) throw io::Error(o.scene, "scene directory not found");
    cli::progress("stage2_diagnose: loading " + o.scene.string());
    scene_ = io::load_scene(o.scene);
    for (const auto& w : scene_.warnings) cli::warn(w);
    const fs::path material = o.material.empty() ? scene_.gt.material : o.material;
    if (material.empty() || !fs::exists(material))
      throw io::Error(material.empty() ? o.scene / "gt/material.json" : material, "material not found (give --material)");
    material_ = io::read_material(material);
    const std::string env = o.env.empty() ? scene_.gt.envmap.string() : o.env;
    if (env.empty()) throw io::Error(o.scene, "has no gt/envmap.hdr: give --env");
    environment_ = cli::load_environment(env);
    if (environment_.field) throw io::Error(environment_.file, "a radiance field: these diagnostics need a distant map");
    mesh_ = cli::load_mesh(o.mesh);
    s_ = std::make_unique<HostScene>(render::make_host_scene(mesh_, material_, o.mesh.filename().string()));
    cli::apply_environment(*s_, environment_);
    training_ = cli::materials_training_views(scene_);
    config_.rays_per_iteration = o.rays;
    config_.views_per_iteration = o.views;
    config_.trace.max_depth = o.depth;
    config_.trace.prune_throughput = o.prune;
    config_.seed = o.seed;
    config_.colour_loss = o.colour_loss;
    // the diagnostics look at rays one by one, each against its pixel, but
    // for ior-noise, which takes the fit's samples per pixel
    config_.pixel_samples = o.pixel_samples;
    // Stage2 starts the material afresh; the diagnostics keep the given one
    const MaterialState given(*s_);
    stage_ = std::make_unique<pipeline::Stage2>(*s_, training_.views, training_.mask_views, config_);
    given.restore(*s_);
    for (bool& d : s_->differentiate) d = false;
    s_->differentiate[render::param_positions] = s_->differentiate[render::param_normals] = true;
  }

  HostScene& scene() { return *s_; }
  const io::Scene& data() const { return scene_; }
  const io::Material& material() const { return material_; }
  const pipeline::Stage2& stage() const { return *stage_; }
  const pipeline::Stage2Config& config() const { return config_; }
  const TraceSettings& trace() const { return config_.trace; }
  const cli::Environment& environment() const { return environment_; }
  const io::Mesh& mesh() const { return mesh_; }

  // Stage2's batch of iteration options.iteration + k.
  void batch(int k, std::vector<BatchRay>& rays, std::vector<Vec3f>& target) const {
    std::mt19937_64 rng = stage_->batch_generator(options_.iteration + k);
    stage_->draw_batch(rng, rays, target);
    if (rays.empty()) throw std::runtime_error("stage2_diagnose: the batch is empty (no object pixels?)");
  }

  // The environment blurred by sigma texels (0: as loaded); this scene and `also`.
  void set_blur(double sigma, HostScene* also = nullptr) {
    if (environment_.file.empty()) return;  // a constant: nothing to blur
    const io::Image map = blur_equirect(environment_.map, sigma);
    render::set_environment(*s_, map);
    if (also) render::set_environment(*also, map);
  }

  void set_positions(const std::vector<float>& x) {
    s_->mesh.positions = x;
    s_->positions_changed();
  }

 private:
  CommonOptions options_;
  io::Scene scene_;
  io::Material material_;
  cli::Environment environment_;
  io::Mesh mesh_;
  std::unique_ptr<HostScene> s_;
  cli::MaterialsViews training_;
  pipeline::Stage2Config config_;
  std::unique_ptr<pipeline::Stage2> stage_;
};

// ------------------------------------------------------------------ tracing

// A non-null direction pointer that moves no vertex.
const std::vector<float>& empty_direction() {
  static const std::vector<float> none;
  return none;
}

// One ray's radiance in double, its derivative along a direction of the
// vertex positions (forward mode; zero without a direction) and what the
// tracer counted on its way.
struct RayEval {
  Vec3d radiance{0.0}, derivative{0.0};
  TraceStats stats;
};

bool same_path(const TraceStats& a, const TraceStats& b) {
  return a.segments == b.segments && a.hits == b.hits && a.tir == b.tir && a.pruned == b.pruned &&
         a.depth_cut == b.depth_cut && a.fallback_hits == b.fallback_hits;
}

// Every ray traced in double (or Dual<double, 1> along `direction`, 3 values
// per vertex, when given) with the library's tracer on the thread pool.
// With ior_tangent (and s.differentiate[param_ior]) the derivative is along the IoR instead.
std::vector<RayEval> trace_rays(const HostScene& s, const std::vector<BatchRay>& rays, const TraceSettings& settings,
                                const std::vector<float>* direction = nullptr, bool ior_tangent = false) {
  using D = ad::Dual<double, 1>;
  std::vector<RayEval> out(rays.size());
  ad::ParamSet params = s.params();
  static const float one = 1.0f;
  if (direction) params.buffers[render::param_positions].tangents[0] = direction->data();
  if (ior_tangent) params.buffers[render::param_ior].tangents[0] = &one, direction = &empty_direction();
  const render::SceneView view = s.view(direction != nullptr);
  ThreadPool::global().parallel_for(std::int64_t(rays.size()), 64, [&](std::int64_t b, std::int64_t e, int) {
    for (std::int64_t i = b; i < e; ++i) {
      const BatchRay& r = rays[std::size_t(i)];
      RayEval& o = out[std::size_t(i)];
      s.with_escape([&](const auto& escape) {
        if (direction) {
          ad::ParamReader<D> reader(&params);
          const Vec3<D> L = render::trace<D>(view, s.accel(), reader, r.origin, r.direction, settings, &o.stats, escape);
          for (int c = 0; c < 3; ++c) o.radiance[c] = L[c].value, o.derivative[c] = L[c].grad[0];
        } else {
          ad::ParamReader<double> reader(&params);
          o.radiance = render::trace<double>(view, s.accel(), reader, r.origin, r.direction, settings, &o.stats, escape);
        }
      });
    }
  });
  return out;
}

// The loss of stage 2 averaged over the first `count` of fixed batches, the
// rays traced in double through `scene`.
double mean_batch_loss(const HostScene& scene, const std::vector<std::vector<BatchRay>>& rays,
                       const std::vector<std::vector<Vec3f>>& targets, int count, const pipeline::Stage2& stage,
                       const TraceSettings& settings, float glint_factor = 0.0f) {
  // k rays per pixel, compared as the fit compares them (Stage2::pixel_loss:
  // with pixel pairs, unbiased by the samples' noise)
  const std::size_t k = std::size_t(std::max(1, stage.config().pixel_samples));
  double sum = 0.0;
  std::vector<Vec3f> L(k), adjoint(k);
  for (int b = 0; b < count; ++b) {
    const auto& r = rays[std::size_t(b)];
    const auto& target = targets[std::size_t(b)];
    const float inv_n = 1.0f / float(std::max<std::size_t>(1, target.size()));
    const float level = stage.glint_level(target, glint_factor);  // infinite when glint_factor is 0
    const std::vector<RayEval> e = trace_rays(scene, r, settings);
    for (std::size_t p = 0; p < target.size() && (p + 1) * k <= e.size(); ++p) {
      for (std::size_t q = 0; q < k; ++q) L[q] = Vec3f(e[p * k + q].radiance);
      sum += stage.pixel_loss(L.data(), int(k), target[p], inv_n, adjoint.data(), stage.config().colour_loss, level).value;
    }
  }
  return sum / double(std::max(1, count));
}

// Per-ray loss callback of ray_batch_gradient (ray index, radiance, adjoint out) -> loss.
using LossFn = std::function<double(std::int32_t, const Vec3f&, Vec3f&)>;

// The gradient w.r.t. the vertex positions (normals folded in, as stage 2
// takes it) of Σ loss over `rays`, tapes in T; clip as Stage2 passes it.
template <class T>
std::vector<double> vertex_gradient(const HostScene& s, const std::vector<BatchRay>& rays, const LossFn& loss,
                                    const TraceSettings& settings, float clip = 0.0f, std::int64_t* clipped = nullptr) {
  render::SceneGradient g(s);
  render::PassOptions po;
  po.trace = settings;
  const render::RayBatchResult r = render::ray_batch_gradient<T>(s, rays, loss, g, po, false, clip);
  if (clipped) *clipped = r.clipped_rays;
  if (r.stats.overflowed_rays > 0)
    cli::warn(std::to_string(r.stats.overflowed_rays) + " rays overflowed their tape: no gradient from them");
  return std::vector<double>(g.positions.begin(), g.positions.end());
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}
double norm(const std::vector<double>& a) { return std::sqrt(dot(a, a)); }
double cosine(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = norm(a) * norm(b);
  return n > 0.0 ? dot(a, b) / n : 0.0;
}
double rel_error(double approx, double exact) {
  return std::abs(approx - exact) / std::max(std::abs(exact), 1e-300);
}
double luminance(const Vec3f& c) { return (double(c.x) + double(c.y) + double(c.z)) / 3.0; }

// The ray classes reported separately, from the tracer's counts at x.
const char* ray_class(const TraceStats& st) {
  if (st.hits == 0) return "miss";
  if (st.tir > 0) return "tir";
  if (st.hits <= 2) return "hits_1_2";
  if (st.hits <= 4) return "hits_3_4";
  return "hits_5_plus";
}
const std::vector<std::string> ray_classes = {"miss", "hits_1_2", "hits_3_4", "hits_5_plus", "tir"};

// ------------------------------------------------------------------ gradcheck

// The true object (SCENE/gt/mesh.obj or gt_mesh) with the setup's material and environment.
HostScene true_scene(Setup& setup, const fs::path& gt_mesh) {
  const fs::path gt_path = gt_mesh.empty() ? setup.data().gt.mesh : gt_mesh;
  if (gt_path.empty() || !fs::exists(gt_path)) throw io::Error(gt_path.empty() ? "gt/mesh.obj" : gt_path, "true mesh not found (give --gt-mesh)");
  HostScene truth = render::make_host_scene(cli::load_mesh(gt_path), setup.material(), "truth");
  cli::apply_environment(truth, setup.environment());
  return truth;
}

// Δ: each vertex of x to its nearest point of the true surface.
std::vector<double> delta_to_truth(const std::vector<float>& x, const HostScene& truth) {
  std::vector<double> delta(x.size());
  const geometry::ClosestPointTree tree(truth.mesh.positions, truth.mesh.triangles);
  for (std::size_t v = 0; v < x.size() / 3; ++v) {
    const glm::vec3 p(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
    const glm::vec3 q = tree.closest(p).point;
    for (int c = 0; c < 3; ++c) delta[3 * v + std::size_t(c)] = double(q[c]) - double(p[c]);
  }
  return delta;
}


// Smooth displacement fields: the vertex normal times a smooth function of
// position, scaled to an RMS displacement of 1 per vertex.
std::vector<double> displacement_field(const scene::TriangleMesh& m, const std::string& name) {
  std::vector<double> d(m.positions.size());
  const Vec3d axis = glm::normalize(Vec3d(0.8, 0.5, 0.3));
  const double pi = 3.14159265358979323846;
  for (std::int32_t v = 0; v < m.num_vertices(); ++v) {
    const Vec3d p(m.positions[3 * std::size_t(v)], m.positions[3 * std::size_t(v) + 1], m.positions[3 * std::size_t(v) + 2]);
    double f = 1.0;
    if (name == "wave1") f = std::cos(2.0 * pi * glm::dot(axis, p) + 0.3);
    else if (name == "wave3") f = std::cos(6.0 * pi * glm::dot(axis, p) + 0.3) * std::cos(4.0 * pi * p.y);
    else if (name != "inflate") throw CLI::ValidationError("--fields", "'" + name + "' is not a field (inflate, wave1, wave3, home)");
    for (int c = 0; c < 3; ++c) d[3 * std::size_t(v) + c] = f * double(m.vertex_normals[3 * std::size_t(v) + c]);
  }
  const double rms = norm(d) / std::sqrt(double(std::max<std::int32_t>(1, m.num_vertices())));
  if (!(rms > 0.0)) throw std::runtime_error("displacement field '" + name + "' is zero on this mesh");
  for (double& x : d) x /= rms;
  return d;
}

// FD against AD over a set of rays: sums, the rays that agree, the median per-ray error.
struct Agreement {
  std::int64_t rays = 0, agree = 0;
  double fd = 0.0, ad = 0.0, fd_disagreeing = 0.0, ad_disagreeing = 0.0;
  std::vector<double> errors, magnitudes;
  void add(double f, double a, bool ok, double error) {
    ++rays;
    magnitudes.push_back(std::abs(a));
    fd += f;
    ad += a;
    if (ok) ++agree;
    else fd_disagreeing += f, ad_disagreeing += a;
    errors.push_back(error);
  }
  io::Json json() {
    double median = 0.0;
    if (!errors.empty()) {
      std::nth_element(errors.begin(), errors.begin() + std::ptrdiff_t(errors.size() / 2), errors.end());
      median = errors[errors.size() / 2];
    }
    // how heavy the tail is: the share of Σ|AD_i| that the largest 1 % of the rays carry
    std::sort(magnitudes.begin(), magnitudes.end(), [](double x, double y) { return x > y; });
    double total = 0.0, top = 0.0;
    for (std::size_t i = 0; i < magnitudes.size(); ++i) {
      total += magnitudes[i];
      if (i < (magnitudes.size() + 99) / 100) top += magnitudes[i];
    }
    return {{"rays", rays}, {"agreeing", rays ? double(agree) / double(rays) : 1.0}, {"median_rel_error", median},
            {"ad_abs_top1pct_share", total > 0.0 ? top / total : 0.0},
            {"fd", fd}, {"ad", ad}, {"rel_error", rel_error(fd, ad)}, {"fd_disagreeing", fd_disagreeing},
            {"ad_disagreeing", ad_disagreeing}};
  }
};

// One branch of a ray's Fresnel tree as the tracer took it: where it starts,
// where it goes, its weight and the light it brought back (escaping there).
template <class S>
struct BranchRecord {
  std::uint32_t path;
  int depth;
  Vec3<S> origin, direction, weight, light;
};

// A follow() collector that sums like SumBranches and logs every branch taken.
template <class S>
struct LogBranches {
  std::vector<BranchRecord<S>>* log;
  void made(render::detail::Branch<S>&) const {}
  void taken(const render::detail::Branch<S>& b) const {
    log->push_back({b.path, b.depth, b.origin, b.direction, b.weight, Vec3<S>(S(0), S(0), S(0))});
  }
  void add(Vec3<S>& radiance, const Vec3<S>& light) const {
    radiance += light;
    if (!log->empty()) log->back().light += light;
  }
};

template <class S>
std::vector<BranchRecord<S>> branch_log(const HostScene& s, const BatchRay& r, const TraceSettings& settings,
                                        const std::vector<float>* direction) {
  std::vector<BranchRecord<S>> log;
  ad::ParamSet params = s.params();
  if (direction) params.buffers[render::param_positions].tangents[0] = direction->data();
  const render::SceneView view = s.view(direction != nullptr);
  s.with_escape([&](const auto& escape) {
    ad::ParamReader<S> reader(&params);
    render::detail::trace_camera_ray<S>(view, s.accel(), reader, r.origin, r.direction, settings, nullptr, escape,
                                        LogBranches<S>{&log});
  });
  return log;
}

// Branch by branch, the forward derivative (along d) of a ray's origins,
// directions, weights and light against central differences of the same
// branch (matched by its path bits) at x ± h d: the first branch where they
// part says which interaction a ray's large derivative comes from.
io::Json explain_ray(Setup& setup, const BatchRay& ray, const TraceSettings& settings, const std::vector<float>& x0,
                     const std::vector<float>& xp, const std::vector<float>& xm, const std::vector<float>& d, double h) {
  using D = ad::Dual<double, 1>;
  HostScene& s = setup.scene();
  setup.set_positions(xp);
  const auto plus = branch_log<double>(s, ray, settings, nullptr);
  setup.set_positions(xm);
  const auto minus = branch_log<double>(s, ray, settings, nullptr);
  setup.set_positions(x0);
  const auto at = branch_log<D>(s, ray, settings, &d);
  const auto find = [](const std::vector<BranchRecord<double>>& log, std::uint32_t path) {
    for (const auto& b : log)
      if (b.path == path) return &b;
    return static_cast<const BranchRecord<double>*>(nullptr);
  };
  // largest |AD − FD| over a vector's components, and the |AD| there
  const auto part = [](const Vec3<D>& ad, const Vec3d& p, const Vec3d& m, double step, io::Json& out) {
    double worst = 0.0;
    io::Json a = io::Json::array(), f = io::Json::array();
    for (int c = 0; c < 3; ++c) {
      const double fd = (p[c] - m[c]) / (2.0 * step);
      a.push_back(ad[c].grad[0]);
      f.push_back(fd);
      worst = std::max(worst, std::abs(ad[c].grad[0] - fd));
    }
    out = {{"ad", a}, {"fd", f}};
    return worst;
  };
  io::Json branches = io::Json::array();
  for (const auto& b : at) {
    io::Json bj = {{"path", b.path}, {"depth", b.depth}};
    const auto* p = find(plus, b.path);
    const auto* m = find(minus, b.path);
    bj["weight"] = {b.weight.x.value, b.weight.y.value, b.weight.z.value};
    bj["light"] = {b.light.x.value, b.light.y.value, b.light.z.value};
    if (!p || !m) {
      bj["in_both_neighbours"] = false;
    } else {
      io::Json o, dir, w, l;
      const double eo = part(b.origin, p->origin, m->origin, h, o);
      const double ed = part(b.direction, p->direction, m->direction, h, dir);
      const double ew = part(b.weight, p->weight, m->weight, h, w);
      const double el = part(b.light, p->light, m->light, h, l);
      bj["origin"] = o, bj["direction"] = dir, bj["weight_derivative"] = w, bj["light_derivative"] = l;
      bj["largest_difference"] = {{"origin", eo}, {"direction", ed}, {"weight", ew}, {"light", el}};
    }
    branches.push_back(bj);
  }
  return branches;
}

// How a branch's direction derivative (along d, forward mode) grows with its
// depth over the first `count` rays: per depth the median and 90th percentile
// of |∂direction| over the branches whose weight is at least 0.01, and the
// median's growth from the depth before. A factor well above 1 per
// interaction means a chaotic path, whose derivative is true at the point and
// useless over any step that moves the light (docs/stage2-diagnostics.md).
io::Json direction_growth(HostScene& s, const std::vector<BatchRay>& rays, std::size_t count,
                          const TraceSettings& settings, const std::vector<float>& d) {
  using D = ad::Dual<double, 1>;
  std::vector<std::vector<double>> by_depth(std::size_t(render::max_trace_depth + 1));
  for (std::size_t i = 0; i < std::min(count, rays.size()); ++i)
    for (const auto& b : branch_log<D>(s, rays[i], settings, &d)) {
      if (b.depth < 1 || std::max({b.weight.x.value, b.weight.y.value, b.weight.z.value}) < 0.01) continue;
      const double g = std::sqrt(square(b.direction.x.grad[0]) + square(b.direction.y.grad[0]) +
                                 square(b.direction.z.grad[0]));
      by_depth[std::size_t(b.depth)].push_back(g);
    }
  io::Json out = io::Json::array();
  double last = 0.0;
  for (std::size_t k = 1; k < by_depth.size(); ++k) {
    std::vector<double>& v = by_depth[k];
    if (v.empty()) break;
    std::sort(v.begin(), v.end());
    const double median = v[v.size() / 2], p90 = v[std::min(v.size() - 1, v.size() * 9 / 10)];
    io::Json row = {{"depth", k}, {"branches", v.size()}, {"median", median}, {"p90", p90}};
    if (last > 0.0) row["median_growth"] = median / last;
    last = median;
    out.push_back(row);
  }
  return out;
}

struct GradcheckOptions {
  std::vector<std::string> fields{"inflate", "wave1", "wave3"};
  std::vector<double> steps{1e-3, 3e-4, 1e-4, 3e-5};
  double ray_tolerance = 0.01;  // a ray agrees when |FD − AD| <= this · (|AD| + floor)
  bool check = false;           // exit status 1 unless min_agreeing of the unchanged rays agree at some step
  double min_agreeing = 0.8;    // and reverse and forward mode agree within reverse_tolerance · Σ|AD_i|
  double reverse_tolerance = 1e-3;
  std::string inject;       // "flat-normals": differentiate a renderer with flat facets (the check must catch it)
  int explain = 0;          // the largest rays whose branches are compared one by one (explain_ray)
};

io::Json gradcheck(Setup& setup, const GradcheckOptions& o, bool& passed) {
  HostScene& s = setup.scene();
  std::vector<BatchRay> rays;
  std::vector<Vec3f> target;
  setup.batch(0, rays, target);
  const std::size_t n = rays.size();
  const float inv_n = 1.0f / float(n);
  const TraceSettings settings = setup.trace();
  TraceSettings ad_settings = settings;
  if (o.inject == "flat-normals") ad_settings.smooth_normals = false;
  else if (!o.inject.empty()) throw CLI::ValidationError("--inject", "'" + o.inject + "' is not known (flat-normals)");
  const pipeline::Stage2& stage = setup.stage();
  const std::vector<float> x0 = s.mesh.positions;

  // at x: per-ray losses, their adjoints, the classes, the radiance at depths 1 and 2 (path-length parts)
  const std::vector<RayEval> at_x = trace_rays(s, rays, settings);
  std::vector<Vec3f> adjoint(n);
  std::vector<int> cls(n);
  double loss0 = 0.0;
  io::Json class_counts = io::Json::object();
  for (const std::string& c : ray_classes) class_counts[c] = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto l = stage.ray_loss(Vec3f(at_x[i].radiance), target[i], inv_n, stage.config().colour_loss);
    adjoint[i] = l.adjoint;
    loss0 += l.value;
    const std::string c = ray_class(at_x[i].stats);
    cls[i] = int(std::find(ray_classes.begin(), ray_classes.end(), c) - ray_classes.begin());
    class_counts[c] = class_counts[c].get<int>() + 1;
  }
  const LossFn real_loss = [&](std::int32_t i, const Vec3f& L, Vec3f& dL) {
    const auto l = stage.ray_loss(L, target[std::size_t(i)], inv_n, stage.config().colour_loss);
    dL = l.adjoint;
    return l.value;
  };
  const std::vector<int> depths = {1, 2, settings.max_depth};

  io::Json out;
  out["rays"] = n;
  out["loss"] = loss0;
  out["ray_classes"] = class_counts;
  out["inject"] = o.inject.empty() ? "none" : o.inject;
  out["fields"] = io::Json::array();
  passed = true;
  for (const std::string& name : o.fields) {
    cli::progress("gradcheck: field " + name);
    io::Json fj;
    std::vector<double> field;
    if (name == "home") {  // Δ towards the true surface, scaled to an RMS of 1 per vertex
      field = delta_to_truth(x0, true_scene(setup, {}));
      const double rms = norm(field) / std::sqrt(double(std::max<std::int32_t>(1, s.mesh.num_vertices())));
      if (!(rms > 0.0)) throw std::runtime_error("the mesh lies on the true surface: no 'home' field");
      fj["rms_to_truth"] = rms;
      for (double& x : field) x /= rms;
    } else {
      field = displacement_field(s.mesh, name);
    }
    fj["field"] = name;
    // reverse mode at x, double and float tapes, unclipped and clipped as stage 2
    s.mesh.positions = x0;
    s.positions_changed();
    const TraceSettings& ts = ad_settings;
    const std::vector<double> g_double = vertex_gradient<double>(s, rays, real_loss, ts);
    const std::vector<double> g_float = vertex_gradient<float>(s, rays, real_loss, ts);
    std::int64_t clipped = 0;
    const std::vector<double> g_clipped =
        vertex_gradient<float>(s, rays, real_loss, ts, setup.config().clip_geometry * inv_n, &clipped);
    io::Json steps = io::Json::array();
    const std::size_t full = depths.size() - 1;
    // per ray and path length: agreed with AD at some step; the counts unchanged at every step
    std::vector<std::vector<char>> agreed(depths.size(), std::vector<char>(n, 0));
    std::vector<char> unchanged_always(n, 1);
    double worst_reverse_forward = 0.0;
    for (double h : o.steps) {
      // x ± h d rounded to float; the derivative is taken along the displacement actually made
      std::vector<float> xp(x0.size()), xm(x0.size());
      std::vector<double> d(x0.size());
      for (std::size_t k = 0; k < x0.size(); ++k) {
        xp[k] = float(double(x0[k]) + h * field[k]);
        xm[k] = float(double(x0[k]) - h * field[k]);
        d[k] = (double(xp[k]) - double(xm[k])) / (2.0 * h);
      }
      const std::vector<float> df(d.begin(), d.end());
      io::Json sj;
      sj["h"] = h;
      for (std::size_t k = 0; k < depths.size(); ++k) {
        TraceSettings t = settings, ta = ad_settings;
        t.max_depth = ta.max_depth = depths[k];
        setup.set_positions(xp);
        const std::vector<RayEval> plus = trace_rays(s, rays, t);
        setup.set_positions(xm);
        const std::vector<RayEval> minus = trace_rays(s, rays, t);
        setup.set_positions(x0);
        const std::vector<RayEval> fwd = trace_rays(s, rays, ta, &df);
        // per ray: FD and AD of the real loss (full depth) or of a_i · radiance (the parts, adjoints held at x)
        std::vector<double> fd(n), adv(n);
        std::vector<char> same(n);
        for (std::size_t i = 0; i < n; ++i) {
          if (k == full) {
            const double lp = stage.ray_loss(Vec3f(plus[i].radiance), target[i], inv_n, stage.config().colour_loss).value;
            const double lm = stage.ray_loss(Vec3f(minus[i].radiance), target[i], inv_n, stage.config().colour_loss).value;
            fd[i] = (lp - lm) / (2.0 * h);
          } else {
            fd[i] = glm::dot(Vec3d(adjoint[i]), plus[i].radiance - minus[i].radiance) / (2.0 * h);
          }
          adv[i] = glm::dot(Vec3d(adjoint[i]), fwd[i].derivative);
          same[i] = same_path(plus[i].stats, minus[i].stats);
        }
        double ms = 0.0;
        for (double a : adv) ms += a * a;
        const double floor = 1e-3 * std::sqrt(ms / double(n));  // |AD_i| below this counts as zero
        std::vector<char> agree(n);
        for (std::size_t i = 0; i < n; ++i) {
          agree[i] = std::abs(fd[i] - adv[i]) <= o.ray_tolerance * (std::abs(adv[i]) + floor);
          agreed[k][i] = agreed[k][i] || agree[i];
        }
        const auto summary = [&](const std::function<bool(std::size_t)>& in) {
          Agreement a;
          for (std::size_t i = 0; i < n; ++i)
            if (in(i)) a.add(fd[i], adv[i], agree[i] != 0, std::abs(fd[i] - adv[i]) / (std::abs(adv[i]) + floor));
          return a.json();
        };
        if (k == full) {
          double fd_all = 0.0, ad_fwd = 0.0, ad_abs = 0.0;
          std::int64_t changed = 0;
          for (std::size_t i = 0; i < n; ++i) {
            fd_all += fd[i];
            ad_fwd += adv[i];
            ad_abs += std::abs(adv[i]);
            changed += !same[i];
            unchanged_always[i] = unchanged_always[i] && same[i];
          }
          const double ad_rev = dot(g_double, d);
          sj["ad_reverse_double"] = ad_rev;
          if (h == o.steps.front()) {
            // the rays with the largest forward derivative, each also in reverse mode on its own: where the
            // batch's forward and reverse sums part, is it these rays, and do the two modes agree on each?
            std::vector<std::size_t> order(n);
            std::iota(order.begin(), order.end(), std::size_t(0));
            const std::size_t top = std::min<std::size_t>(8, n);
            std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(top), order.end(),
                              [&](std::size_t a, std::size_t b) { return std::abs(adv[a]) > std::abs(adv[b]); });
            io::Json largest = io::Json::array();
            for (std::size_t r = 0; r < top; ++r) {
              const std::size_t j = order[r];
              const LossFn one = [&](std::int32_t, const Vec3f& L, Vec3f& dL) {
                const auto l = stage.ray_loss(L, target[j], inv_n, stage.config().colour_loss);
                dL = l.adjoint;
                return l.value;
              };
              const double reverse_j = dot(vertex_gradient<double>(s, std::vector<BatchRay>{rays[j]}, one, ts), d);
              largest.push_back({{"ray", j},
                                 {"forward", adv[j]},
                                 {"reverse", reverse_j},
                                 {"fd", fd[j]},
                                 {"segments", fwd[j].stats.segments},
                                 {"hits", fwd[j].stats.hits},
                                 {"tir", fwd[j].stats.tir},
                                 {"min_cos2_t", fwd[j].stats.min_cos2_t}});
              if (r < std::size_t(o.explain))
                largest.back()["branches"] = explain_ray(setup, rays[j], ta, x0, xp, xm, df, h);
            }
            sj["largest_rays"] = largest;
            sj["direction_derivative_by_depth"] = direction_growth(s, rays, 1024, ta, df);
          }
          sj["ad_reverse_float"] = dot(g_float, d);
          sj["ad_reverse_clipped"] = dot(g_clipped, d);
          sj["ad_forward"] = ad_fwd;
          sj["fd"] = fd_all;
          sj["rel_error"] = rel_error(fd_all, ad_rev);
          // relative to Σ|AD_i|: the rays' terms cancel, and the reverse pass sums them into float gradients
          const double reverse_forward = std::abs(ad_fwd - ad_rev) / std::max(ad_abs, 1e-300);
          sj["reverse_vs_forward"] = reverse_forward;
          worst_reverse_forward = std::max(worst_reverse_forward, reverse_forward);
          sj["changed_rays"] = changed;
          sj["rays"] = summary([](std::size_t) { return true; });
          sj["unchanged"] = summary([&](std::size_t i) { return same[i] != 0; });
          sj["changed"] = summary([&](std::size_t i) { return !same[i]; });
          io::Json cj = io::Json::object();
          for (std::size_t c = 0; c < ray_classes.size(); ++c)
            cj[ray_classes[c]] = summary([&](std::size_t i) { return cls[i] == int(c); });
          sj["classes"] = cj;
        } else {
          sj[k == 0 ? "depth_1" : "depth_2"] = summary([&](std::size_t i) { return same[i] != 0; });
        }
      }
      steps.push_back(sj);
    }
    setup.set_positions(x0);
    // rays that agreed with AD at some step, by ray class and path length
    const auto fraction = [&](const std::vector<char>& ok, const std::function<bool(std::size_t)>& in) {
      std::int64_t m = 0, a = 0;
      for (std::size_t i = 0; i < n; ++i)
        if (in(i)) ++m, a += ok[i];
      return m ? double(a) / double(m) : 1.0;
    };
    io::Json agreeing;
    agreeing["all"] = fraction(agreed[full], [](std::size_t) { return true; });
    agreeing["unchanged"] = fraction(agreed[full], [&](std::size_t i) { return unchanged_always[i] != 0; });
    for (std::size_t c = 0; c < ray_classes.size(); ++c)
      agreeing[ray_classes[c]] = fraction(agreed[full], [&](std::size_t i) { return cls[i] == int(c); });
    agreeing["depth_1"] = fraction(agreed[0], [](std::size_t) { return true; });
    agreeing["depth_2"] = fraction(agreed[1], [](std::size_t) { return true; });
    fj["clipped_rays"] = clipped;
    fj["gradient_norm"] = norm(g_double);
    fj["steps"] = steps;
    fj["agreeing_at_some_step"] = agreeing;
    fj["worst_reverse_vs_forward"] = worst_reverse_forward;
    const double unchanged_agreeing = agreeing["unchanged"].get<double>();
    if (o.check && (unchanged_agreeing < o.min_agreeing || worst_reverse_forward > o.reverse_tolerance)) passed = false;
    out["fields"].push_back(fj);
  }
  out["ray_tolerance"] = o.ray_tolerance;
  if (o.check) {
    out["min_agreeing"] = o.min_agreeing;
    out["reverse_tolerance"] = o.reverse_tolerance;
    out["passed"] = passed;
  }
  return out;
}

// ------------------------------------------------------------------ home

struct HomeOptions {
  fs::path gt_mesh;                      // default SCENE/gt/mesh.obj
  std::vector<double> blurs{0, 2, 8, 32};
  int batches = 20;
  int loss_batches = 8;
  double t_max = 1.5, t_step = 0.1;
  double lambda = -1.0;                  // large steps' λ of the preconditioned components (< 0: stage 2's)
  std::string targets = "photo";         // photo | ray
  int noise_blur_index = 0;              // the blur whose gradient noise is split by class
  fs::path write_projected;              // the mesh moved onto the true surface (x + Δ), as OBJ
  int bands = 0;                         // > 0: the mean gradients against Δ slab by slab along band_axis
  std::string band_axis = "y";
};

// Running statistics of one gradient component over the batches.
struct ComponentStats {
  std::vector<double> sum;               // Σ_b g_b
  double sum_norm2 = 0.0, sum_proj = 0.0, sum_proj2 = 0.0, sum_cos = 0.0;
  int count = 0;
  void add(const std::vector<double>& g, const std::vector<double>& delta_unit) {
    if (sum.empty()) sum.assign(g.size(), 0.0);
    for (std::size_t k = 0; k < g.size(); ++k) sum[k] += g[k];
    const double p = -dot(g, delta_unit);
    sum_norm2 += dot(g, g);
    sum_proj += p;
    sum_proj2 += p * p;
    sum_cos += p / std::max(norm(g), 1e-300);
    ++count;
  }
  io::Json json(const std::vector<double>& delta_unit) const {
    const double nb = double(std::max(1, count));
    std::vector<double> mean(sum.size());
    for (std::size_t k = 0; k < sum.size(); ++k) mean[k] = sum[k] / nb;
    const double mp = sum_proj / nb, var_p = std::max(0.0, sum_proj2 / nb - mp * mp);
    const double mean_norm2 = sum_norm2 / nb, norm2_of_mean = dot(mean, mean);
    return {{"mean_cos_minus_grad_delta", sum_cos / nb},
            {"cos_minus_mean_grad_delta", -cosine(mean, delta_unit)},
            {"proj_mean", mp},             // E[−g·Δ̂]
            {"proj_std", std::sqrt(var_p)},
            {"proj_snr", std::sqrt(var_p) > 0 ? mp / std::sqrt(var_p) : 0.0},
            {"norm2_mean", mean_norm2},    // E|g|²
            {"norm2_of_mean", norm2_of_mean},
            {"variance_total", std::max(0.0, mean_norm2 - norm2_of_mean)}};
  }
};

// (I + λL)^-2 g, the direction of large steps' first update in x.
std::vector<double> preconditioned(const optim::LargeSteps& m, const std::vector<double>& g) {
  const std::vector<float> gf(g.begin(), g.end());
  const std::vector<float> once = m.backward(gf);
  const std::vector<float> twice = m.backward(once);
  return std::vector<double>(twice.begin(), twice.end());
}

// Each vertex of `mesh` by its slab: `count` equal slabs of the truth's
// extent along the named axis, both in the truth's unit box (the frame of
// evaluate --bands), shared by `home --bands` and `movement --bands`.
struct VertexSlabs {
  metrics::Slabs slabs;
  std::vector<int> of_vertex;
};
VertexSlabs vertex_slabs(const io::Mesh& mesh, const io::Mesh& truth, const std::string& axis, int count) {
  const io::UnitBoxTransform frame = io::unit_box_transform(truth);
  io::Mesh m = mesh, t = truth;
  io::apply_transform(frame, m);
  io::apply_transform(frame, t);
  VertexSlabs out{metrics::slabs_over(t.positions, metrics::axis_index(axis), count), {}};
  out.of_vertex.resize(m.positions.size());
  for (std::size_t v = 0; v < m.positions.size(); ++v)
    out.of_vertex[v] = out.slabs.of(double(m.positions[v][out.slabs.axis]));
  return out;
}

// The batches' mean gradient against Δ within each slab of the truth's
// extent along an axis (the vertices by their position in the truth's unit
// box, as `movement --bands`): does the gradient point home in the part that
// holds the error, and how much of the step falls there?
io::Json home_by_bands(const std::vector<int>& band, int bands, const std::vector<double>& sum,
                       const std::vector<double>& delta) {
  io::Json rows = io::Json::array();
  double all_g = 0.0, all_d = 0.0;
  for (std::size_t k = 0; k < sum.size(); ++k) all_g += sum[k] * sum[k], all_d += delta[k] * delta[k];
  for (int b = 0; b < bands; ++b) {
    double gd = 0.0, gg = 0.0, dd = 0.0;
    int vertices = 0;
    for (std::size_t v = 0; v < band.size(); ++v) {
      if (band[v] != b) continue;
      ++vertices;
      for (std::size_t c = 3 * v; c < 3 * v + 3; ++c) gd += sum[c] * delta[c], gg += sum[c] * sum[c], dd += delta[c] * delta[c];
    }
    rows.push_back({{"vertices", vertices},
                    {"cos_minus_mean_grad_delta", gg > 0.0 && dd > 0.0 ? -gd / std::sqrt(gg * dd) : 0.0},
                    {"share_of_step", all_g > 0.0 ? gg / all_g : 0.0},     // of |mean gradient|²
                    {"share_of_delta", all_d > 0.0 ? dd / all_d : 0.0}});  // of |Δ|²
  }
  return rows;
}

io::Json home(Setup& setup, const HomeOptions& o) {
  HostScene& s = setup.scene();
  HostScene truth = true_scene(setup, o.gt_mesh);
  const std::vector<float> x0 = s.mesh.positions;
  std::vector<double> delta = delta_to_truth(x0, truth), delta_unit;
  const double delta_norm = norm(delta);
  delta_unit = delta;
  for (double& x : delta_unit) x /= delta_norm;
  // how much of Δ lies along the vertex normals (fraction of |Δ|²)
  double along_normal = 0.0;
  {
    double sum = 0.0;
    for (std::size_t v = 0; v < x0.size() / 3; ++v) {
      double dn = 0.0;
      for (int c = 0; c < 3; ++c) dn += delta[3 * v + std::size_t(c)] * double(s.mesh.vertex_normals[3 * v + std::size_t(c)]);
      sum += dn * dn;
    }
    along_normal = sum / std::max(1e-300, delta_norm * delta_norm);
  }
  if (!o.write_projected.empty()) {
    std::vector<float> xp(x0.size());
    for (std::size_t k = 0; k < x0.size(); ++k) xp[k] = float(double(x0[k]) + delta[k]);
    io::write_mesh(o.write_projected, cli::to_io_mesh(xp, s.mesh.triangles));
  }
  const double lambda = o.lambda >= 0.0 ? o.lambda : setup.config().lambda;
  optim::LargeSteps large_steps(lambda);
  large_steps.set_topology(s.mesh.triangles, s.mesh.num_vertices());

  const std::size_t nv = x0.size() / 3;
  io::Json out;
  // the best cosine a preconditioned step can reach: that of (I + λL)^-2 Δ with Δ
  out["preconditioned_ceiling"] = cosine(preconditioned(large_steps, delta), delta);
  out["vertices"] = nv;
  out["delta_rms"] = delta_norm / std::sqrt(double(nv));
  out["delta_energy_along_normals"] = along_normal;
  out["targets"] = o.targets;
  out["lambda"] = lambda;
  out["blurs"] = io::Json::array();
  // --bands: each vertex's slab (in the truth's unit box)
  const VertexSlabs bands = o.bands > 0 ? vertex_slabs(cli::to_io_mesh(x0, s.mesh.triangles),
                                                       cli::to_io_mesh(truth.mesh.positions, truth.mesh.triangles),
                                                       o.band_axis, o.bands)
                                        : VertexSlabs{};
  const pipeline::Stage2& stage = setup.stage();
  TraceSettings reference = render::reference_pass_options().trace;

  for (std::size_t bi = 0; bi < o.blurs.size(); ++bi) {
    const double blur = o.blurs[bi];
    setup.set_blur(blur, &truth);
    const bool split = int(bi) == o.noise_blur_index;
    cli::progress("home: blur " + std::to_string(blur) + " texels" + (split ? " (noise split by class)" : ""));
    setup.set_positions(x0);
    // the batches: rays, targets (photographs, or the true object along the same ray)
    const int nb = std::max(o.batches, o.loss_batches);
    std::vector<std::vector<BatchRay>> rays(static_cast<std::size_t>(nb));
    std::vector<std::vector<Vec3f>> targets(static_cast<std::size_t>(nb));
    for (int b = 0; b < nb; ++b) {
      setup.batch(b, rays[std::size_t(b)], targets[std::size_t(b)]);
      if (o.targets == "ray") {
        const std::vector<RayEval> t = trace_rays(truth, rays[std::size_t(b)], reference);
        for (std::size_t i = 0; i < t.size(); ++i) targets[std::size_t(b)][i] = Vec3f(t[i].radiance);
      }
    }
    // brightness tertiles of the first batch's targets
    std::vector<double> lum;
    for (const Vec3f& c : targets[0]) lum.push_back(luminance(c));
    std::sort(lum.begin(), lum.end());
    const double t1 = lum[lum.size() / 3], t2 = lum[2 * lum.size() / 3];

    std::vector<std::string> names = {"raw",       "clipped",         "depth_2", "main_path", "main_path_clipped",
                                      "clipped_normal", "main_path_clipped_normal"};
    if (split) names.insert(names.end(), {"paths_1", "paths_2", "paths_3_4", "tir", "no_tir", "dark", "mid", "bright"});
    std::vector<ComponentStats> comp(names.size()), comp_pre(7);
    double sum_clipped_rays = 0.0;
    for (int b = 0; b < o.batches; ++b) {
      const auto& r = rays[std::size_t(b)];
      const auto& tg = targets[std::size_t(b)];
      const float inv_n = 1.0f / float(r.size());
      const LossFn loss = [&](std::int32_t i, const Vec3f& L, Vec3f& dL) {
        const auto l = stage.ray_loss(L, tg[std::size_t(i)], inv_n, stage.config().colour_loss);
        dL = l.adjoint;
        return l.value;
      };
      std::int64_t clipped = 0;
      const std::vector<double> g = vertex_gradient<float>(s, r, loss, setup.trace());
      const std::vector<double> gc =
          vertex_gradient<float>(s, r, loss, setup.trace(), setup.config().clip_geometry * inv_n, &clipped);
      sum_clipped_rays += double(clipped) / double(r.size());
      // fixed adjoints from the full-depth radiance; parts by depth and by ray subsets
      const std::vector<RayEval> at_x = trace_rays(s, r, setup.trace());
      std::vector<Vec3f> adj(r.size());
      for (std::size_t i = 0; i < r.size(); ++i) adj[i] = stage.ray_loss(Vec3f(at_x[i].radiance), tg[i], inv_n, stage.config().colour_loss).adjoint;
      const auto fixed = [&](const std::vector<char>& keep) {
        return LossFn([&adj, keep](std::int32_t i, const Vec3f&, Vec3f& dL) {
          dL = keep[std::size_t(i)] ? adj[std::size_t(i)] : Vec3f(0.0f);
          return 0.0;
        });
      };
      const std::vector<char> all(r.size(), 1);
      TraceSettings d1 = setup.trace(), d2 = setup.trace();
      d1.max_depth = 1;
      d2.max_depth = 2;
      // the colour of the depth-4 tree, the vertex gradient through the paths of at most 2 interactions
      const std::vector<double> g12 = vertex_gradient<float>(s, r, fixed(all), d2);
      // the loss of the whole tree, its vertex gradient through the main
      // refraction path only (entry and exit: TraceSettings::gradient_refractions)
      TraceSettings main_path = setup.trace();
      main_path.gradient_refractions = 2;
      const std::vector<double> gm = vertex_gradient<float>(s, r, loss, main_path);
      const std::vector<double> gmc =
          vertex_gradient<float>(s, r, loss, main_path, setup.config().clip_geometry * inv_n);
      // each vertex's gradient projected on its normal (Δ lies mostly along the normals)
      const auto along_normals = [&](const std::vector<double>& v) {
        std::vector<double> out(v.size());
        for (std::size_t q = 0; q < nv; ++q) {
          double dn = 0.0;
          for (int c = 0; c < 3; ++c) dn += v[3 * q + std::size_t(c)] * double(s.mesh.vertex_normals[3 * q + std::size_t(c)]);
          for (int c = 0; c < 3; ++c) out[3 * q + std::size_t(c)] = dn * double(s.mesh.vertex_normals[3 * q + std::size_t(c)]);
        }
        return out;
      };
      const std::vector<double> gcn = along_normals(gc), gmcn = along_normals(gmc);
      const std::vector<const std::vector<double>*> parts{&g, &gc, &g12, &gm, &gmc, &gcn, &gmcn};
      for (std::size_t c = 0; c < parts.size(); ++c) {
        comp[c].add(*parts[c], delta_unit);
        comp_pre[c].add(preconditioned(large_steps, *parts[c]), delta_unit);
      }
      if (!split) continue;
      const std::vector<double> g1 = vertex_gradient<float>(s, r, fixed(all), d1);
      std::vector<double> g2(g.size()), g34(g.size());
      for (std::size_t k = 0; k < g.size(); ++k) g2[k] = g12[k] - g1[k], g34[k] = g[k] - g12[k];
      comp[7].add(g1, delta_unit);
      comp[8].add(g2, delta_unit);
      comp[9].add(g34, delta_unit);
      std::vector<char> tir(r.size()), dark(r.size()), mid(r.size()), bright(r.size());
      for (std::size_t i = 0; i < r.size(); ++i) {
        tir[i] = at_x[i].stats.tir > 0;
        const double l = luminance(tg[i]);
        dark[i] = l < t1;
        bright[i] = l >= t2;
        mid[i] = !dark[i] && !bright[i];
      }
      const std::vector<double> gt = vertex_gradient<float>(s, r, fixed(tir), setup.trace());
      std::vector<double> gnt(g.size());
      for (std::size_t k = 0; k < g.size(); ++k) gnt[k] = g[k] - gt[k];
      comp[10].add(gt, delta_unit);
      comp[11].add(gnt, delta_unit);
      comp[12].add(vertex_gradient<float>(s, r, fixed(dark), setup.trace()), delta_unit);
      comp[13].add(vertex_gradient<float>(s, r, fixed(mid), setup.trace()), delta_unit);
      comp[14].add(vertex_gradient<float>(s, r, fixed(bright), setup.trace()), delta_unit);
    }
    io::Json bj;
    bj["blur_texels"] = blur;
    bj["clipped_ray_fraction"] = sum_clipped_rays / double(std::max(1, o.batches));
    io::Json cj = io::Json::object();
    for (std::size_t c = 0; c < names.size(); ++c) cj[names[c]] = comp[c].json(delta_unit);
    cj["raw_preconditioned"] = comp_pre[0].json(delta_unit);
    cj["clipped_preconditioned"] = comp_pre[1].json(delta_unit);
    for (std::size_t c = 2; c < comp_pre.size(); ++c) cj[names[c] + "_preconditioned"] = comp_pre[c].json(delta_unit);
    bj["gradient"] = cj;
    if (o.bands > 0) {
      io::Json rows = home_by_bands(bands.of_vertex, o.bands, comp_pre[1].sum, delta);  // clipped, preconditioned: the step
      for (int b = 0; b < o.bands; ++b)
        rows[std::size_t(b)]["from"] = bands.slabs.lower(b), rows[std::size_t(b)]["to"] = bands.slabs.upper(b);
      bj["clipped_preconditioned_by_bands"] = {{"axis", o.band_axis}, {"bands", rows}};
    }
    if (split) bj["brightness_tertiles"] = {t1, t2};
    // the deterministic loss along x + tΔ over loss_batches fixed batches, and at the true mesh
    const auto mean_loss = [&](const HostScene& scene) {
      return mean_batch_loss(scene, rays, targets, o.loss_batches, stage, setup.trace());
    };
    io::Json line = io::Json::array();
    double best_t = 0.0, best_loss = 1e300;
    for (int k = 0; k * o.t_step <= o.t_max + 1e-9; ++k) {
      const double t = k * o.t_step;
      std::vector<float> x(x0.size());
      for (std::size_t q = 0; q < x0.size(); ++q) x[q] = float(double(x0[q]) + t * delta[q]);
      setup.set_positions(x);
      const double l = mean_loss(s);
      if (l < best_loss) best_loss = l, best_t = t;
      line.push_back({{"t", t}, {"loss", l}});
    }
    setup.set_positions(x0);
    bj["loss_along_delta"] = line;
    bj["argmin_t"] = best_t;
    bj["loss_true_mesh"] = mean_loss(truth);
    out["blurs"].push_back(bj);
  }
  setup.set_blur(0.0, &truth);
  return out;
}

// ------------------------------------------------------------------ ior

struct IorOptions {
  std::vector<double> iors;              // the IoR values of the scan
  std::vector<double> sigmas;            // grey homogeneous absorption values (empty: the material's)
  int loss_batches = 8;                  // fixed batches averaged per point
  int gradient_batches = 8;              // batches of dL/dIoR at the material's IoR
  std::vector<double> check_steps;       // per-ray central differences of the first batch (empty: none)
  std::vector<double> clip_ior{0.0};     // per-ray clips of the IoR derivative (0: none)
  float glint = 0.0f;                    // leave out pixels brighter than this × the batch's median (0: none)
};

// Where is the loss lowest in the IoR (and a grey absorption)? The loss
// averaged over fixed batches on a grid of IoR (× σ) values, the parabola
// through the lowest point and its neighbours, and the IoR gradient's mean
// and spread over batches at the material's IoR. On the true mesh with the
// true environment and a deep enough tracer the minimum must sit at the
// true IoR; each departure (recovered map, depth, stage-1 mesh) shows
// what moves it.
io::Json ior_scan(Setup& setup, const IorOptions& o) {
  HostScene& s = setup.scene();
  const pipeline::Stage2& stage = setup.stage();
  const MaterialState material(s);
  const float ior0 = s.ior;
  const auto restore_material = [&] { material.restore(s); };
  const int nb = std::max(o.loss_batches, o.gradient_batches);
  std::vector<std::vector<BatchRay>> rays(static_cast<std::size_t>(nb));
  std::vector<std::vector<Vec3f>> targets(static_cast<std::size_t>(nb));
  for (int b = 0; b < nb; ++b) setup.batch(b, rays[std::size_t(b)], targets[std::size_t(b)]);
  const auto mean_loss = [&] { return mean_batch_loss(s, rays, targets, o.loss_batches, stage, setup.trace(), o.glint); };
  io::Json out;
  out["glint_factor"] = o.glint;
  out["pixel_samples"] = stage.config().pixel_samples;
  // the per-ray statistics below: each of a pixel's k rays against its photograph
  const std::size_t k = std::size_t(std::max(1, stage.config().pixel_samples));
  // the gradient at the material's IoR, batch by batch, each ray's
  // derivative clipped at each of clip_ior (per ray, before the 1/n of the mean; 0: not clipped)
  {
    for (bool& d : s.differentiate) d = false;
    s.differentiate[render::param_ior] = true;
    io::Json gj = io::Json::array();
    for (const double clip : o.clip_ior) {
      double sum = 0.0, sum2 = 0.0, clipped = 0.0;
      for (int b = 0; b < o.gradient_batches; ++b) {
        const auto& r = rays[std::size_t(b)];
        const auto& tg = targets[std::size_t(b)];
        const float inv_n = 1.0f / float(r.size());
        render::SceneGradient g(s);
        render::PassOptions po;
        po.trace = setup.trace();
        const render::RayBatchResult rb = render::ray_batch_gradient<float>(
            s, r,
            [&](std::int32_t i, const Vec3f& L, Vec3f& dL) {
              const auto l = stage.ray_loss(L, tg[std::size_t(i) / k], inv_n, stage.config().colour_loss);
              dL = l.adjoint;
              return l.value;
            },
            g, po, false, 0.0f, float(clip) * inv_n);
        sum += double(g.ior[0]);
        sum2 += double(g.ior[0]) * double(g.ior[0]);
        clipped += double(rb.clipped_ior_rays) / double(r.size());
      }
      const double n = double(std::max(1, o.gradient_batches)), mean = sum / n;
      const double sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
      gj.push_back({{"clip", clip}, {"mean", mean}, {"std", sd}, {"standard_error", sd / std::sqrt(n)},
                    {"snr", sd > 0.0 ? mean / sd : 0.0}, {"clipped_ray_fraction", clipped / n}});
    }
    out["gradient_at_material_ior"] = {{"ior", ior0}, {"batches", o.gradient_batches}, {"by_clip", gj}};
    for (bool& d : s.differentiate) d = false;
    s.differentiate[render::param_positions] = s.differentiate[render::param_normals] = true;
  }
  // ray by ray on the first batch: forward mode against central differences
  if (!o.check_steps.empty()) {
    const auto& r = rays[0];
    const auto& tg = targets[0];
    const float inv_n = 1.0f / float(r.size());
    for (bool& d : s.differentiate) d = false;
    s.differentiate[render::param_ior] = true;
    const std::vector<RayEval> at = trace_rays(s, r, setup.trace(), nullptr, true);
    for (bool& d : s.differentiate) d = false;
    s.differentiate[render::param_positions] = s.differentiate[render::param_normals] = true;
    std::vector<double> ad_ray(r.size());
    double rms = 0.0;
    for (std::size_t i = 0; i < r.size(); ++i) {
      const Vec3f adj = stage.ray_loss(Vec3f(at[i].radiance), tg[i / k], inv_n, stage.config().colour_loss).adjoint;
      ad_ray[i] = glm::dot(Vec3d(adj), at[i].derivative);
      rms += ad_ray[i] * ad_ray[i];
    }
    rms = std::sqrt(rms / double(std::max<std::size_t>(1, r.size())));
    // the heavy tail: do the rays of largest IoR derivative refract near the
    // critical angle (TraceStats::min_cos2_t small), more than the others?
    {
      std::vector<std::size_t> order(r.size());
      std::iota(order.begin(), order.end(), std::size_t(0));
      std::sort(order.begin(), order.end(),
                [&](std::size_t a, std::size_t b) { return std::abs(ad_ray[a]) > std::abs(ad_ray[b]); });
      const std::size_t top = std::min(r.size(), std::max<std::size_t>(8, r.size() / 100));
      const auto describe = [&](std::size_t from, std::size_t to) {
        std::vector<float> c2;
        double share = 0.0, total = 0.0;
        std::int64_t near = 0;
        for (std::size_t k = from; k < to; ++k) {
          c2.push_back(at[order[k]].stats.min_cos2_t);
          near += at[order[k]].stats.min_cos2_t < 0.01f;
          share += std::abs(ad_ray[order[k]]);
        }
        for (double a : ad_ray) total += std::abs(a);
        std::sort(c2.begin(), c2.end());
        return io::Json{{"rays", to - from},
                        {"median_min_cos2_t", c2.empty() ? 1.0f : c2[c2.size() / 2]},
                        {"fraction_below_0.01", c2.empty() ? 0.0 : double(near) / double(c2.size())},
                        {"share_of_sum_abs", total > 0.0 ? share / total : 0.0}};
      };
      out["critical_angle"] = {{"largest_1pct", describe(0, top)}, {"others", describe(top, r.size())}};
    }
    io::Json checks = io::Json::array();
    for (const double h : o.check_steps) {
      s.ior = float(double(ior0) + h);
      const std::vector<RayEval> up = trace_rays(s, r, setup.trace());
      s.ior = float(double(ior0) - h);
      const std::vector<RayEval> down = trace_rays(s, r, setup.trace());
      s.ior = ior0;
      const double step = (double(float(double(ior0) + h)) - double(float(double(ior0) - h)));
      double sum_ad = 0.0, sum_fd = 0.0, fd_changed = 0.0, ad_changed = 0.0;
      std::int64_t agree = 0, changed = 0;
      std::map<std::string, Agreement> by_class;
      for (std::size_t i = 0; i < r.size(); ++i) {
        const double lu = stage.ray_loss(Vec3f(up[i].radiance), tg[i / k], inv_n, stage.config().colour_loss).value;
        const double ld = stage.ray_loss(Vec3f(down[i].radiance), tg[i / k], inv_n, stage.config().colour_loss).value;
        const double fd = (lu - ld) / step, a = ad_ray[i];
        const bool ok = std::abs(fd - a) <= 0.01 * std::abs(a) + 1e-3 * rms;
        const bool moved = !same_path(up[i].stats, at[i].stats) || !same_path(down[i].stats, at[i].stats);
        sum_ad += a, sum_fd += fd;
        agree += ok;
        if (moved) ++changed, fd_changed += fd, ad_changed += a;
        by_class[ray_class(at[i].stats)].add(fd, a, ok, std::abs(fd - a) / std::max(std::abs(a), 1e-300));
      }
      io::Json cj = io::Json::object();
      for (auto& [name, ag] : by_class) cj[name] = ag.json();
      checks.push_back({{"step", h}, {"sum_ad", sum_ad}, {"sum_fd", sum_fd},
                        {"agreeing_fraction", double(agree) / double(r.size())},
                        {"path_changed_rays", changed}, {"sum_fd_path_changed", fd_changed},
                        {"sum_ad_path_changed", ad_changed}, {"by_class", cj}});
    }
    out["ray_check"] = checks;
  }
  std::vector<double> sigmas = o.sigmas;
  if (sigmas.empty()) sigmas.push_back(-1.0);  // the material's own absorption
  io::Json rows = io::Json::array();
  double best = 1e300, best_ior = 0.0, best_sigma = 0.0;
  for (const double sigma : sigmas) {
    restore_material();
    if (sigma >= 0.0) s.set_homogeneous_absorption(Vec3f(float(sigma)));
    std::vector<double> losses;
    for (const double ior : o.iors) {
      s.ior = float(ior);
      losses.push_back(mean_loss());
      cli::progress("ior: sigma " + (sigma >= 0.0 ? std::to_string(sigma) : std::string("material")) + " IoR " +
                    std::to_string(ior) + " loss " + std::to_string(losses.back()));
    }
    const std::size_t k = std::size_t(std::min_element(losses.begin(), losses.end()) - losses.begin());
    // the vertex of the parabola through the lowest point and its neighbours (equal spacing not assumed)
    double vertex = o.iors[k];
    if (k > 0 && k + 1 < losses.size()) {
      const double x0 = o.iors[k - 1], x1 = o.iors[k], x2 = o.iors[k + 1];
      const double y0 = losses[k - 1], y1 = losses[k], y2 = losses[k + 1];
      const double d = (x0 - x1) * (x0 - x2) * (x1 - x2);
      const double a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / d;
      const double b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / d;
      if (a > 0.0) vertex = -b / (2.0 * a);
    }
    if (losses[k] < best) best = losses[k], best_ior = vertex, best_sigma = sigma;
    io::Json row;
    if (sigma >= 0.0) row["sigma"] = sigma;
    else row["sigma"] = "material";
    row["loss"] = losses;
    row["argmin_ior"] = o.iors[k];
    row["parabola_ior"] = vertex;
    rows.push_back(row);
  }
  restore_material();
  out["iors"] = o.iors;
  out["rows"] = rows;
  out["best"] = {{"ior", best_ior}, {"loss", best}};
  if (best_sigma >= 0.0) out["best"]["sigma"] = best_sigma;
  return out;
}

struct IorNoiseOptions {
  int batches = 32;           // fixed batches per IoR
  double step = 0.02;         // the IoRs: the material's and ± step
  float glint = 20.0f;        // a glint: brighter than this times the batch's median photographed pixel
};

// Which pixels carry the IoR's signal and which its noise, in the fit's own
// estimator: its samples per pixel and their pair loss, its tracer and its
// per-ray clip. The IoR gradient of each batch is split by pixel class
// (the gradient is a sum over pixels, so the classes' parts add up to it):
// pixels whose photograph glints, pixels where only a sample glints, and
// the rest by the photograph's brightness (thirds of the batch). At the
// material's IoR and ± step, per class: the mean part and its spread over
// the batches, and the slope of each batch's three values. The slope is the
// signal (how hard the class pulls the IoR back per unit of error), the
// spread the noise; batches_for_0.01 is how many batches a 0.01 error needs
// before the class's mean pull stands two standard errors clear of zero.
io::Json ior_noise(Setup& setup, const IorNoiseOptions& o) {
  HostScene& s = setup.scene();
  const pipeline::Stage2& stage = setup.stage();
  const float ior0 = s.ior;
  const int k = std::max(1, stage.config().pixel_samples);
  enum Class : int { photo_glint, sample_glint, dim, middle, bright, classes };
  static const char* const names[classes] = {"photograph_glints", "a_sample_glints", "dim", "middle", "bright"};
  const std::vector<double> iors{double(ior0) - o.step, double(ior0), double(ior0) + o.step};
  // value[class][ior][batch]
  std::vector<std::vector<std::vector<double>>> value(
      classes, std::vector<std::vector<double>>(iors.size(), std::vector<double>(std::size_t(o.batches), 0.0)));
  std::vector<double> pixels(classes, 0.0);
  double split_error = 0.0;  // the largest |sum of the parts - the whole| / sum of |parts| over the batches
  for (bool& d : s.differentiate) d = false;
  s.differentiate[render::param_ior] = true;
  for (int b = 0; b < o.batches; ++b) {
    std::vector<BatchRay> rays;
    std::vector<Vec3f> target;
    setup.batch(b, rays, target);
    const std::size_t n = target.size();
    const float inv_n = 1.0f / float(std::max<std::size_t>(1, n));
    const float level = stage.glint_level(target, o.glint);
    // the brightness thirds of the pixels whose photograph does not glint
    std::vector<float> bright_of;
    for (const Vec3f& t : target)
      if (pipeline::Stage2::brightest(t) <= level) bright_of.push_back(float(luminance(t)));
    std::sort(bright_of.begin(), bright_of.end());
    const float third1 = bright_of.empty() ? 0.0f : bright_of[bright_of.size() / 3];
    const float third2 = bright_of.empty() ? 0.0f : bright_of[2 * bright_of.size() / 3];
    const auto class_of = [&](std::size_t p, const Vec3f* L) {
      if (!(pipeline::Stage2::brightest(target[p]) <= level)) return photo_glint;
      for (int q = 0; q < k; ++q)
        if (!(pipeline::Stage2::brightest(L[q]) <= level)) return sample_glint;
      const float y = float(luminance(target[p]));
      return y < third1 ? dim : y < third2 ? middle : bright;
    };
    for (std::size_t q = 0; q < iors.size(); ++q) {
      s.ior = float(iors[q]);
      for (int c = 0; c < classes; ++c) {
        render::SceneGradient g(s);
        render::PassOptions po;
        po.trace = setup.trace();
        std::vector<std::uint8_t> counted(n, 0);
        render::ray_group_gradient<float>(
            s, rays, k,
            [&](std::int64_t i, const Vec3f* L, Vec3f* dL) {
              const std::size_t p = std::size_t(i);
              if (class_of(p, L) != c) {
                for (int j = 0; j < k; ++j) dL[j] = Vec3f(0.0f);
                return 0.0;
              }
              counted[p] = 1;
              return stage.pixel_loss(L, k, target[p], inv_n, dL, stage.config().colour_loss).value;
            },
            g, po, false, 0.0f, stage.config().clip_ior * inv_n);
        value[std::size_t(c)][q][std::size_t(b)] = double(g.ior[0]);
        if (q == 1) pixels[std::size_t(c)] += double(std::count(counted.begin(), counted.end(), std::uint8_t(1))) / double(n);
      }
      if (q != 1) continue;
      // the whole batch at once: the parts must add up to it
      render::SceneGradient g(s);
      render::PassOptions po;
      po.trace = setup.trace();
      render::ray_group_gradient<float>(
          s, rays, k,
          [&](std::int64_t i, const Vec3f* L, Vec3f* dL) {
            return stage.pixel_loss(L, k, target[std::size_t(i)], inv_n, dL, stage.config().colour_loss).value;
          },
          g, po, false, 0.0f, stage.config().clip_ior * inv_n);
      double parts = 0.0, size = 0.0;
      for (int c = 0; c < classes; ++c)
        parts += value[std::size_t(c)][1][std::size_t(b)], size += std::abs(value[std::size_t(c)][1][std::size_t(b)]);
      split_error = std::max(split_error, std::abs(parts - double(g.ior[0])) / std::max(size, 1e-30));
    }
    cli::progress("ior-noise: batch " + std::to_string(b + 1) + "/" + std::to_string(o.batches));
  }
  s.ior = ior0;
  for (bool& d : s.differentiate) d = false;
  s.differentiate[render::param_positions] = s.differentiate[render::param_normals] = true;
  const auto mean_sd = [](const std::vector<double>& v) {
    double m = 0.0, var = 0.0;
    for (double x : v) m += x / double(v.size());
    for (double x : v) var += (x - m) * (x - m) / double(std::max<std::size_t>(1, v.size() - 1));
    return std::pair<double, double>(m, std::sqrt(var));
  };
  // a group of classes: their parts summed batch by batch
  const auto report = [&](const std::vector<int>& members) {
    io::Json j;
    double share = 0.0;
    for (int c : members) share += pixels[std::size_t(c)] / double(o.batches);
    j["pixel_share"] = share;
    io::Json at = io::Json::array();
    std::vector<std::vector<double>> sum(iors.size(), std::vector<double>(std::size_t(o.batches), 0.0));
    for (std::size_t q = 0; q < iors.size(); ++q) {
      for (int c : members)
        for (int b = 0; b < o.batches; ++b) sum[q][std::size_t(b)] += value[std::size_t(c)][q][std::size_t(b)];
      const auto [m, sd] = mean_sd(sum[q]);
      at.push_back({{"ior", iors[q]}, {"mean", m}, {"std", sd}, {"standard_error", sd / std::sqrt(double(o.batches))}});
    }
    j["gradient"] = at;
    std::vector<double> slope(std::size_t(o.batches));
    for (int b = 0; b < o.batches; ++b)
      slope[std::size_t(b)] = (sum[2][std::size_t(b)] - sum[0][std::size_t(b)]) / (iors[2] - iors[0]);
    const auto [sm, ssd] = mean_sd(slope);
    const double noise = mean_sd(sum[1]).second;
    j["slope"] = sm;
    j["slope_standard_error"] = ssd / std::sqrt(double(o.batches));
    // a 0.01 error pulls by 0.01 × slope; its mean over N batches stands 2 SE clear when N ≥ (2 σ / (0.01 slope))²
    j["batches_for_0.01"] = sm > 0.0 ? std::pow(2.0 * noise / (0.01 * sm), 2.0) : -1.0;
    return j;
  };
  io::Json out;
  out["iors"] = iors;
  out["batches"] = o.batches;
  out["pixel_samples"] = k;
  out["glint_factor"] = o.glint;
  // float sums of the rays in another order: the parts and the whole agree to rounding
  out["split_error"] = split_error;
  out["split_exact"] = split_error < 1e-3;
  io::Json by = io::Json::object();
  for (int c = 0; c < classes; ++c) by[names[c]] = report({c});
  out["by_class"] = by;
  out["all"] = report({photo_glint, sample_glint, dim, middle, bright});
  out["without_glints"] = report({dim, middle, bright});
  out["without_sample_glints"] = report({photo_glint, dim, middle, bright});
  return out;
}

std::vector<double> parse_numbers(const std::string& text, const std::string& option) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string part; std::getline(ss, part, ',');) {
    char* end = nullptr;
    const double x = std::strtod(part.c_str(), &end);
    if (part.empty() || *end != '\0' || !std::isfinite(x)) throw CLI::ValidationError(option, "'" + text + "' is not a list of numbers");
    v.push_back(x);
  }
  if (v.empty()) throw CLI::ValidationError(option, "is empty");
  return v;
}

}  // namespace

// ------------------------------------------------------------------ environment

struct EnvironmentOptions {
  fs::path truth;    // the true map (default SCENE/gt/envmap.hdr)
  int batches = 8;
  int margin = 2;    // the environment stage's margin around the masks
  float glint = 20.0f;
  fs::path write_filled;  // the recovered map with its unseen texels from the true map (an experiment's input)
};

// The parts of the sphere the object's rays escape to: seen or not by any
// background pixel of the training views (the texels a bilinear lookup of an
// observation touches, at the map's resolution), upper or lower hemisphere.
enum EscapeRegion : int { seen_upper, seen_lower, unseen_upper, unseen_lower, region_count };
const char* region_name(int r) {
  static const char* names[] = {"seen_upper", "seen_lower", "unseen_upper", "unseen_lower"};
  return names[r];
}

// An escape that sees `map` in one region and black elsewhere.
struct RegionEscape {
  scene::EnvMap map;
  const std::vector<std::uint8_t>* seen;
  int width, height, region;
  template <class Reader>
  Vec3f operator()(Reader& reader, const render::SceneView&, const Vec3f&, const Vec3f& d) const {
    const Vec2f uv = scene::direction_to_uv(d);
    const int col = std::clamp(int(uv.x * float(width)), 0, width - 1);
    const int row = std::clamp(int(uv.y * float(height)), 0, height - 1);
    const bool is_seen = (*seen)[std::size_t(row) * std::size_t(width) + std::size_t(col)] != 0;
    const int r = (is_seen ? 0 : 2) + (uv.y > 0.5f ? 1 : 0);
    return r == region ? scene::lookup(reader, map, d) : Vec3f(0.0f);
  }
};

// Where the light of the object's pixels comes from, and how the recovered
// map differs from the true one there. The object (the given mesh and
// material) is traced along Stage2's batches, once per region of the sphere
// with the true map and once with the recovered one (each seeing only that
// region): per region and channel the sum over the batches' rays, beside the
// photographs' sum over the same pixels.
io::Json environment_sources(Setup& setup, const EnvironmentOptions& o) {
  const cli::Environment& recovered = setup.environment();
  if (recovered.map.width == 0) throw std::runtime_error("environment: --env must be a map");
  const fs::path truth_file = o.truth.empty() ? setup.data().gt.envmap : o.truth;
  if (truth_file.empty() || !fs::exists(truth_file)) throw io::Error(truth_file, "true map not found (give --truth)");
  const cli::Environment truth = cli::load_environment(truth_file.string());
  if (truth.map.width == 0) throw io::Error(truth_file, "not a map");
  const int W = recovered.map.width, H = recovered.map.height;
  // the texels background observations touch, at the recovered map's size
  pipeline::BackgroundOptions bo;
  bo.margin = o.margin;
  const std::vector<scene::EnvObservation> obs = pipeline::background_observations(setup.data().train, bo);
  const std::vector<std::uint8_t> seen = pipeline::seen_texels(obs, W, H);
  if (!o.write_filled.empty()) {
    io::Image filled = recovered.map;
    const scene::EnvMap t = scene::equirect_environment(truth.map.rgb.data(), truth.map.width, truth.map.height);
    ad::ParamReader<float> reader(nullptr);
    for (int row = 0; row < H; ++row)
      for (int col = 0; col < W; ++col)
        if (!seen[std::size_t(row) * std::size_t(W) + std::size_t(col)])
          filled.set(col, row, scene::lookup_uv(reader, t, Vec2f((float(col) + 0.5f) / float(W), (float(row) + 0.5f) / float(H))));
    io::write_hdr(o.write_filled, filled);
  }
  const scene::EnvMap maps[2] = {scene::equirect_environment(truth.map.rgb.data(), truth.map.width, truth.map.height),
                                 scene::equirect_environment(recovered.map.rgb.data(), W, H)};
  const HostScene& s = setup.scene();
  std::array<std::array<Vec3d, region_count>, 2> sums{};
  Vec3d photographed(0.0);
  std::int64_t rays_traced = 0, glint_pixels = 0;
  for (int b = 0; b < o.batches; ++b) {
    std::vector<BatchRay> rays;
    std::vector<Vec3f> target;
    setup.batch(b, rays, target);
    std::vector<Vec3f> L[2][region_count];
    std::vector<Vec3f> full[2] = {std::vector<Vec3f>(rays.size(), Vec3f(0.0f)), std::vector<Vec3f>(rays.size(), Vec3f(0.0f))};
    for (int m = 0; m < 2; ++m)
      for (int r = 0; r < region_count; ++r) {
        L[m][r] = render::trace_batch(s, rays, setup.trace(), RegionEscape{maps[m], &seen, W, H, r});
        for (std::size_t i = 0; i < rays.size(); ++i) full[m][i] += L[m][r][i];
      }
    // glints (Stage2Config::sigma_search_glint): a pixel whose photograph or
    // either render is brighter than the level is left out of every sum
    const float level = setup.stage().glint_level(target, o.glint);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      if (pipeline::Stage2::glinting(target[i], &full[0][i], 1, level) ||
          pipeline::Stage2::glinting(target[i], &full[1][i], 1, level)) {
        ++glint_pixels;
        continue;
      }
      ++rays_traced;
      photographed += Vec3d(target[i]);
      for (int m = 0; m < 2; ++m)
        for (int r = 0; r < region_count; ++r) sums[std::size_t(m)][std::size_t(r)] += Vec3d(L[m][r][i]);
    }
  }
  const auto rgb = [](const Vec3d& v) { return io::Json::array({v.x, v.y, v.z}); };
  io::Json regions = io::Json::object();
  Vec3d total_true(0.0), total_recovered(0.0);
  for (int r = 0; r < region_count; ++r) {
    const Vec3d t = sums[0][std::size_t(r)], c = sums[1][std::size_t(r)];
    total_true += t;
    total_recovered += c;
    regions[region_name(r)] = {{"true_sum", rgb(t)}, {"recovered_sum", rgb(c)},
                               {"recovered_over_true", rgb(Vec3d(c.x / t.x, c.y / t.y, c.z / t.z))}};
  }
  for (int r = 0; r < region_count; ++r) {
    const Vec3d t = sums[0][std::size_t(r)];
    regions[region_name(r)]["share_of_true_light"] =
        rgb(Vec3d(t.x / total_true.x, t.y / total_true.y, t.z / total_true.z));
  }
  return {{"map_size", {W, H}},
          {"background_observations", obs.size()},
          {"seen_solid_angle_fraction", pipeline::seen_solid_angle_fraction(seen, W, H)},
          {"rays", rays_traced},
          {"glint_pixels_left_out", glint_pixels},
          {"photographed_sum", rgb(photographed)},
          {"true_sum", rgb(total_true)},
          {"recovered_sum", rgb(total_recovered)},
          {"regions", regions}};
}

// ---------------------------------------------------------------- movement

struct MovementOptions {
  fs::path scene, mesh, reference, gt_mesh;
  fs::path material;   // the fitted material, against SCENE/gt/material.json under the surface
  fs::path other;      // another refinement of the same reference (same vertices): does the movement repeat?
  double depth = 0.03;  // how far under the surface σ is read, in the truth's bounding box's largest side
  fs::path write_map;  // PREFIX: PREFIX_moved.png, PREFIX_change.png
  double scale = 0.01;
  double contour_band = 0.0;  // > 0: split the vertices by how many training masks' outlines pin them
  int bands = 0;               // > 0: split the vertices into slabs along band_axis
  std::string band_axis = "y";
};

// Blue (−1) through light grey (0) to red (+1); t in [0, 1] maps −1..1.
render::VertexColour diverging(float t) {
  const float x = std::clamp(2.0f * t - 1.0f, -1.0f, 1.0f);
  const std::array<float, 3> mid{200.0f, 200.0f, 200.0f}, lo{40.0f, 90.0f, 230.0f}, hi{225.0f, 45.0f, 35.0f};
  const std::array<float, 3>& end = x < 0.0f ? lo : hi;
  const float a = std::abs(x);
  render::VertexColour c{};
  for (std::size_t k = 0; k < 3; ++k) c[k] = std::uint8_t(std::lround(mid[k] + a * (end[k] - mid[k])));
  return c;
}

// σ of a material at p (none, homogeneous or a grid)
Vec3f material_sigma(const io::Material& m, const Vec3f& p) {
  return m.absorption == io::AbsorptionType::grid          ? metrics::grid_sigma_at(m.grid, p)
         : m.absorption == io::AbsorptionType::homogeneous ? m.sigma
                                                           : Vec3f(0.0f);
}

// Does the surface move where the fitted absorption is wrong? Under each
// vertex (o.depth of the truth's largest side along its inward normal) the
// fitted σ against the true σ, as the mean over channels of
// ln((σ_fit + 0.05) / (σ_true + 0.05)); then the correlation of the
// vertices' signed movement with it. A fit too dark somewhere (ratio > 0)
// can lighten the pixels by thinning the object there (movement < 0): a
// negative correlation is that trade.
io::Json movement_against_absorption(const MovementOptions& o, const io::Mesh& moved, const io::Mesh& truth,
                                     const metrics::SurfaceMovement& s) {
  const io::Material fit = io::read_material(o.material);
  const io::Material real = io::read_material(o.scene / "gt" / "material.json");
  Vec3f lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (const Vec3f& p : truth.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const float depth = float(o.depth) * std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  std::vector<Vec3f> normals(moved.positions.size(), Vec3f(0.0f));  // area-weighted
  for (const Vec3i& t : moved.triangles) {
    const Vec3f n = glm::cross(moved.positions[std::size_t(t.y)] - moved.positions[std::size_t(t.x)],
                               moved.positions[std::size_t(t.z)] - moved.positions[std::size_t(t.x)]);
    for (int k = 0; k < 3; ++k) normals[std::size_t(t[k])] += n;
  }
  std::vector<double> ratio(moved.positions.size());
  double mean_ratio = 0.0;
  for (std::size_t v = 0; v < ratio.size(); ++v) {
    const float len = glm::length(normals[v]);
    const Vec3f inside = moved.positions[v] - (len > 0.0f ? depth / len : 0.0f) * normals[v];
    const Vec3f f = material_sigma(fit, inside), t = material_sigma(real, inside);
    double r = 0.0;
    for (int c = 0; c < 3; ++c) r += std::log((double(f[c]) + 0.05) / (double(t[c]) + 0.05)) / 3.0;
    ratio[v] = r;
    mean_ratio += r / double(ratio.size());
  }
  double srr = 0.0, srm = 0.0, smm = 0.0;
  for (std::size_t v = 0; v < ratio.size(); ++v) {
    const double dr = ratio[v] - mean_ratio, dm = s.moved[v] - s.mean_moved;
    srr += dr * dr, srm += dr * dm, smm += dm * dm;
  }
  return {{"material", o.material.string()},
          {"depth", depth},
          {"mean_log_ratio", mean_ratio},
          {"rms_log_ratio", std::sqrt(srr / double(ratio.size()) + mean_ratio * mean_ratio)},
          {"correlation_with_moved", srr > 0.0 && smm > 0.0 ? srm / std::sqrt(srr * smm) : 0.0},
          {"moved_per_unit_log_ratio", srr > 0.0 ? srm / srr : 0.0}};
}

// The movement's figures over the vertices v with in(v): how many, their
// share, the mean and RMS signed distances before and after, the mean and
// RMS movement, the mean change of |distance| (> 0: worse than stage 1) and
// the gain of moved against −before within the group.
io::Json movement_group(const metrics::SurfaceMovement& s, const std::function<bool(std::size_t)>& in) {
  std::size_t n = 0;
  double b = 0.0, a = 0.0, bb = 0.0, aa = 0.0, m = 0.0, mm = 0.0, change = 0.0;
  double xx = 0.0, xy = 0.0, sx = 0.0, sy = 0.0;
  for (std::size_t v = 0; v < s.moved.size(); ++v) {
    if (!in(v)) continue;
    ++n;
    b += s.before[v], a += s.after[v];
    bb += s.before[v] * s.before[v], aa += s.after[v] * s.after[v];
    m += s.moved[v], mm += s.moved[v] * s.moved[v];
    change += std::abs(s.after[v]) - std::abs(s.before[v]);
    const double x = -s.before[v], y = s.moved[v];
    sx += x, sy += y, xx += x * x, xy += x * y;
  }
  const double k = std::max<double>(1.0, double(n));
  const double var = xx / k - (sx / k) * (sx / k);
  return {{"vertices", n},
          {"share", double(n) / std::max<double>(1.0, double(s.moved.size()))},
          {"mean_before", b / k},
          {"mean_after", a / k},
          {"rms_before", std::sqrt(bb / k)},
          {"rms_after", std::sqrt(aa / k)},
          {"mean_moved", m / k},
          {"rms_moved", std::sqrt(mm / k)},
          {"mean_change", change / k},
          {"gain", var > 0.0 ? (xy / k - (sx / k) * (sy / k)) / var : 0.0}};
}

// The movement split into o.bands equal slabs of the truth's extent along
// o.band_axis, each vertex of the moved mesh in the slab of its own
// coordinate (in the truth's unit box, as evaluate --bands): did stage 2
// move the part that held the error (a base no silhouette shows) toward
// the truth, or wander there?
io::Json movement_by_bands(const MovementOptions& o, const io::Mesh& moved, const io::Mesh& truth,
                           const metrics::SurfaceMovement& s) {
  const VertexSlabs bands = vertex_slabs(moved, truth, o.band_axis, o.bands);
  io::Json rows = io::Json::array();
  for (int b = 0; b < o.bands; ++b) {
    io::Json row = movement_group(s, [&](std::size_t v) { return bands.of_vertex[v] == b; });
    row["from"] = bands.slabs.lower(b);
    row["to"] = bands.slabs.upper(b);
    rows.push_back(row);
  }
  return {{"axis", o.band_axis}, {"bands", rows}};
}

// The movement split by how many training views' mask outlines pass within
// o.contour_band pixels of each vertex's stage-1 position (scene::contour_views;
// the reference's vertex when the two meshes share their vertices, else the
// moved mesh's own): is what the colour moved where the masks pinned stage 1
// (a trade against the material, or a correction the masks missed?) or where
// they left it free? One count per vertex of the moved mesh.
io::Json movement_by_contours(const MovementOptions& o, const io::Mesh& moved, const io::Mesh& reference,
                              const metrics::SurfaceMovement& s, std::vector<int>* counts) {
  cli::progress("movement: reading the masks of " + o.scene.string());
  const io::Scene scene = io::load_scene(o.scene);
  const cli::MaterialsViews training = cli::materials_training_views(scene);
  std::vector<scene::SilhouetteView> views;
  for (const pipeline::Stage2View& v : training.views) views.push_back({v.camera, v.mask});
  const io::Mesh& at = reference.positions.size() == moved.positions.size() ? reference : moved;
  *counts = scene::contour_views(io::flat_positions(at), views, float(o.contour_band));
  // four groups at the quartiles of the counts (with 50 views around the
  // object most points lie on several rims), and the histogram
  std::vector<int> sorted = *counts;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::size_t> histogram(std::size_t(sorted.empty() ? 0 : sorted.back() + 1), 0);
  for (int c : sorted) ++histogram[std::size_t(c)];
  struct Group {
    int lo, hi;  // views, inclusive
  };
  std::vector<Group> groups;
  for (int q = 0; q < 4 && !sorted.empty(); ++q) {
    const int lo = groups.empty() ? 0 : groups.back().hi + 1;
    const int hi = q == 3 ? sorted.back() : sorted[(sorted.size() - 1) * std::size_t(q + 1) / 4];
    if (hi >= lo) groups.push_back({lo, hi});
  }
  io::Json rows = io::Json::array();
  for (const Group& g : groups) {
    io::Json row = movement_group(s, [&](std::size_t v) { return (*counts)[v] >= g.lo && (*counts)[v] <= g.hi; });
    row["views"] = {g.lo, g.hi};
    rows.push_back(row);
  }
  return {{"band_pixels", o.contour_band}, {"views", views.size()}, {"histogram", histogram}, {"groups", rows}};
}

io::Json movement(const MovementOptions& o) {
  const fs::path gt = o.gt_mesh.empty() ? o.scene / "gt" / "mesh.obj" : o.gt_mesh;
  cli::progress("movement: reading " + o.mesh.string() + ", " + o.reference.string() + " and " + gt.string());
  const io::Mesh moved = io::read_mesh(o.mesh), reference = io::read_mesh(o.reference), truth = io::read_mesh(gt);
  const metrics::SurfaceMovement s = metrics::surface_movement(moved, reference, truth);
  io::Json out = {{"mesh", o.mesh.string()}, {"reference", o.reference.string()}, {"truth", gt.string()},
                  {"vertices", moved.positions.size()},
                  {"mean_before", s.mean_before}, {"mean_after", s.mean_after}, {"mean_moved", s.mean_moved},
                  {"rms_before", s.rms_before}, {"rms_after", s.rms_after}, {"rms_moved", s.rms_moved},
                  {"gain", s.gain}, {"offset", s.offset}, {"residual_rms", s.residual_rms},
                  {"correlation", s.correlation}, {"improved_fraction", s.improved_fraction},
                  {"worst_tenth_share", s.worst_tenth_share}};
  if (!o.other.empty()) {
    // Two fits from the same reference with other seeds: what they share is
    // what the data asks for (a correction, or a bias such as the trade with a
    // wrong material); what differs between them is the batches' noise.
    const io::Mesh other = io::read_mesh(o.other);
    if (other.positions.size() != moved.positions.size())
      throw std::runtime_error(o.other.string() + " has " + std::to_string(other.positions.size()) + " vertices, " +
                               o.mesh.string() + " " + std::to_string(moved.positions.size()) +
                               ": --other must be a refinement of the same mesh");
    const metrics::SurfaceMovement t = metrics::surface_movement(other, reference, truth);
    const auto residual = [](const metrics::SurfaceMovement& m, std::size_t v) {
      return m.moved[v] - (m.gain * -m.before[v] + m.offset);
    };
    double saa = 0.0, sbb = 0.0, sab = 0.0, raa = 0.0, rbb = 0.0, rab = 0.0, dd = 0.0;
    for (std::size_t v = 0; v < s.moved.size(); ++v) {
      const double a = s.moved[v] - s.mean_moved, b = t.moved[v] - t.mean_moved;
      saa += a * a, sbb += b * b, sab += a * b;
      const double ra = residual(s, v), rb = residual(t, v);
      raa += ra * ra, rbb += rb * rb, rab += ra * rb;
      dd += (s.moved[v] - t.moved[v]) * (s.moved[v] - t.moved[v]);
    }
    const auto corr = [](double xy, double xx, double yy) { return xx > 0.0 && yy > 0.0 ? xy / std::sqrt(xx * yy) : 0.0; };
    const double n = double(s.moved.size());
    out["repeat"] = {{"other", o.other.string()},
                     {"other_gain", t.gain}, {"other_offset", t.offset}, {"other_rms_after", t.rms_after},
                     {"correlation_moved", corr(sab, saa, sbb)},
                     {"correlation_residual", corr(rab, raa, rbb)},
                     // half the RMS difference of two independent runs: one run's noise
                     {"noise_rms", std::sqrt(dd / n) / std::sqrt(2.0)}};
  }
  if (!o.material.empty()) out["against_absorption"] = movement_against_absorption(o, moved, truth, s);
  std::vector<int> contours;
  if (o.contour_band > 0.0) out["by_contour_views"] = movement_by_contours(o, moved, reference, s, &contours);
  if (o.bands > 0) out["by_bands"] = movement_by_bands(o, moved, truth, s);
  if (!o.write_map.empty()) {
    const std::vector<float> positions = io::flat_positions(moved);
    const std::vector<std::int32_t> triangles = io::flat_triangles(moved);
    const auto write = [&](const std::string& name, const std::vector<double>& value) {
      std::vector<render::VertexColour> colours(value.size());
      for (std::size_t v = 0; v < value.size(); ++v) colours[v] = diverging(float(0.5 + 0.5 * value[v] / o.scale));
      const fs::path path = o.write_map.string() + "_" + name + ".png";
      io::write_png8(path, render::vertex_colour_sheet(positions, triangles, colours, 200, diverging));
      return path.string();
    };
    std::vector<double> change(s.after.size());
    for (std::size_t v = 0; v < change.size(); ++v) change[v] = std::abs(s.after[v]) - std::abs(s.before[v]);
    out["maps"] = {{"scale", o.scale},
                   {"moved", write("moved", s.moved)},
                   {"change", write("change", change)}};
    if (!contours.empty()) {  // blue: on the fewest outlines, red: on the most
      const auto [lo, hi] = std::minmax_element(contours.begin(), contours.end());
      const double mid = 0.5 * double(*lo + *hi), half = std::max(0.5, 0.5 * double(*hi - *lo));
      std::vector<double> pinned(contours.size());
      for (std::size_t v = 0; v < pinned.size(); ++v) pinned[v] = (double(contours[v]) - mid) / half * o.scale;
      out["maps"]["contours"] = write("contours", pinned);
    }
  }
  return out;
}

int main(int argc, char** argv) {
  CLI::App app{"stage2_diagnose: why stage 2's vertex refinement fails, in numbers (JSON on stdout)"};
  app.require_subcommand(1);
  CommonOptions common;
  GradcheckOptions gc;
  HomeOptions ho;
  IorOptions io_;
  std::string iors = "1.3,1.35,1.4,1.45,1.5,1.55,1.6,1.65", sigmas, check_steps, clip_ior = "0";
  std::string fields = "inflate,wave1,wave3", steps = "1e-3,3e-4,1e-4,3e-5", blurs = "0,2,8,32";

  CLI::App* g = app.add_subcommand("gradcheck", "AD against central differences of the stage-2 loss on one fixed batch");
  add_common(g, common);
  g->add_option("--fields", fields,
                "Displacement fields: inflate, wave1, wave3, home (towards the nearest points of the true mesh, "
                "SCENE/gt/mesh.obj)")
      ->capture_default_str();
  g->add_option("--steps", steps, "Central-difference steps (RMS vertex displacement)")->capture_default_str();
  g->add_option("--tolerance", gc.ray_tolerance,
                "A ray's FD agrees with its AD when |FD - AD| <= TOL (|AD| + 1e-3 RMS(AD))")->capture_default_str();
  g->add_option("--reverse-tolerance", gc.reverse_tolerance,
                "With --check: the bound on |reverse - forward| / sum over rays of |AD|")->capture_default_str();
  g->add_option("--min-agreeing", gc.min_agreeing, "With --check: the fraction of rays (path counts unchanged at every "
                "step) that must agree at some step")->capture_default_str();
  g->add_flag("--check", gc.check, "Exit status 1 when too few rays agree or reverse and forward mode differ");
  g->add_option("--explain", gc.explain,
                "Of the largest rays, the first N are compared branch by branch (origin, direction, weight, light: "
                "forward mode against central differences of the same branch)")
      ->capture_default_str()->check(CLI::Range(0, 8));
  g->add_option("--inject", gc.inject, "Differentiate a deliberately different renderer (flat-normals): the check must fail");

  CLI::App* h = app.add_subcommand("home", "Does −∇L point to the true surface? Cosines, noise, loss along Δ");
  add_common(h, common);
  h->add_option("--gt-mesh", ho.gt_mesh, "True mesh (default SCENE/gt/mesh.obj)");
  h->add_option("--blurs", blurs, "Environment blurs, Gaussian sigma in texels of the map")->capture_default_str();
  h->add_option("--batches", ho.batches, "Batches for the gradient statistics")->capture_default_str()->check(CLI::PositiveNumber);
  h->add_option("--loss-batches", ho.loss_batches, "Fixed batches averaged for the loss along Δ")->capture_default_str()
      ->check(CLI::PositiveNumber);
  h->add_option("--lambda", ho.lambda, "Large steps' lambda of the preconditioned components (default: stage 2's)")
      ->check(CLI::NonNegativeNumber);
  h->add_option("--t-max", ho.t_max, "Loss along x + tΔ for t in [0, T_MAX]")->capture_default_str();
  h->add_option("--t-step", ho.t_step, "Step of t")->capture_default_str()->check(CLI::PositiveNumber);
  h->add_option("--targets", ho.targets, "photo: the training pixels; ray: the true object traced along the same ray "
                                         "(depth 16, no pruning) under the same blurred environment")
      ->capture_default_str()->check(CLI::IsMember({"photo", "ray"}));
  h->add_option("--noise-blur", ho.noise_blur_index, "Index into --blurs whose gradient noise is split by class (-1: none)")
      ->capture_default_str();
  h->add_option("--write-projected", ho.write_projected, "Write the mesh moved to the true surface (x + Δ) as OBJ");
  h->add_option("--bands", ho.bands, "The mean clipped, preconditioned gradient against Δ in this many equal slabs of "
                                     "the truth's extent along --band-axis (0: none)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  h->add_option("--band-axis", ho.band_axis, "Axis of --bands")->capture_default_str()->check(CLI::IsMember({"x", "y", "z"}));

  CLI::App* r = app.add_subcommand("ior", "Where is the loss lowest in the IoR (and a grey absorption)?");
  add_common(r, common);
  r->add_option("--iors", iors, "IoR values of the scan")->capture_default_str();
  r->add_option("--sigmas", sigmas, "Grey homogeneous absorption values (per unit length) scanned with each IoR; "
                                    "default: the material's absorption");
  r->add_option("--check-steps", check_steps, "IoR steps of per-ray central differences on the first batch "
                                             "(against forward mode), e.g. 1e-3,1e-4")->capture_default_str();
  r->add_option("--clip-ior", clip_ior, "Per-ray clips of the IoR derivative for the gradient statistics (0: none)")
      ->capture_default_str();
  r->add_option("--loss-batches", io_.loss_batches, "Fixed batches averaged per point")->capture_default_str()
      ->check(CLI::PositiveNumber);
  r->add_option("--gradient-batches", io_.gradient_batches, "Batches of dL/dIoR at the material's IoR")
      ->capture_default_str()->check(CLI::PositiveNumber);
  int scan_samples = 1;
  r->add_option("--pixel-samples", scan_samples, "Rays per pixel, compared as the fit does (2: pixel pairs, whose "
                                                 "loss the samples' noise does not bias)")
      ->capture_default_str()->check(CLI::Range(1, 64));
  r->add_option("--glint", io_.glint, "Leave out of the scanned loss the pixels whose photograph or render is brighter "
                                      "than this times the batch's median photographed pixel (0: none)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);

  IorNoiseOptions no;
  CLI::App* nz = app.add_subcommand("ior-noise", "The fit's own IoR gradient split by pixel class (glints, "
                                                 "brightness): where its signal and its noise come from");
  add_common(nz, common);
  nz->add_option("--batches", no.batches, "Fixed batches per IoR")->capture_default_str()->check(CLI::Range(2, 100000));
  nz->add_option("--step", no.step, "The IoRs: the material's and ± STEP")->capture_default_str()
      ->check(CLI::Range(1e-6, 1.0));
  nz->add_option("--glint", no.glint, "Glint level: this times the batch's median photographed pixel")
      ->capture_default_str()->check(CLI::PositiveNumber);
  int noise_samples = 2;
  nz->add_option("--pixel-samples", noise_samples, "Rays per pixel, compared as the fit does (pairs)")
      ->capture_default_str()->check(CLI::Range(1, 64));

  MovementOptions mo;
  CLI::App* mv = app.add_subcommand("movement", "How --mesh moved from --reference (stage 1), against the true mesh: "
                                                "correction, offset or wandering");
  mv->add_option("scene", mo.scene, "Scene directory (its gt/mesh.obj is the truth)")->required();
  mv->add_option("--mesh", mo.mesh, "The refined mesh (e.g. a mesh_stage2.obj)")->required();
  mv->add_option("--reference", mo.reference, "The mesh it was refined from (e.g. mesh_stage1.obj)")->required();
  mv->add_option("--gt-mesh", mo.gt_mesh, "True mesh (default SCENE/gt/mesh.obj)");
  mv->add_option("--other", mo.other, "Another refinement of --reference (another seed): the correlation of the "
                                      "two movements, what repeats and what is noise");
  mv->add_option("--material", mo.material, "A fitted material (e.g. material_stage2.json): its σ against "
                                            "SCENE/gt/material.json under the surface, and the movement against it");
  mv->add_option("--depth", mo.depth, "With --material: how far under the surface σ is read (fraction of the "
                                      "truth's largest side)")->capture_default_str()->check(CLI::PositiveNumber);
  mv->add_option("--write-map", mo.write_map, "Write PREFIX_moved.png (signed movement, red outwards) and "
                                              "PREFIX_change.png (red: farther from the truth than stage 1)");
  mv->add_option("--contours", mo.contour_band, "Split the vertices by the number of training masks whose outline "
                                               "passes within this many pixels of the reference vertex (0: no split; "
                                               "with --write-map, PREFIX_contours.png)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  mv->add_option("--scale", mo.scale, "The maps' full colour, in the truth's unit box")->capture_default_str()
      ->check(CLI::PositiveNumber);
  mv->add_option("--bands", mo.bands, "Split the vertices into this many equal slabs of the truth's extent along "
                                      "--band-axis (0: no split)")
      ->capture_default_str()->check(CLI::Range(0, 1000));
  mv->add_option("--band-axis", mo.band_axis, "Axis of --bands")->capture_default_str()->check(CLI::IsMember({"x", "y", "z"}));

  EnvironmentOptions eo;
  CLI::App* e = app.add_subcommand("environment", "Where the object's light comes from (seen / unseen by the "
                                                   "background, upper / lower hemisphere), true map against --env");
  add_common(e, common);
  e->add_option("--truth", eo.truth, "True map (default SCENE/gt/envmap.hdr)");
  e->add_option("--batches", eo.batches, "Stage 2's batches traced")->capture_default_str()->check(CLI::PositiveNumber);
  e->add_option("--margin", eo.margin, "Pixels around the masks left out of the background (as the environment stage)")
      ->capture_default_str();
  e->add_option("--glint", eo.glint, "Pixels brighter than this times the batch's median photograph, in the photograph "
                                     "or a render, are left out (0: none)")->capture_default_str();
  e->add_option("--write-filled", eo.write_filled, "Write --env with the texels no background pixel sees taken from the "
                                                   "true map (.hdr)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (mv->parsed()) {  // meshes only: no scene set-up
      io::Json result;
      result["movement"] = movement(mo);
      std::cout << result.dump(2) << std::endl;
      return 0;
    }
    if (nz->parsed()) common.pixel_samples = noise_samples;
    if (r->parsed()) common.pixel_samples = scan_samples;
    Setup setup(common);
    io::Json result;
    result["scene"] = common.scene.string();
    result["mesh"] = common.mesh.string();
    result["environment"] = setup.environment().description();
    result["ior"] = setup.material().ior;
    result["settings"] = {{"rays", common.rays}, {"views", common.views}, {"depth", common.depth},
                          {"prune", common.prune}, {"seed", common.seed}, {"iteration", common.iteration},
                          {"colour_loss", pipeline::detail::enum_name(common.colour_loss)},
                          {"threads", ThreadPool::global().size()}};
    bool passed = true;
    if (g->parsed()) {
      gc.fields.clear();
      std::stringstream ss(fields);
      for (std::string f; std::getline(ss, f, ',');)
        if (!f.empty()) gc.fields.push_back(f);
      gc.steps = parse_numbers(steps, "--steps");
      result["gradcheck"] = gradcheck(setup, gc, passed);
    } else if (r->parsed()) {
      io_.iors = parse_numbers(iors, "--iors");
      if (!sigmas.empty()) io_.sigmas = parse_numbers(sigmas, "--sigmas");
      io_.clip_ior = parse_numbers(clip_ior, "--clip-ior");
      if (!check_steps.empty()) io_.check_steps = parse_numbers(check_steps, "--check-steps");
      result["ior_scan"] = ior_scan(setup, io_);
    } else if (nz->parsed()) {
      result["ior_noise"] = ior_noise(setup, no);
    } else if (e->parsed()) {
      result["environment_sources"] = environment_sources(setup, eo);
    } else {
      ho.blurs = parse_numbers(blurs, "--blurs");
      result["home"] = home(setup, ho);
    }
    std::cout << result.dump(2) << std::endl;
    if (!passed) {
      std::cerr << "stage2_diagnose: AD and finite differences disagree (--check)" << std::endl;
      return 1;
    }
  } catch (const CLI::Error& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "stage2_diagnose: " << e.what() << std::endl;
    return 2;
  }
  return 0;
}
