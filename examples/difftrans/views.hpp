// Shared pieces of synth, render and relight: option parsing (colours,
// environments, materials, --device), rendering a list of views to files with progress,
// comparing renders with ground truth (metrics JSON, contact sheet), and
// writing an output folder so that a failure leaves nothing half-written.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "command.hpp"
#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/dataset.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/io/radiance_field.hpp"
#include "difftrans/metrics/image.hpp"
#include "difftrans/render/footprint.hpp"
#include "difftrans/render/views.hpp"
#include "difftrans/scene/room.hpp"
#include "gpu/gpu_views.hpp"

#ifndef DIFFTRANS_DEFAULT_DATA_DIR
#define DIFFTRANS_DEFAULT_DATA_DIR "data"
#endif

namespace difftrans::cli {

namespace fs = std::filesystem;

// Linear images are written as OpenEXR (32-bit float, lossless); PNG previews
// are tone-mapped as docs/conventions.md says.
inline constexpr const char* linear_extension = ".exr";

// The data folder (meshes/, envmaps/; data/README.md): --data, else
// $DIFFTRANS_DATA, else the data/ of the source tree this command was built
// from, else the installed copy (PREFIX/share/difftrans/data beside
// PREFIX/bin/difftrans).
inline fs::path data_dir(const std::string& option) {
  if (!option.empty()) return option;
  if (const char* env = std::getenv("DIFFTRANS_DATA"); env && *env) return env;
  const fs::path built_from = DIFFTRANS_DEFAULT_DATA_DIR;
  if (fs::is_directory(built_from)) return built_from;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "difftrans" / "data";
    if (fs::is_directory(installed)) return installed;
  }
  return built_from;
}

// "R,G,B" (three finite numbers) or throws CLI::ValidationError naming the option.
inline Vec3f parse_rgb(const std::string& text, const std::string& option, bool non_negative = true) {
  std::stringstream ss(text);
  std::string part;
  std::vector<double> v;
  while (std::getline(ss, part, ',')) {
    char* end = nullptr;
    const double x = std::strtod(part.c_str(), &end);
    if (part.empty() || end == part.c_str() || *end != '\0' || !std::isfinite(x))
      throw CLI::ValidationError(option, "'" + text + "' is not three numbers R,G,B");
    v.push_back(x);
  }
  if (v.size() != 3) throw CLI::ValidationError(option, "'" + text + "' is not three numbers R,G,B");
  if (non_negative && (v[0] < 0 || v[1] < 0 || v[2] < 0))
    throw CLI::ValidationError(option, "'" + text + "' has a negative value");
  return Vec3f(float(v[0]), float(v[1]), float(v[2]));
}

// --env: an equirectangular map (.hdr, .exr or .png, +Y up), constant:R,G,B,
// a near-field radiance field (its .json file, as `reconstruct --env-model
// near` writes it), or the output folder of `reconstruct` (its
// radiance_field.json when there is one, else its envmap.hdr).
struct Environment {
  std::string spec;       // as given
  fs::path file;          // empty for a constant
  Vec3f constant{1.0f};
  io::Image map;          // the loaded map (empty for a constant or a field)
  std::shared_ptr<const scene::RadianceField> field;  // a near-field environment
  std::string description() const {
    if (file.empty()) return "constant " + std::to_string(constant.x) + "," + std::to_string(constant.y) + "," +
                             std::to_string(constant.z);
    return (field ? "radiance field " : "map ") + file.string();
  }
  std::string name() const {
    if (file.empty()) return "constant";
    return field ? file.parent_path().filename().string() + "_" + file.stem().string() : file.stem().string();
  }
};

// The distant map a reconstruction folder holds: stage 2's (envmap_stage2.hdr,
// its unseen sky scaled by the fitted factor) when it wrote one, else the
// environment stage's envmap.hdr (which may be absent).
inline fs::path recovered_map(const fs::path& dir) {
  std::error_code ec;
  const fs::path stage2 = dir / "envmap_stage2.hdr";
  return fs::is_regular_file(stage2, ec) ? stage2 : dir / "envmap.hdr";
}

