// difftrans evaluate: the metrics of docs/metrics.md as one JSON object on stdout
// (and in --out): geometry (chamfer, f1, precision, recall) of a predicted
// mesh against the ground truth and the predicted mesh's quality, images (psnr, psnr_mask, ssim per image and
// mean) of a folder of predictions against a folder of ground truth, IoR error.
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "command.hpp"
#include "difftrans/io/dataset.hpp"
#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/io/ply.hpp"
#include "difftrans/metrics/metrics.hpp"
#include "difftrans/render/mesh_picture.hpp"
#include "stage_output.hpp"

namespace difftrans::cli {
namespace {

namespace fs = std::filesystem;

struct EvaluateOptions {
  std::string pred, gt;
  std::string pred_images, gt_images, masks;
  std::string scene, split = "test";
  std::size_t samples = metrics::GeometryOptions{}.samples;
  std::uint64_t seed = metrics::GeometryOptions{}.seed;
  double tau = metrics::GeometryOptions{}.tau;
  std::optional<double> pred_ior, gt_ior;
  std::optional<fs::path> out;
  std::string error_map;
  std::optional<double> error_scale;
  int bands = 0;
  std::string band_axis = "y";
};

// The images of a folder by name (stem); a name in several formats keeps the
// first of io::image_extensions() (linear formats before PNG).
std::map<std::string, fs::path> images_in(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw io::Error(dir, fs::exists(dir, ec) ? "is not a directory" : "directory not found");
  const auto& exts = io::image_extensions();
  const auto rank = [&](const fs::path& p) {
    return std::find(exts.begin(), exts.end(), io::detail::lower_extension(p)) - exts.begin();
  };
  std::map<std::string, fs::path> found;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file() || rank(entry.path()) == std::ptrdiff_t(exts.size())) continue;
    auto& slot = found[entry.path().stem().string()];
    if (slot.empty() || rank(entry.path()) < rank(slot)) slot = entry.path();
  }
  return found;
}

// The predicted mesh with each vertex coloured by its distance to the true
// surface (io::heat_color of distance / scale), as a PLY that mesh viewers
// open; the distances' quantiles go in the JSON.
void write_error_map(const EvaluateOptions& o, const io::Mesh& pred, const io::Mesh& gt,
                     const metrics::GeometryOptions& options, io::Json& result) {
  progress("evaluate: the error map (distance of each of the " + std::to_string(pred.positions.size()) +
           " predicted vertices to the true surface)");
  const std::vector<double> d = metrics::vertex_distances(pred, gt, options);
  const double scale = o.error_scale.value_or(o.tau);
  std::vector<std::array<std::uint8_t, 3>> colours(d.size());
  for (std::size_t v = 0; v < d.size(); ++v) colours[v] = io::heat_color(float(d[v] / scale));
  io::write_ply(o.error_map, pred, false, nullptr, &colours);
  // the same colours as a picture: the mesh from the front, the right, the
  // back, the left (first row), above and below, and the scale (a bar from 0
  // at the bottom to `scale` and beyond at the top)
  const fs::path picture = fs::path(o.error_map).replace_extension(".png");
  io::write_png8(picture, render::vertex_colour_sheet(io::flat_positions(pred), io::flat_triangles(pred), colours, 200,
                                                      io::heat_color));
  std::vector<double> sorted = d;
  std::sort(sorted.begin(), sorted.end());
  const auto quantile = [&](double q) {
    return sorted.empty() ? 0.0 : sorted[std::min(sorted.size() - 1, std::size_t(q * double(sorted.size())))];
  };
  double sum = 0.0, above = 0.0;
  for (double x : d) sum += x, above += x > o.tau;
  const double n = double(std::max<std::size_t>(1, d.size()));
  result["error_map"] = {{"file", o.error_map},
                         {"picture", picture.string()},
                         {"scale", scale},
                         {"vertices", d.size()},
                         {"mean", sum / n},
                         {"p50", quantile(0.5)},
                         {"p90", quantile(0.9)},
                         {"p99", quantile(0.99)},
                         {"max", sorted.empty() ? 0.0 : sorted.back()},
                         {"fraction_above_tau", above / n}};
}

