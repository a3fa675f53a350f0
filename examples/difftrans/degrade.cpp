// difftrans degrade SCENE --out DIR: turns a synthesized scene directory into
// a capture-like one — 8-bit sRGB PNG images (clamped), another exposure,
// noisy poses (as a COLMAP binary model, or in transforms_train.json), masks
// eroded or dilated or with random blobs flipped, optionally carried in the images' alpha channel — with
// gt/ and scene.json copied so that the metrics still work. The held-out test
// views keep their exact poses (they are for evaluation); their images and
// masks are degraded like the training views'. degrade.json records what was
// done.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "output_folder.hpp"
#include "views.hpp"

namespace difftrans::cli {
namespace {

struct DegradeOptions {
  fs::path scene, out;
  bool png8 = false;
  double exposure = 1.0;
  double pose_noise_deg = 0.0;
  std::optional<double> pose_noise_trans;
  bool colmap_binary = false;
  int erode = 0, dilate = 0;
  int blobs = 0;             // discs flipped in each mask
  double blob_radius = 3.0;  // their radius in pixels
  bool mask_alpha = false;
  std::uint64_t seed = 1;
  bool overwrite = false;
};

constexpr double pi = 3.14159265358979323846;

// A unit vector uniformly on the sphere.
Vec3d random_direction(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  for (;;) {
    const Vec3d v(n(rng), n(rng), n(rng));
    const double l = glm::length(v);
    if (l > 1e-9) return v / l;
  }
}

// Rotation by `angle` radians about the unit `axis` (Rodrigues).
Mat3<double> rotation(const Vec3d& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  const double x = axis.x, y = axis.y, z = axis.z;
  Mat3<double> r;  // column-major: r[column][row]
  r[0] = Vec3d(t * x * x + c, t * x * y + s * z, t * x * z - s * y);
  r[1] = Vec3d(t * x * y - s * z, t * y * y + c, t * y * z + s * x);
  r[2] = Vec3d(t * x * z + s * y, t * y * z - s * x, t * z * z + c);
  return r;
}

// What happened to the poses, for degrade.json.
struct PoseNoise {
  double angle_deg = 0.0;
  double translation_mean = 0.0, translation_max = 0.0;
  std::string translation_rule;
};

// Turns each training camera by the angle about a random axis through its
// centre and moves the centre by the translation in a random direction: the
// given --pose-noise-trans, else the displacement the same angle sweeps at the
// camera's distance from the scene's centre (scene.json's aabb centre, else
// the origin).
PoseNoise perturb_poses(io::Split& split, const DegradeOptions& o, const Vec3d& centre, std::mt19937_64& rng) {
  PoseNoise noise;
  noise.angle_deg = o.pose_noise_deg;
  noise.translation_rule = o.pose_noise_trans ? "given (--pose-noise-trans)"
                                              : "matching: angle (radians) x the camera's distance from the scene centre";
  const double angle = o.pose_noise_deg * pi / 180.0;
  for (io::Frame& f : split.frames) {
    const Mat3<double> q = rotation(random_direction(rng), angle);
    const Vec3d c = f.position();
    const double t = o.pose_noise_trans ? *o.pose_noise_trans : angle * glm::length(c - centre);
    const Vec3d moved = c + t * random_direction(rng);
    const Mat3<double> r = q * Mat3<double>(f.camera_to_world);
    for (int k = 0; k < 3; ++k) f.camera_to_world[k] = glm::dvec4(r[k], 0.0);
    f.camera_to_world[3] = glm::dvec4(moved, 1.0);
    noise.translation_mean += t / double(split.frames.size());
    noise.translation_max = std::max(noise.translation_max, t);
  }
  return noise;
}

// `count` discs of `radius` pixels, centred uniformly at random in the
// mask's bounding box grown by the radius (the whole image for an empty
// mask): where a segmentation goes wrong, near the object's outline.
std::vector<io::Disc> random_blobs(const io::Mask& m, int count, double radius, std::mt19937_64& rng) {
  int x0 = m.width, y0 = m.height, x1 = -1, y1 = -1;
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x)
      if (m.at(x, y)) x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
  if (x1 < 0) x0 = 0, y0 = 0, x1 = m.width - 1, y1 = m.height - 1;
  std::uniform_real_distribution<double> ux(x0 - radius, x1 + 1 + radius), uy(y0 - radius, y1 + 1 + radius);
  std::vector<io::Disc> discs;
  for (int i = 0; i < count; ++i) discs.push_back({float(ux(rng)), float(uy(rng)), float(radius)});
  return discs;
}

// Writes a frame's degraded image and mask into dir, updating its paths.
void write_frame(io::Frame& f, const fs::path& dir, const DegradeOptions& o, std::mt19937_64& rng) {
  if (o.exposure != 1.0)
    for (float& v : f.image.rgb) v *= float(o.exposure);
  io::Mask mask;
  if (f.has_mask() && f.mask.width > 0) mask = io::morph_mask(f.mask, o.dilate > 0 ? o.dilate : -o.erode);
  if (o.blobs > 0 && mask.width > 0) mask = io::flip_discs(mask, random_blobs(mask, o.blobs, o.blob_radius, rng));
  const fs::path image = dir / "images" / (f.name + (o.png8 ? ".png" : linear_extension));
  if (o.mask_alpha) {  // RGBA PNG: the mask in the alpha channel (opaque where there is none)
    const auto rgb = io::tone_map(f.image);
    io::Image8 out{f.image.width, f.image.height, 4, std::vector<std::uint8_t>(f.image.pixel_count() * 4)};
    for (std::size_t p = 0; p < f.image.pixel_count(); ++p) {
      for (int c = 0; c < 3; ++c) out.data[p * 4 + std::size_t(c)] = rgb[p * 3 + std::size_t(c)];
      out.data[p * 4 + 3] = mask.width == 0 || mask.inside[p] ? 255 : 0;
    }
    io::write_png8(image, out);
    f.mask_path.clear();
  } else {
    io::write_image(image, f.image);  // .png: exposure 1, clamped, sRGB, 8 bits
    if (mask.width > 0) {
      f.mask_path = dir / "masks" / (f.name + ".png");
      io::write_mask(f.mask_path, mask);
    } else {
      f.mask_path.clear();
    }
  }
  f.image_path = image;
}

void run(const DegradeOptions& o) {
  if (o.mask_alpha && !o.png8) throw CLI::ValidationError("--mask-alpha", "needs --png8 (the alpha channel of a PNG)");
  progress("degrade: loading " + o.scene.string());
  io::Scene scene = io::load_scene(o.scene);
  for (const auto& w : scene.warnings) warn(w);
  OutputDir out(o.out, o.overwrite, {o.scene});
  const fs::path dir = out.path();
  fs::create_directories(dir / "images");
  if (!o.mask_alpha) fs::create_directories(dir / "masks");
  std::mt19937_64 rng(o.seed);

  const Vec3d centre = scene.settings.aabb ? 0.5 * (scene.settings.aabb->lo + scene.settings.aabb->hi) : Vec3d(0.0);
  std::optional<PoseNoise> noise;
  if (o.pose_noise_deg > 0.0 || (o.pose_noise_trans && *o.pose_noise_trans > 0.0))
    noise = perturb_poses(scene.train, o, centre, rng);
  for (io::Split* split : {&scene.train, &scene.test})
    for (io::Frame& f : split->frames) write_frame(f, dir, o, rng);
  if (o.colmap_binary) {
    for (const auto& f : scene.train.frames)
      if (f.environment_only)
        warn("degrade: " + f.name + " is environment_only, which a COLMAP model cannot say; it becomes an ordinary view");
    io::write_colmap_binary(dir / "sparse" / "0", scene.train, dir / "images");
  } else {
    io::write_transforms(dir / "transforms_train.json", scene.train);
  }
  if (!scene.test.frames.empty()) io::write_transforms(dir / "transforms_test.json", scene.test);
  if (scene.has_scene_json) io::write_scene_settings(dir / "scene.json", scene.settings);
  if (scene.gt.present) fs::copy(o.scene / "gt", dir / "gt", fs::copy_options::recursive);

  io::Json j = io::Json::object();
  j["source"] = o.scene.string();
  j["images"] = o.png8 ? "8-bit sRGB PNG (clamped at 1)" : "linear OpenEXR";
  j["exposure"] = o.exposure;
  j["poses"] = o.colmap_binary ? "COLMAP binary model in sparse/0 (training views); test views in transforms_test.json"
                               : "transforms_train.json";
  if (noise) {
    j["pose_noise"] = {{"rotation_degrees", noise->angle_deg},
                       {"rotation_axis", "random, uniform on the sphere, through the camera centre"},
                       {"translation", noise->translation_rule},
                       {"translation_mean", noise->translation_mean},
                       {"translation_max", noise->translation_max},
                       {"scene_centre", {centre.x, centre.y, centre.z}},
                       {"views", "training views only; test views keep their exact poses"}};
  }
  j["masks"] = o.mask_alpha ? "alpha channel of the images" : "masks/NAME.png";
  j["mask_morphology"] = o.erode ? "eroded by " + std::to_string(o.erode) + " px"
                         : o.dilate ? "dilated by " + std::to_string(o.dilate) + " px"
                                    : std::string("none");
  if (o.blobs > 0)
    j["mask_blobs"] = {{"per_mask", o.blobs}, {"radius_px", o.blob_radius},
                       {"placement", "centres uniform in the mask's bounding box grown by the radius; pixels within flipped"}};
  j["seed"] = o.seed;
  j["views"] = {{"train", scene.train.frames.size()}, {"test", scene.test.frames.size()}};
  io::write_json(dir / "degrade.json", j);
  out.commit();
  progress("degrade: wrote " + out.final_path().string());
  std::cout << j.dump(2) << std::endl;
}

}  // namespace