inline Environment load_environment(const std::string& spec) {
  Environment e;
  e.spec = spec;
  const std::string prefix = "constant:";
  if (spec.compare(0, prefix.size(), prefix) == 0) {
    e.constant = parse_rgb(spec.substr(prefix.size()), "--env");
    return e;
  }
  e.file = spec;
  std::error_code ec;
  if (fs::is_directory(e.file, ec)) {  // a reconstruction folder
    const fs::path field = e.file / "radiance_field.json", map = recovered_map(e.file);
    if (fs::exists(field, ec)) e.file = field;
    else if (fs::exists(map, ec)) e.file = map;
    else throw io::Error(spec, "holds none of radiance_field.json, envmap_stage2.hdr, envmap.hdr (the environments "
                               "reconstruct writes)");
  }
  if (io::detail::lower_extension(e.file) == ".json") {
    e.field = std::make_shared<const scene::RadianceField>(io::read_radiance_field(e.file));
    return e;
  }
  e.map = io::read_image(e.file);
  if (e.map.width < 2 || e.map.height < 1) throw io::Error(e.file, "environment map is too small");
  return e;
}

inline void apply_environment(render::HostScene& s, const Environment& e) {
  s.set_near_field(e.field);  // null for a map or a constant: the distant environment is used
  if (e.field) return;
  if (e.file.empty()) s.set_constant_environment(e.constant);
  else render::set_environment(s, e.map);
}

// The environment as an image for gt/: the map itself, or a small constant one.
inline io::Image environment_image(const Environment& e) {
  if (e.field)
    throw io::Error(e.file, "is a radiance field: a synthetic scene's environment is a map or constant:R,G,B "
                            "(synth --room makes a near-field scene)");
  if (!e.file.empty()) return e.map;
  io::Image im(16, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) im.set(x, y, e.constant);
  return im;
}

// Material options shared by render and relight: --material FILE, or --ior
// with --absorption R,G,B or --absorption-grid FILE.
struct MaterialOptions {
  std::string material_file;
  std::optional<double> ior;
  std::string absorption;
  std::string absorption_grid;

  void add(CLI::App* cmd) {
    cmd->add_option("--material", material_file, "material.json (ior and absorption), e.g. SCENE/gt/material.json");
    cmd->add_option("--ior", ior, "index of refraction (overrides --material's)")->check(CLI::Range(1.0, 4.0));
    cmd->add_option("--absorption", absorption, "homogeneous absorption sigma_a R,G,B per unit length");
    cmd->add_option("--absorption-grid", absorption_grid, "absorption grid file (format in README: scene directories)");
  }

  io::Material resolve() const {
    if (!absorption.empty() && !absorption_grid.empty())
      throw CLI::ValidationError("--absorption and --absorption-grid exclude each other");
    if (material_file.empty() && !ior) throw CLI::ValidationError("give --ior or --material");
    io::Material m = material_file.empty() ? io::Material{} : io::read_material(material_file);
    if (ior) m.ior = *ior;
    if (!absorption.empty()) {
      m.absorption = io::AbsorptionType::homogeneous;
      m.sigma = parse_rgb(absorption, "--absorption");
    }
    if (!absorption_grid.empty()) {
      m.absorption = io::AbsorptionType::grid;
      m.grid = io::read_absorption_grid(absorption_grid);
      m.grid_file = fs::path(absorption_grid).filename().string();
    }
    return m;
  }
};

// Reads a mesh, printing its warnings.
inline io::Mesh load_mesh(const fs::path& path) {
  std::vector<std::string> warnings;
  io::Mesh mesh = io::read_mesh(path, &warnings);
  for (const auto& w : warnings) warn(w);
  if (mesh.triangles.empty()) throw io::Error(path, "mesh has no triangles");
  return mesh;
}

// One view to render: its name, camera, the frame it came from (for
// transforms JSON) and, when known, its ground-truth image and mask.
struct View {
  std::string name;
  scene::Camera camera;
  io::Frame frame;  // intrinsics and camera_to_world; paths empty
  fs::path truth_image, truth_mask;
};