// --bands: the chamfer split into slabs of the truth's extent along
// --band-axis (metrics::chamfer_bands), lowest first, each with its share.
void write_chamfer_bands(const EvaluateOptions& o, const metrics::MatchedPoints& matched, io::Json& result) {
  progress("evaluate: the chamfer in " + std::to_string(o.bands) + " bands along " + o.band_axis);
  const metrics::ChamferBands b = metrics::chamfer_bands(
      matched, metrics::slabs_over(matched.truth, metrics::axis_index(o.band_axis), o.bands));
  double total = 0.0;
  for (int i = 0; i < o.bands; ++i) total += b.predicted[std::size_t(i)] + b.truth[std::size_t(i)];
  io::Json list = io::Json::array();
  for (int i = 0; i < o.bands; ++i) {
    const double part = b.predicted[std::size_t(i)] + b.truth[std::size_t(i)];
    list.push_back({{"from", b.slabs.lower(i)},
                    {"to", b.slabs.upper(i)},
                    {"chamfer", part},
                    {"predicted_to_truth", b.predicted[std::size_t(i)]},
                    {"truth_to_predicted", b.truth[std::size_t(i)]},
                    {"share", total > 0.0 ? part / total : 0.0}});
  }
  result["chamfer_bands"] = {{"axis", o.band_axis}, {"bands", list}};
}

void evaluate_geometry(const EvaluateOptions& o, io::Json& result) {
  std::vector<std::string> warnings;
  progress("evaluate: reading " + o.pred + " and " + o.gt);
  const io::Mesh pred = io::read_mesh(o.pred, &warnings);
  const io::Mesh gt = io::read_mesh(o.gt, &warnings);
  for (const auto& w : warnings) warn(w);
  metrics::GeometryOptions options;
  options.samples = o.samples;
  options.seed = o.seed;
  options.tau = o.tau;
  progress("evaluate: sampling " + std::to_string(o.samples) + " points per mesh, nearest neighbours");
  const metrics::MatchedPoints matched = metrics::match_samples(pred, gt, options);
  const metrics::GeometryMetrics m = metrics::compare_matched(matched, options.tau);
  result["chamfer"] = m.chamfer;
  result["f1"] = m.f1;
  result["precision"] = m.precision;
  result["recall"] = m.recall;
  result["tau"] = m.tau;
  result["normal_error_deg"] = normal_error_json(metrics::normal_error(pred, gt, options));
  result["samples"] = m.samples;
  result["seed"] = o.seed;
  result["mesh_warnings"] = warnings;
  // the predicted mesh's own quality: speckle (dihedral angles), self-intersections, topology
  result["pred_mesh_quality"] = mesh_quality_json(metrics::mesh_quality(io::flat_positions(pred), io::flat_triangles(pred)));
  if (!o.error_map.empty()) write_error_map(o, pred, gt, options, result);
  if (o.bands > 0) write_chamfer_bands(o, matched, result);
}

// Ground truth from a scene directory's split: images and masks by frame name.
struct SceneTruth {
  std::map<std::string, fs::path> images, masks;
};

SceneTruth scene_truth(const EvaluateOptions& o) {
  io::LoadOptions lo;
  lo.read_pixels = false;
  const io::Scene scene = io::load_scene(o.scene, lo);
  for (const auto& w : scene.warnings) warn(w);
  const io::Split& split = o.split == "train" ? scene.train : scene.test;
  if (split.frames.empty()) throw io::Error(o.scene, "the scene has no " + o.split + " views");
  SceneTruth t;
  for (const auto& f : split.frames) {
    if (f.environment_only) continue;
    t.images[f.name] = f.image_path;
    if (!f.mask_path.empty()) t.masks[f.name] = f.mask_path;
  }
  return t;
}

