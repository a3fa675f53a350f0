// A COLMAP model directory as a split of frames: the model's format (binary
// cameras.bin + images.bin preferred, as COLMAP does, else text) and the
// loader that pairs its images with the photographs. Pinhole intrinsics only
// (images with lens distortion must be undistorted first); poses converted to
// camera-to-world in OpenGL axes (colmap_types.hpp).
#pragma once

#include "difftrans/io/colmap_binary.hpp"
#include "difftrans/io/colmap_text.hpp"

namespace difftrans::io {

// Whether model_dir holds a COLMAP model: "binary" (cameras.bin + images.bin,
// preferred, as COLMAP does), "text" (cameras.txt + images.txt) or "".
inline std::string colmap_model_format(const std::filesystem::path& model_dir) {
  std::error_code ec;
  const auto both = [&](const char* ext) {
    return std::filesystem::is_regular_file(model_dir / (std::string("cameras") + ext), ec) &&
           std::filesystem::is_regular_file(model_dir / (std::string("images") + ext), ec);
  };
  if (both(".bin")) return "binary";
  if (both(".txt")) return "text";
  return "";
}

// Reads a COLMAP model, binary (cameras.bin, images.bin) or text
// (cameras.txt, images.txt) as colmap_model_format finds it in model_dir;
// images are image_dir/NAME, masks (masks files or automatic) mask_dir/STEM.png
// or mask_dir/NAME.png when mask_dir is given and one exists (options.masks.dir
// overrides mask_dir). Frames come in the model's image order.
inline Split load_colmap(const std::filesystem::path& model_dir, const std::filesystem::path& image_dir,
                         const std::filesystem::path& mask_dir = {}, const LoadOptions& options = {},
                         std::vector<std::string>* warnings = nullptr) {
  const bool binary = colmap_model_format(model_dir) == "binary";
  const std::filesystem::path cameras_file = model_dir / (binary ? "cameras.bin" : "cameras.txt");
  const std::filesystem::path images_file = model_dir / (binary ? "images.bin" : "images.txt");
  const auto cameras = binary ? read_colmap_cameras_binary(cameras_file) : read_colmap_cameras(cameras_file);
  const auto images = binary ? read_colmap_images_binary(images_file) : read_colmap_images(images_file);
  const std::filesystem::path masks = options.masks.dir.empty() ? mask_dir : options.masks.dir;
  Split split;
  split.file = images_file;
  std::set<std::uint32_t> ids;
  std::string first_skipped;
  for (const ColmapImage& im : images) {
    try {
      if (!ids.insert(im.id).second) throw Error(images_file, im.where + ": image id appears twice", im.line);
      const double qn = glm::length(im.q_wxyz);
      if (std::abs(qn - 1.0) > 1e-3)
        throw Error(images_file, im.where + ": rotation quaternion has norm " + std::to_string(qn) + ", expected 1",
                    im.line);
      const auto cam = cameras.find(im.camera_id);
      if (cam == cameras.end())
        throw Error(images_file, im.where + ": camera id " + std::to_string(im.camera_id) + " is not in " +
                                     cameras_file.filename().string(), im.line);
      Frame f;
      f.name = std::filesystem::path(im.name).stem().string();
      f.image_path = image_dir / im.name;
      f.intrinsics = cam->second.intrinsics;
      f.camera_to_world = colmap_to_camera_to_world(im.q_wxyz, im.t);
      check_camera_matrix(f.camera_to_world, images_file, im.where, im.line);
      std::error_code ec;
      if (!std::filesystem::is_regular_file(f.image_path, ec))
        throw Error(images_file, im.where + ": file " + f.image_path.string() + " not found", im.line);
      std::filesystem::path file;
      if (!masks.empty()) {
        file = mask_in_dir(masks, f);
        const auto nested = masks / (im.name + ".png");  // COLMAP's convention: NAME with its folders, plus .png
        if (file.empty() && std::filesystem::is_regular_file(nested, ec)) file = nested;
      }
      if (!choose_mask(f, file, options.masks) && options.masks.source != MaskSource::none && warnings)
        warnings->push_back(images_file.string() + (im.line ? ":" + std::to_string(im.line) : std::string()) + ": " +
                            im.where + " (" + im.name + ") has no mask" +
                            (masks.empty() ? std::string() : " in " + masks.string()));
      if (options.read_pixels) read_frame_pixels(f, cameras_file, options.masks, warnings);
      else if (options.check_sizes) check_frame_headers(f, cameras_file);
      split.frames.push_back(std::move(f));
    } catch (const Error& e) {
      if (!options.skip_bad_frames) throw;
      if (first_skipped.empty()) first_skipped = e.what();
      if (warnings) warnings->push_back(std::string("skipped a frame: ") + e.what());
    }
  }
  if (split.frames.empty())
    throw Error(images_file, images.empty() ? std::string("no images")
                                            : "no usable images (every one was skipped; the first: " + first_skipped + ")");
  return split;
}

}  // namespace difftrans::io