inline View view_from_frame(const io::Frame& f) {
  View v;
  v.name = f.name;
  const auto& k = f.intrinsics;
  v.camera = render::camera_from(f.camera_to_world, k.fx, k.fy, k.cx, k.cy, k.width, k.height);
  v.frame = f;
  v.frame.image = {};
  v.frame.mask = {};
  v.truth_image = f.image_path;
  v.truth_mask = f.mask_path;
  return v;
}

// A benchmark view (docs/benchmark-scenes.md camera) in direction `dir`; the camera is built
// from the frame, exactly as a reader of the transforms JSON will build it.
inline View protocol_view(const std::string& name, const Vec3f& dir, int width, int height) {
  const scene::Camera c = scene::protocol_camera(dir, width, height);
  io::Frame f;
  f.name = name;
  f.intrinsics = io::Intrinsics::from_fov_y(width, height, double(scene::protocol_camera_fov_y));
  f.camera_to_world = Mat4<double>(c.camera_to_world);
  View v;
  v.name = name;
  v.camera = render::camera_from(f.camera_to_world, f.intrinsics.fx, f.intrinsics.fy, f.intrinsics.cx,
                                 f.intrinsics.cy, width, height);
  v.frame = f;
  return v;
}

// Seconds as "12.3 s" or "4 min 05 s".
inline std::string duration_text(double s) {
  char b[64];
  if (s < 100.0) std::snprintf(b, sizeof(b), "%.1f s", s);
  else std::snprintf(b, sizeof(b), "%d min %02d s", int(s) / 60, int(s) % 60);
  return b;
}

// Progress of n items on stderr: "LABEL: 12/70 NAME, 3.2 s elapsed, ~15.1 s left".
class Progress {
 public:
  Progress(std::string label, std::size_t total) : label_(std::move(label)), total_(total), start_(clock::now()) {}
  void done(std::size_t count, const std::string& what) const {
    const double t = elapsed();
    std::string line = label_ + ": " + std::to_string(count) + "/" + std::to_string(total_) + " " + what + ", " +
                       duration_text(t) + " elapsed";
    if (count < total_ && count > 0) line += ", ~" + duration_text(t / double(count) * double(total_ - count)) + " left";
    progress(line);
  }
  double elapsed() const { return std::chrono::duration<double>(clock::now() - start_).count(); }

 private:
  using clock = std::chrono::steady_clock;
  std::string label_;
  std::size_t total_;
  clock::time_point start_;
};

// The work of render_views: camera rays, ray segments traced, and the seconds
// spent tracing (image writing and masks left out).
struct RenderTotals {
  std::int64_t rays = 0, segments = 0;
  double trace_seconds = 0.0;
  io::Json json(std::size_t views) const {
    return {{"camera_rays", rays}, {"segments", segments}, {"seconds", trace_seconds},
            {"seconds_per_view", views ? trace_seconds / double(views) : 0.0}};
  }
};

// --device: where render and relight trace their views.
inline constexpr const char* device_help =
    "where to trace: cpu (the host's threads), cuda (the GPU; fails at once without one) or auto (the GPU when there "
    "is one)";

// --device cuda on a build or machine without a usable GPU: fails at once.
inline void check_device(const std::string& device) {
  if (device != "cuda") return;
  const std::string why = gpu_unavailable_reason();
  if (!why.empty()) throw std::runtime_error("--device cuda: " + why);
}

// The GPU tracer of `s` that --device asks for, or none (trace on the host).
// cuda fails at once, saying why, when there is no usable GPU or the scene
// is one the GPU does not trace (a near field, a room); auto falls back to
// the host and says so.
inline std::unique_ptr<GpuViewTracer> gpu_tracer_for(const std::string& device, const render::HostScene& s,
                                                     const std::string& label, bool room = false) {
  if (device == "cpu") return nullptr;
  std::string why = gpu_unavailable_reason();
  if (why.empty() && (s.near_field || room)) why = "a near-field environment or a room is traced on the host only";
  if (!why.empty()) {
    if (device == "cuda") throw std::runtime_error("--device cuda: " + why);
    progress(label + ": tracing on the host (" + why + ")");
    return nullptr;
  }
  progress(label + ": tracing on the GPU");
  return std::make_unique<GpuViewTracer>(s);
}

