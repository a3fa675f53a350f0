// A scene owned on the host — mesh, IoR, absorption, environment and the
// host accelerator (Embree, or the portable BVH in a build without it) — with the parameter buffers (values, gradients, tangents) that
// the generic tracer reads its unknowns from. Examples and tests build one
// and hand view() / params() to the passes in render/passes.hpp.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#if DIFFTRANS_HAVE_EMBREE
#include "difftrans/accel/embree.hpp"
#else
#include "difftrans/accel/bvh.hpp"
#endif
#include "difftrans/ad/params.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/radiance_field.hpp"

namespace difftrans::render {

// The closest-hit accelerator of host scenes. The host-tracing target
// (difftrans::host_tracing) defines DIFFTRANS_HAVE_EMBREE=1 when Embree was
// found; otherwise the portable BVH answers the same query (same RayHit, a
// watertight test, its own tree), so every pass runs unchanged on either.
#if DIFFTRANS_HAVE_EMBREE
using HostAccel = accel::EmbreeScene;
#else
using HostAccel = accel::Bvh;
#endif

// Parameter buffer ids of a scene.
enum ParamId : int {
  param_positions = 0,    // 3 per vertex
  param_ior = 1,          // 1
  param_absorption = 2,   // raw absorption parameters (sigma = softplus(raw))
  param_environment = 3,  // RGB texels
  param_normals = 4,      // vertex normals, derived from the positions (two-level normals)
  param_count = 5,
};

// How stage 2's training pass caps each group's gradient before adding it
// (the clip classes of ad::ParamReader::scatter_clipped, on the host and on
// the device): the vertices (positions and normals together) at L2 norm
// `geometry`, the IoR at `ior` in magnitude; 0: no cap.
struct GroupClip {
  std::int8_t classes[ad::max_param_buffers] = {};
  float caps[2] = {0.0f, 0.0f};
};

inline GroupClip vertex_and_ior_clip(float geometry, float ior) {
  GroupClip c;
  c.classes[param_positions] = c.classes[param_normals] = 1;
  c.classes[param_ior] = 2;
  c.caps[0] = geometry;
  c.caps[1] = ior;
  return c;
}

// The softplus table (scene::AbsorptionField::softplus_table) of a scene's raw
// absorption, made again whenever the raw values differ from those it was
// made from: the optimizers step absorption_raw in place, so a table kept
// up to date by hand would be one forgotten call away from a stale sigma.
// The comparison costs a pass over the raw values per view; the table saves
// a softplus (a log1p and an exp) at every grid corner a sample reads. A
// mutex guards views taken from several threads at once.
class SoftplusTableCache {
 public:
  SoftplusTableCache() = default;
  SoftplusTableCache(SoftplusTableCache&& other) noexcept {
    const std::lock_guard<std::mutex> lock(other.mutex_);
    raw_ = std::move(other.raw_);
    table_ = std::move(other.table_);
  }
  SoftplusTableCache& operator=(SoftplusTableCache&& other) noexcept {
    if (this != &other) {
      const std::scoped_lock lock(mutex_, other.mutex_);
      raw_ = std::move(other.raw_);
      table_ = std::move(other.table_);
    }
    return *this;
  }

  // The table of `raw` (2 floats per value), valid until the next call with
  // other values.
  const float* table(const std::vector<float>& raw) const {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (table_.size() != 2 * raw.size() || raw_ != raw) {
      raw_ = raw;
      table_.resize(2 * raw.size());
      scene::fill_softplus_table(raw.data(), raw.size(), table_.data());
    }
    return table_.data();
  }

 private:
  mutable std::mutex mutex_;
  mutable std::vector<float> raw_, table_;
};

class HostScene {
 public:
  scene::TriangleMesh mesh;
  float ior = 1.5f;
  // absorption: kind, raw parameters (3 for homogeneous, res³·3 for a grid) and the grid box
  scene::AbsorptionKind absorption_kind = scene::AbsorptionKind::none;
  std::vector<float> absorption_raw;
  Vec3i absorption_res{2, 2, 2};
  Vec3f absorption_lo{-0.5f}, absorption_hi{0.5f};
  // environment: a constant colour (3 values) or width x height RGB texels
  std::vector<float> environment{1.0f, 1.0f, 1.0f};
  int environment_width = 0, environment_height = 0;  // 0: constant
  // A near-field environment: when set, rays that leave the object read this
  // radiance field at their origin and direction instead of the distant map
  // (the host passes choose the escape once per pass). It is held fixed: no
  // gradients flow into it (see render::FixedEscape). Host passes only.
  std::shared_ptr<const scene::RadianceField> near_field;
  // which unknowns carry derivatives (read through the reader) in AD passes
  bool differentiate[param_count] = {true, true, true, true, true};
  // Vertex normals as leaves of their own whose gradient is folded into the
  // positions once per pass (fast), rather than one-rings recomputed per hit.
  bool two_level_normals = true;

  HostScene() = default;
  HostScene(std::vector<float> positions, std::vector<std::int32_t> triangles, std::string name = "mesh")
      : mesh(std::move(positions), std::move(triangles)), name_(std::move(name)) {
    rebuild_accel();
  }

  // Call after changing mesh.positions (same topology): normals and BVH.
  void positions_changed() {
    mesh.update_normals();
    if (accel_ && accel_->vertex_count() == mesh.num_vertices() &&
        accel_->triangle_count() == mesh.num_triangles())
      accel_->update_positions(mesh.positions.data());
    else
      rebuild_accel();
  }
  void rebuild_accel() {
    accel_ = std::make_unique<HostAccel>(mesh.positions.data(), mesh.num_vertices(), mesh.triangles.data(),
                                         mesh.num_triangles(), name_);
  }

