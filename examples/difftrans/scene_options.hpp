// Options of the subcommands that load a scene directory: where the object
// masks come from (--masks, --mask-dir, --mask-level, --mask-threshold,
// --mask-below; reconstruct and info), and the exposure of LDR photographs
// (--exposure, --exposure-env; reconstruct), estimated against a known
// environment or given, divided out of the images and recorded.
#pragma once

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "command.hpp"

#include "difftrans/io/dataset.hpp"
#include "difftrans/io/image_file.hpp"
#include "pipeline/exposure.hpp"

namespace difftrans::cli {

struct MaskCliOptions {
  std::string source = "auto";
  std::string dir;
  int level = 127;
  std::optional<double> threshold;
  bool below = false;
};

inline void add_mask_options(CLI::App* cmd, MaskCliOptions& o) {
  cmd->add_option("--masks", o.source,
                  "Where object masks come from: auto (mask files, else the image's alpha channel), files, alpha, "
                  "threshold (--mask-threshold), none")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "files", "alpha", "threshold", "none"}));
  cmd->add_option("--mask-dir", o.dir, "Masks NAME.png from this folder instead of the scene's (implies --masks files)");
  cmd->add_option("--mask-level", o.level, "Mask files and alpha: 8-bit values above this are object")
      ->capture_default_str()
      ->check(CLI::Range(0, 254));
  cmd->add_option("--mask-threshold", o.threshold,
                  "Masks from the image: object where its brightest channel's sRGB value (0..1) is above this "
                  "(implies --masks threshold)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--mask-below", o.below, "With --mask-threshold: object where the image is darker (a bright backdrop)");
}

// The loader's mask options from the command line; contradictory choices are a ValidationError.
inline io::MaskOptions mask_options(const MaskCliOptions& o) {
  io::MaskOptions m;
  const std::string source = o.source;
  if (source == "files") m.source = io::MaskSource::files;
  else if (source == "alpha") m.source = io::MaskSource::alpha;
  else if (source == "threshold") m.source = io::MaskSource::threshold;
  else if (source == "none") m.source = io::MaskSource::none;
  if (!o.dir.empty()) {
    if (m.source != io::MaskSource::automatic && m.source != io::MaskSource::files)
      throw CLI::ValidationError("--mask-dir", "takes masks from files, but --masks says " + source);
    std::error_code ec;
    if (!std::filesystem::is_directory(o.dir, ec)) throw io::Error(o.dir, "mask folder not found (--mask-dir)");
    m.source = io::MaskSource::files;
    m.dir = o.dir;
  }
  if (o.threshold) {
    if (m.source != io::MaskSource::automatic && m.source != io::MaskSource::threshold)
      throw CLI::ValidationError("--mask-threshold", "makes masks from the image, but --masks says " + source);
    if (!(*o.threshold > 0.0 && *o.threshold < 1.0))
      throw CLI::ValidationError("--mask-threshold", "must lie strictly between 0 and 1");
    m.source = io::MaskSource::threshold;
    m.threshold = *o.threshold;
  } else if (m.source == io::MaskSource::threshold) {
    throw CLI::ValidationError("--masks", "threshold needs --mask-threshold T");
  }
  if (o.below && m.source != io::MaskSource::threshold)
    throw CLI::ValidationError("--mask-below", "goes with --mask-threshold");
  m.below = o.below;
  m.level = o.level;
  return m;
}

inline io::Json describe(const io::MaskOptions& m) {
  io::Json j = io::Json::object();
  j["source"] = io::to_string(m.source);
  if (!m.dir.empty()) j["dir"] = m.dir.string();
  if (m.source == io::MaskSource::threshold) {
    j["threshold"] = m.threshold;
    j["object"] = m.below ? "below" : "above";
  } else if (m.source != io::MaskSource::none) {
    j["level"] = m.level;
  }
  return j;
}

struct ExposureCliOptions {
  std::string exposure = "auto";  // auto | estimate | none | a positive number
  std::string env;                // the environment to estimate against (default: the scene's gt/envmap.hdr)
};

inline void add_exposure_options(CLI::App* cmd, ExposureCliOptions& o) {
  cmd->add_option("--exposure", o.exposure,
                  "Exposure of the images (image = exposure x radiance), divided out before reconstruction: a number, "
                  "estimate (from the background against --exposure-env), none, or auto (estimate for 8-bit "
                  "images when an environment is known and the scene is distant, else none)")
      ->capture_default_str();
  cmd->add_option("--exposure-env", o.env,
                  "Environment map (.hdr/.exr, equirectangular) the exposure is estimated against (default: the "
                  "scene's gt/envmap.hdr)");
}

// Whether the scene's images are 8-bit (PNG/JPEG photographs) rather than radiance (EXR/HDR).
inline bool low_dynamic_range(const io::Scene& scene) {
  for (const io::Split* s : {&scene.train, &scene.test})
    for (const io::Frame& f : s->frames) {
      const std::string ext = io::detail::lower_extension(f.image_path);
      if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") return true;
    }
  return false;
}

// Settles the exposure (--exposure), divides it out of the scene's images
// and returns its record for reconstruct.json.
inline io::Json apply_exposure_option(io::Scene& scene, const ExposureCliOptions& o) {
  io::Json j = io::Json::object();
  double scale = 1.0;
  std::string mode = o.exposure;
  if (mode != "auto" && mode != "estimate" && mode != "none") {
    char* end = nullptr;
    scale = std::strtod(mode.c_str(), &end);
    if (mode.empty() || *end != '\0' || !(scale > 0.0) || !std::isfinite(scale))
      throw CLI::ValidationError("--exposure", "'" + mode + "' is neither auto, estimate, none nor a positive number");
    j["source"] = "given";
  } else if (mode == "none") {
    j["source"] = "none";
  } else {
    const std::filesystem::path env_file = !o.env.empty() ? std::filesystem::path(o.env) : scene.gt.envmap;
    std::string reason;
    if (env_file.empty()) reason = "no environment to estimate it against (no --exposure-env, no gt/envmap.hdr)";
    else if (mode == "auto" && scene.settings.environment == io::EnvironmentKind::near && o.env.empty())
      reason = "a near-field scene: the reference panorama is seen from the object's centre, not from the cameras";
    else if (mode == "auto" && !low_dynamic_range(scene))
      reason = "the images are radiance (EXR/HDR), not 8-bit photographs";
    if (!reason.empty()) {
      if (mode == "estimate") throw CLI::ValidationError("--exposure", "estimate: " + reason);
      j["source"] = "none";
      j["reason"] = reason;
    } else {
      const io::Image map = io::read_image(env_file);
      const scene::EnvMap env = scene::equirect_environment(map.rgb.data(), map.width, map.height);
      const pipeline::ExposureEstimate e = pipeline::estimate_exposure(scene.train, env);
      if (!(e.pixels > 0))
        throw io::Error(scene.dir, "cannot estimate the exposure: no background pixel is both unclipped and bright "
                                   "enough (" + std::to_string(e.clipped) + " clipped, " + std::to_string(e.dark) +
                                       " too dark); give --exposure X");
      scale = e.scale;
      j["source"] = "estimated";
      j["environment"] = env_file.string();
      j["pixels"] = e.pixels;
      j["clipped"] = e.clipped;
      j["dark"] = e.dark;
      j["quartiles"] = {e.q25, e.q75};
    }
  }
  j["scale"] = scale;
  if (scale != 1.0) {
    pipeline::apply_exposure(scene.train, scale);
    pipeline::apply_exposure(scene.test, scale);
  }
  return j;
}

}  // namespace difftrans::cli