// gpu_tracer_for for a scene whose materials or environment change between
// calls (relight): the tracer in `keep` is made once and updated after, its
// BVH kept. Near-field environments are traced on the host (cuda fails).
inline GpuViewTracer* gpu_tracer_kept(std::unique_ptr<GpuViewTracer>& keep, const std::string& device,
                                      const render::HostScene& s, const std::string& label) {
  if (device == "cpu") return nullptr;
  if (!keep || s.near_field) {
    std::unique_ptr<GpuViewTracer> made = gpu_tracer_for(device, s, label);
    if (!made) return nullptr;
    keep = std::move(made);
    return keep.get();
  }
  keep->update(s);
  return keep.get();
}

// The GPU training pass of stage 2 that --device asks for, or none (the
// host's): as gpu_tracer_for.
inline std::unique_ptr<GpuBatchTracer> gpu_batch_tracer_for(const std::string& device, const render::HostScene& s,
                                                            const std::string& label) {
  if (device == "cpu") return nullptr;
  std::string why = gpu_unavailable_reason();
  if (why.empty() && s.near_field) why = "a near-field environment is traced on the host only";
  if (!why.empty()) {
    if (device == "cuda") throw std::runtime_error("--device cuda: " + why);
    progress(label + ": training rays on the host (" + why + ")");
    return nullptr;
  }
  progress(label + ": training rays on the GPU");
  return std::make_unique<GpuBatchTracer>();
}

// What was rendered for one view.
struct Rendered {
  View view;
  io::Image image;
  io::Mask mask;
};

// Renders every view; writes DIR/images/NAME.exr, DIR/previews/NAME.png and
// (write_masks) DIR/masks/NAME.png, filling each view's frame paths.
// A room (synth --room), when given, is what rays leaving the object see.
// `totals`, when given, receives the work done. `gpu`, when given, traces
// the images (gpu_tracer_for; the masks stay on the host). `footprints`,
// when given (and no room, no GPU), renders with ray footprints
// (render::render_image_footprints).
inline std::vector<Rendered> render_views(const render::HostScene& s, std::vector<View> views,
                                          const render::PassOptions& options, const fs::path& dir, bool write_masks,
                                          const std::string& label, const scene::Room* room = nullptr,
                                          RenderTotals* totals = nullptr, GpuViewTracer* gpu = nullptr,
                                          const render::FootprintSettings* footprints = nullptr) {
  fs::create_directories(dir / "images");
  fs::create_directories(dir / "previews");
  if (write_masks) fs::create_directories(dir / "masks");
  Progress bar(label, views.size());
  std::vector<Rendered> out;
  out.reserve(views.size());
  std::int64_t rays = 0, segments = 0;
  double trace_seconds = 0.0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    Rendered r;
    r.view = std::move(views[i]);
    render::PassStats st;
    const auto t0 = std::chrono::steady_clock::now();
    if (gpu && !room) {
      GpuViewStats g;
      r.image = io::Image(r.view.camera.width, r.view.camera.height);
      r.image.rgb = gpu->render(r.view.camera, options, &g);
      st.rays = g.rays;
      st.trace.segments = std::int32_t(g.segments);
    } else if (footprints && !room) {
      r.image = io::Image(r.view.camera.width, r.view.camera.height);
      r.image.rgb = render::render_image_footprints(s, r.view.camera, options, *footprints, &st);
    } else {
      r.image = room ? render::render_view_with(s, r.view.camera, options, render::fixed_escape(*room), &st)
                     : render::render_view(s, r.view.camera, options, &st);
    }
    trace_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rays += st.rays;
    segments += st.trace.segments;
    r.mask = render::object_mask(s, r.view.camera);
    r.view.frame.image_path = dir / "images" / (r.view.name + linear_extension);
    io::write_image(r.view.frame.image_path, r.image);
    io::write_png(dir / "previews" / (r.view.name + ".png"), r.image);
    if (write_masks) {
      r.view.frame.mask_path = dir / "masks" / (r.view.name + ".png");
      io::write_mask(r.view.frame.mask_path, r.mask);
    }
    r.view.frame.name = r.view.name;
    bar.done(i + 1, r.view.name);
    out.push_back(std::move(r));
  }
  if (rays > 0)
    progress(label + ": " + std::to_string(rays) + " camera rays, " + std::to_string(segments) + " ray segments (" +
             std::to_string(double(segments) / double(rays)).substr(0, 5) + " per camera ray) in " +
             duration_text(bar.elapsed()));
  if (totals) *totals = RenderTotals{rays, segments, trace_seconds};
  return out;
}