  void set_homogeneous_absorption(const Vec3f& sigma) {
    absorption_kind = scene::AbsorptionKind::homogeneous;
    absorption_raw = {scene::raw_from_sigma(sigma.x), scene::raw_from_sigma(sigma.y), scene::raw_from_sigma(sigma.z)};
  }
  void set_grid_absorption(const Vec3i& res, const Vec3f& lo, const Vec3f& hi, std::vector<float> raw) {
    absorption_kind = scene::AbsorptionKind::grid;
    absorption_res = res;
    absorption_lo = lo;
    absorption_hi = hi;
    absorption_raw = std::move(raw);
  }
  void set_constant_environment(const Vec3f& rgb) {
    environment = {rgb.x, rgb.y, rgb.z};
    environment_width = environment_height = 0;
  }
  void set_environment_map(std::vector<float> texels, int width, int height) {
    environment = std::move(texels);
    environment_width = width;
    environment_height = height;
  }

  void set_near_field(std::shared_ptr<const scene::RadianceField> field) { near_field = std::move(field); }

  const HostAccel& accel() const { return *accel_; }

  // Calls f(escape) with the escape the tracer should use for this scene:
  // FixedEscape over the near field when one is set, else DistantEscape.
  template <class F>
  void with_escape(F&& f) const {
    if (near_field) f(fixed_escape(scene::FieldRadiance{near_field->view()}));
    else f(DistantEscape{});
  }

  // The view for the generic tracer. ad = true: the unknowns marked in
  // `differentiate` are read through the pass's reader. reverse = true (a
  // reverse-mode pass that calls SceneGradient::fold_normals afterwards):
  // vertex normals are leaves of their own when two_level_normals is set.
  SceneView view(bool ad, bool reverse = false) const {
    const auto buffer = [&](ParamId id) { return ad && differentiate[id] ? int(id) : -1; };
    SceneView v;
    const bool normals_ad = reverse && two_level_normals && buffer(param_positions) >= 0;
    v.mesh = mesh.view(buffer(param_positions), normals_ad ? int(param_normals) : -1);
    v.ior = ad::ParamSource{&ior, 1, buffer(param_ior)};
    switch (absorption_kind) {
      case scene::AbsorptionKind::none: v.absorption = scene::no_absorption(); break;
      case scene::AbsorptionKind::homogeneous:
        v.absorption = scene::homogeneous_absorption(absorption_raw.data(), buffer(param_absorption));
        break;
      case scene::AbsorptionKind::grid:
        v.absorption = scene::grid_absorption(absorption_raw.data(), absorption_res, absorption_lo, absorption_hi,
                                              buffer(param_absorption));
        break;
    }
    if (v.absorption.kind != scene::AbsorptionKind::none && !absorption_raw.empty())
      v.absorption.softplus_table = softplus_table_.table(absorption_raw);
    v.environment = environment_width > 0
                        ? scene::equirect_environment(environment.data(), environment_width, environment_height,
                                                      buffer(param_environment))
                        : scene::constant_environment(environment.data(), buffer(param_environment));
    return v;
  }

  // Values of every parameter buffer, without gradient or tangent arrays.
  ad::ParamSet params() const {
    ad::ParamSet set;
    set.buffers[param_positions].values = mesh.positions.data();
    set.buffers[param_positions].size = std::int32_t(mesh.positions.size());
    set.buffers[param_ior].values = &ior;
    set.buffers[param_ior].size = 1;
    set.buffers[param_absorption].values = absorption_raw.data();
    set.buffers[param_absorption].size = std::int32_t(absorption_raw.size());
    set.buffers[param_environment].values = environment.data();
    set.buffers[param_environment].size = std::int32_t(environment.size());
    set.buffers[param_normals].values = mesh.vertex_normals.data();
    set.buffers[param_normals].size = std::int32_t(mesh.vertex_normals.size());
    return set;
  }

 private:
  std::string name_ = "mesh";
  std::unique_ptr<HostAccel> accel_;
  SoftplusTableCache softplus_table_;
};

// Gradient arrays for every parameter of a scene, sized to match.
struct SceneGradient {
  std::vector<float> positions, ior, absorption, environment;
  std::vector<float> normals;  // intermediate: folded into positions by fold_normals

  explicit SceneGradient(const HostScene& s)
      : positions(s.mesh.positions.size(), 0.0f), ior(1, 0.0f), absorption(s.absorption_raw.size(), 0.0f),
        environment(s.environment.size(), 0.0f), normals(s.mesh.positions.size(), 0.0f) {}

  // Moves the gradient w.r.t. the vertex normals into the positions (the
  // second level of two-level normals). Called by the passes after a sweep.
  void fold_normals(const HostScene& s) {
    bool any = false;
    for (float g : normals) any = any || g != 0.0f;
    if (!any) return;
    s.mesh.normals_backward(normals.data(), positions.data());
    std::fill(normals.begin(), normals.end(), 0.0f);
  }

  // Points the buffers of `set` at these arrays.
  void attach(ad::ParamSet& set) {
    set.buffers[param_positions].gradient = positions.data();
    set.buffers[param_ior].gradient = ior.data();
    set.buffers[param_absorption].gradient = absorption.data();
    set.buffers[param_environment].gradient = environment.data();
    set.buffers[param_normals].gradient = normals.data();
  }
};

}  // namespace difftrans::render