void evaluate_images(const EvaluateOptions& o, io::Json& result) {
  const bool from_scene = !o.scene.empty();
  const SceneTruth truth = from_scene ? scene_truth(o) : SceneTruth{};
  const auto gt = from_scene ? truth.images : images_in(o.gt_images);
  const auto pred = images_in(o.pred_images);
  if (gt.empty()) throw io::Error(from_scene ? o.scene : o.gt_images, "no images (.exr, .hdr, .png, .jpg) in this directory");
  io::Json per_image = io::Json::array();
  double sum_psnr = 0.0, sum_mask = 0.0, sum_ssim = 0.0;
  std::size_t n = 0, n_mask = 0;
  for (const auto& [name, gt_path] : gt) {
    const auto p = pred.find(name);
    if (p == pred.end()) throw io::Error(fs::path(o.pred_images) / name, "no predicted image for " + gt_path.string());
    progress("evaluate: image " + std::to_string(n + 1) + "/" + std::to_string(gt.size()) + " " + name);
    const io::Image a = io::read_image(p->second), b = io::read_image(gt_path);
    if (a.width != b.width || a.height != b.height)
      throw io::Error(p->second, "image is " + std::to_string(a.width) + " x " + std::to_string(a.height) +
                                     " but the ground truth " + gt_path.string() + " is " + std::to_string(b.width) +
                                     " x " + std::to_string(b.height));
    std::unique_ptr<io::Mask> mask;
    const bool scene_mask = from_scene && truth.masks.count(name);
    if (!o.masks.empty() || scene_mask) {
      const fs::path mask_path = scene_mask ? truth.masks.at(name) : fs::path(o.masks) / (name + ".png");
      mask = std::make_unique<io::Mask>(io::read_mask(mask_path));
      if (mask->width != b.width || mask->height != b.height)
        throw io::Error(mask_path, "mask is " + std::to_string(mask->width) + " x " + std::to_string(mask->height) +
                                       " but its image " + gt_path.string() + " is " + std::to_string(b.width) + " x " +
                                       std::to_string(b.height));
    }
    const auto m = metrics::evaluate_image(a, b, mask.get());
    io::Json entry = {{"name", name}, {"psnr", m.psnr}, {"ssim", m.ssim}};
    if (mask) {
      entry["psnr_mask"] = m.psnr_mask;
      if (std::isnan(m.psnr_mask)) warn(name + ": the mask is empty; psnr_mask is null");
      else sum_mask += m.psnr_mask, ++n_mask;
    }
    per_image.push_back(entry);
    sum_psnr += m.psnr;
    sum_ssim += m.ssim;
    ++n;
  }
  for (const auto& [name, path] : pred)
    if (!gt.count(name)) warn(path.string() + ": no ground-truth image of that name; not evaluated");
  // Means of the per-image values; an infinite PSNR (identical images) makes the mean infinite (null).
  result["psnr"] = sum_psnr / double(n);
  result["ssim"] = sum_ssim / double(n);
  if (!o.masks.empty() || !truth.masks.empty()) result["psnr_mask"] = n_mask ? sum_mask / double(n_mask) : std::nan("");
  result["count"] = n;
  result["images"] = per_image;
}

void run(const EvaluateOptions& o) {
  const bool geometry = !o.pred.empty() || !o.gt.empty();
  const bool images = !o.pred_images.empty() || !o.gt_images.empty() || !o.scene.empty();
  if (!o.scene.empty() && !o.gt_images.empty()) throw CLI::ValidationError("--scene and --gt-images exclude each other");
  if (!o.scene.empty() && o.pred_images.empty()) throw CLI::ValidationError("--scene needs --pred-images");
  const bool ior = o.pred_ior || o.gt_ior;
  if (geometry && (o.pred.empty() || o.gt.empty())) throw CLI::ValidationError("--pred and --gt go together");
  if (images && o.scene.empty() && (o.pred_images.empty() || o.gt_images.empty()))
    throw CLI::ValidationError("--pred-images and --gt-images go together");
  if (!o.masks.empty() && !images) throw CLI::ValidationError("--masks needs --pred-images and --gt-images");
  if (ior && !(o.pred_ior && o.gt_ior)) throw CLI::ValidationError("--pred-ior and --gt-ior go together");
  if ((!o.error_map.empty() || o.error_scale) && !geometry)
    throw CLI::ValidationError("--error-map and --error-scale need --pred and --gt");
  if (!o.error_map.empty() && io::detail::lower_extension(o.error_map) != ".ply")
    throw CLI::ValidationError("--error-map writes a PLY file (vertex colours): name it .ply, not " + o.error_map);
  if (o.bands > 0 && !geometry) throw CLI::ValidationError("--bands needs --pred and --gt");
  if (!geometry && !images && !ior)
    throw CLI::ValidationError("nothing to evaluate: give --pred/--gt, --pred-images/--gt-images or --pred-ior/--gt-ior");
  io::Json result = io::Json::object();
  if (geometry) evaluate_geometry(o, result);
  if (images) evaluate_images(o, result);
  if (ior) result["ior_error"] = metrics::ior_error(*o.pred_ior, *o.gt_ior);
  emit_json(result, o.out);
}

}  // namespace