inline io::Split split_of(const std::vector<Rendered>& rendered) {
  io::Split s;
  for (const auto& r : rendered) s.frames.push_back(r.view.frame);
  return s;
}

// Metrics of renders against ground-truth images (the views' truth_image and
// truth_mask, or `truth` renders when given, in the same order), and a contact
// sheet of up to `sheet_rows` views. Returns the JSON (the keys of difftrans
// evaluate); writes DIR/metrics.json and DIR/contact_sheet.png.
inline io::Json compare_with_truth(const std::vector<Rendered>& renders, const std::vector<Rendered>* truth,
                                   const fs::path& dir, int sheet_rows = 4) {
  io::Json per = io::Json::array();
  double sum_psnr = 0, sum_mask = 0, sum_ssim = 0;
  std::size_t n = 0, n_mask = 0;
  std::vector<io::Image> truth_images;
  for (std::size_t i = 0; i < renders.size(); ++i) {
    const Rendered& r = renders[i];
    io::Image gt;
    io::Mask mask;
    bool has_mask = false;
    if (truth) {
      gt = (*truth)[i].image;
      mask = (*truth)[i].mask;
      has_mask = true;
    } else {
      gt = io::read_image(r.view.truth_image);
      if (gt.width != r.image.width || gt.height != r.image.height)
        throw io::Error(r.view.truth_image, "image is " + std::to_string(gt.width) + " x " + std::to_string(gt.height) +
                                                " but its camera renders " + std::to_string(r.image.width) + " x " +
                                                std::to_string(r.image.height));
      if (!r.view.truth_mask.empty()) {
        mask = io::read_mask(r.view.truth_mask);
        has_mask = mask.width == gt.width && mask.height == gt.height;
        if (!has_mask) warn(r.view.truth_mask.string() + ": mask size differs from its image; psnr_mask left out");
      }
    }
    const auto m = metrics::evaluate_image(r.image, gt, has_mask ? &mask : nullptr);
    io::Json e = {{"name", r.view.name}, {"psnr", m.psnr}, {"ssim", m.ssim}};
    if (has_mask && !std::isnan(m.psnr_mask)) {
      e["psnr_mask"] = m.psnr_mask;
      sum_mask += m.psnr_mask;
      ++n_mask;
    }
    per.push_back(e);
    sum_psnr += m.psnr;
    sum_ssim += m.ssim;
    ++n;
    truth_images.push_back(std::move(gt));
  }
  io::Json result = io::Json::object();
  result["psnr"] = n ? sum_psnr / double(n) : std::nan("");
  result["psnr_mask"] = n_mask ? sum_mask / double(n_mask) : std::nan("");
  result["ssim"] = n ? sum_ssim / double(n) : std::nan("");
  result["count"] = n;
  result["images"] = per;
  if (n > 0) {
    std::vector<io::SheetRow> rows;
    for (int i : io::spread_indices(int(n), sheet_rows)) rows.push_back({&truth_images[size_t(i)], &renders[size_t(i)].image});
    io::write_png8(dir / "contact_sheet.png", io::comparison_sheet(rows));
    result["contact_sheet"] = "contact_sheet.png";  // relative to the output folder
  }
  io::write_json(dir / "metrics.json", result);
  return result;
}

}  // namespace difftrans::cli