void add_degrade(CLI::App& app) {
  auto o = std::make_shared<DegradeOptions>();
  CLI::App* cmd = app.add_subcommand("degrade", "Turn a synthesized scene into a capture-like one (8-bit images, "
                                                "exposure, pose noise, COLMAP binary poses, imperfect masks)");
  cmd->footer(
      "Writes DIR/images/NAME.png (--png8: 8-bit sRGB, clamped) or .exr, DIR/masks/NAME.png (or the images' alpha\n"
      "channel with --mask-alpha), the poses as DIR/sparse/0/{cameras,images,points3D}.bin (--colmap-binary; the\n"
      "test views stay in transforms_test.json) or transforms_*.json, scene.json, gt/ (copied) and degrade.json.\n"
      "Pose noise (training views only): each camera turned by exactly --pose-noise-deg about a random axis through\n"
      "its centre, and its centre moved in a random direction by --pose-noise-trans, or by default by the matching\n"
      "displacement: the angle in radians times the camera's distance from the scene centre (scene.json's aabb\n"
      "centre, else the origin) -- what the same angle sweeps at that distance.\n"
      "Example: difftrans degrade scenes/spot --out scenes/spot-phone --png8 --colmap-binary --pose-noise-deg 0.3");
  cmd->add_option("scene", o->scene, "Scene directory to degrade (e.g. from difftrans synth)")->required();
  cmd->add_option("--out", o->out, "Scene directory to write")->required();
  cmd->add_flag("--overwrite", o->overwrite, "replace an existing, non-empty --out");
  cmd->add_flag("--png8", o->png8, "write 8-bit sRGB PNG images (clamped at 1) instead of linear EXR");
  cmd->add_option("--exposure", o->exposure, "multiply the radiance by this before writing")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  auto* deg = cmd->add_option("--pose-noise-deg", o->pose_noise_deg, "rotate each training camera by this many degrees")
                  ->check(CLI::Range(0.0, 180.0));
  cmd->add_option("--pose-noise-trans", o->pose_noise_trans,
                  "move each training camera's centre by this distance (default: the matching displacement)")
      ->check(CLI::Range(0.0, 1e6))
      ->needs(deg);
  cmd->add_flag("--colmap-binary", o->colmap_binary, "write the training poses as a COLMAP binary model (sparse/0)");
  auto* erode = cmd->add_option("--mask-erode", o->erode, "erode the masks by N pixels (Euclidean disk)")
                    ->check(CLI::Range(0, 1000));
  auto* dilate = cmd->add_option("--mask-dilate", o->dilate, "dilate the masks by N pixels (Euclidean disk)")
                     ->check(CLI::Range(0, 1000));
  erode->excludes(dilate);
  cmd->add_option("--mask-blobs", o->blobs, "flip N random discs of each mask (inside <-> outside), near the object")
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--mask-blob-radius", o->blob_radius, "radius of those discs in pixels")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 1e4));
  cmd->add_flag("--mask-alpha", o->mask_alpha, "carry the masks in the PNG images' alpha channel (needs --png8)");
  cmd->add_option("--seed", o->seed, "seed of the pose noise and the mask blobs")->capture_default_str();
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