void add_evaluate(CLI::App& app) {
  auto o = std::make_shared<EvaluateOptions>();
  CLI::App* cmd = app.add_subcommand("evaluate", "Compute the metrics of docs/metrics.md; print them as one JSON object");
  cmd->footer(
      "Geometry: difftrans evaluate --pred MESH --gt MESH\n"
      "  both meshes normalized with the ground truth's unit box; chamfer = mean d^2 both ways, f1 at --tau.\n"
      "Images:   difftrans evaluate --pred-images DIR --gt-images DIR [--masks DIR]\n"
      "  images paired by name (any of .exr .hdr .png), tone-mapped to 8 bits; masks are DIR/NAME.png.\n"
      "Images of a scene: difftrans evaluate --pred-images OUT/images --scene SCENE_DIR [--split test]\n"
      "  ground truth and masks from the scene's transforms_test.json (or _train), paired by frame name.\n"
      "Infinite values (identical images) are written as null.\n"
      "Error map: difftrans evaluate --pred MESH --gt MESH --error-map ERR.ply\n"
      "  where the prediction is wrong, as vertex colours (and ERR.png, a picture of them); the distances' quantiles\n"
      "  in the JSON (error_map).\n"
      "Where the error lies: difftrans evaluate --pred MESH --gt MESH --bands 5 [--band-axis y]\n"
      "  the chamfer split into slabs of the truth's height (chamfer_bands: each slab's part and share).");
  cmd->add_option("--pred", o->pred, "predicted mesh (.obj or .ply)");
  cmd->add_option("--gt", o->gt, "ground-truth mesh (.obj or .ply)");
  cmd->add_option("--samples", o->samples, "points sampled per mesh")->capture_default_str()->check(CLI::PositiveNumber);
  cmd->add_option("--seed", o->seed, "sampling seed")->capture_default_str();
  cmd->add_option("--tau", o->tau, "F1 distance threshold (normalized units)")->capture_default_str()->check(CLI::PositiveNumber);
  cmd->add_option("--pred-images", o->pred_images, "folder of predicted images");
  cmd->add_option("--gt-images", o->gt_images, "folder of ground-truth images");
  cmd->add_option("--masks", o->masks, "folder of object masks NAME.png (adds psnr_mask)");
  cmd->add_option("--scene", o->scene, "instead of --gt-images: a scene directory's images and masks (by frame name)");
  cmd->add_option("--split", o->split, "--scene's views")->capture_default_str()->check(CLI::IsMember({"train", "test"}));
  cmd->add_option("--pred-ior", o->pred_ior, "predicted index of refraction (adds ior_error)");
  cmd->add_option("--gt-ior", o->gt_ior, "true index of refraction");
  cmd->add_option("--out", o->out, "also write the JSON to this file");
  cmd->add_option("--error-map", o->error_map,
                  "with --pred/--gt: write the predicted mesh as PLY, each vertex coloured by its distance to the true "
                  "surface (black at 0, through purple and red, to pale yellow at --error-scale), and beside it "
                  "ERR.png: the same colours seen from six sides, and the scale");
  cmd->add_option("--error-scale", o->error_scale, "distance drawn pale yellow in --error-map (default: --tau)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--bands", o->bands,
                  "with --pred/--gt: split the chamfer into this many equal slabs of the truth's extent along "
                  "--band-axis, each point counted in its slab (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  cmd->add_option("--band-axis", o->band_axis, "axis of --bands")->capture_default_str()->check(CLI::IsMember({"x", "y", "z"}));
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
