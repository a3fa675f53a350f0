// Cameras and frames of a scene directory as the loaders return them (pinhole
// intrinsics, camera-to-world in OpenGL axes, optional pixels and mask), with
// the checks every loader applies: rigid camera matrices, image/mask sizes;
// and where a frame's mask comes from (a mask file, the image's alpha
// channel, or a threshold on the image).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "difftrans/io/image_file.hpp"

namespace difftrans::io {

// Pinhole intrinsics in pixels. The image's top-left corner is (0, 0), so the
// centre of pixel (i, j) is (i + 0.5, j + 0.5) and a centred camera has cx = w / 2.
struct Intrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0;
  double cx = 0.0, cy = 0.0;

  double fov_x() const { return 2.0 * std::atan(0.5 * width / fx); }
  double fov_y() const { return 2.0 * std::atan(0.5 * height / fy); }
  static Intrinsics from_fov_x(int width, int height, double fov_x) {
    const double f = 0.5 * width / std::tan(0.5 * fov_x);
    return {width, height, f, f, 0.5 * width, 0.5 * height};
  }
  static Intrinsics from_fov_y(int width, int height, double fov_y) {
    const double f = 0.5 * height / std::tan(0.5 * fov_y);
    return {width, height, f, f, 0.5 * width, 0.5 * height};
  }
};

// Where object masks come from (LoadOptions::masks.source).
enum class MaskSource {
  automatic,  // a mask file (the scene's mask_path or masks/NAME.png) if there is one, else the image's alpha channel if it has one
  files,      // mask files only (masks.dir when given, else the scene's own)
  alpha,      // the image's alpha channel (8-bit formats: PNG); an image without one is an error
  threshold,  // the image itself: object where its brightest channel's sRGB value is above (below) masks.threshold
  none,       // no masks
};

inline const char* to_string(MaskSource s) {
  switch (s) {
    case MaskSource::automatic: return "auto";
    case MaskSource::files: return "files";
    case MaskSource::alpha: return "alpha";
    case MaskSource::threshold: return "threshold";
    case MaskSource::none: return "none";
  }
  return "?";
}

struct MaskOptions {
  MaskSource source = MaskSource::automatic;
  std::filesystem::path dir;  // files (and automatic): masks DIR/NAME.png (or DIR/FILE_NAME.png) instead of the scene's
  int level = 127;            // files, alpha: 8-bit values above this are object
  double threshold = 0.5;     // threshold: sRGB value in (0, 1) of the image's brightest channel
  bool below = false;         // threshold: object where the image is darker than the threshold (a bright backdrop)
};

struct Frame {
  std::string name;                  // image file name without folder and extension
  std::filesystem::path image_path;  // resolved, with extension
  std::filesystem::path mask_path;   // mask_source files: the mask file, empty when the frame has no mask
  MaskSource mask_source = MaskSource::files;  // files (mask_path, if any), alpha or threshold; never automatic or none
  Intrinsics intrinsics;
  Mat4<double> camera_to_world{1.0};  // OpenGL axes: the camera looks down -Z, +Y is up
  bool environment_only = false;      // fits the environment, not the object
  Image image;                        // empty unless pixels were read
  Mask mask;                          // empty unless pixels were read and there is a mask

  bool has_mask() const { return mask_source != MaskSource::files || !mask_path.empty(); }
  Vec3d position() const { return Vec3d(camera_to_world[3]); }
  Vec3d forward() const { return -Vec3d(camera_to_world[2]); }
  Vec3d up() const { return Vec3d(camera_to_world[1]); }
};

// The frames of one transforms_*.json (or one COLMAP model).
struct Split {
  std::filesystem::path file;
  std::vector<Frame> frames;
};

struct LoadOptions {
  bool read_pixels = true;       // false: cameras and paths only; of the images, only headers are read (to check
                                 // the declared sizes, and where w, h are absent or masks may come from alpha)
  bool check_sizes = true;       // read_pixels false: each image's (and mask file's) header is read to check the
                                 // declared size; false: image files are not opened unless needed as above
  bool skip_bad_frames = false;  // true: a bad frame becomes a warning and is left out, instead of an Error
  MaskOptions masks;
};

// Largest deviation of R^T R from the identity that counts as rigid.
inline constexpr double rigid_tolerance = 1e-4;

// Farthest a camera may be from the scene's origin (in scene units, on any
// axis). Rays are traced in float: a million units out, floats are 0.06 units
// apart, so an object of unit size near the origin can no longer be rendered
// faithfully, and Embree aborts the program on ray origins beyond 1.8e18.
// Scenes as docs/conventions.md places them keep cameras a few units away.
inline constexpr double max_camera_distance = 1e6;

// Throws Error (naming `file`, the field `where` and `line` when known) unless
// the camera-to-world matrix is finite and rigid: orthonormal rotation with
// determinant +1 (within rigid_tolerance) and last row 0 0 0 1; and its
// position lies within max_camera_distance of the origin on every axis.
inline void check_camera_matrix(const Mat4<double>& m, const std::filesystem::path& file, const std::string& where,
                                long line = 0) {
  const std::string prefix = where.empty() ? std::string() : where + ": ";
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r]))
        throw Error(file, prefix + "camera matrix has a non-finite entry at row " + std::to_string(r) + ", column " +
                              std::to_string(c), line);
  if (std::abs(m[0][3]) > rigid_tolerance || std::abs(m[1][3]) > rigid_tolerance ||
      std::abs(m[2][3]) > rigid_tolerance || std::abs(m[3][3] - 1.0) > rigid_tolerance)
    throw Error(file, prefix + "camera matrix's last row is not 0 0 0 1", line);
  const Mat3<double> rot(m);
  const Mat3<double> g = glm::transpose(rot) * rot;
  double deviation = 0.0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) deviation = std::max(deviation, std::abs(g[c][r] - (c == r ? 1.0 : 0.0)));
  if (deviation > rigid_tolerance)
    throw Error(file, prefix + "camera matrix is not rigid: its rotation part is not orthonormal (max |R^T R - I| = " +
                          std::to_string(deviation) + ", tolerance " + std::to_string(rigid_tolerance) + ")", line);
  if (glm::determinant(rot) < 0.0)
    throw Error(file, prefix + "camera matrix is not rigid: its rotation part is a reflection (determinant -1)", line);
  const Vec3d t(m[3]);
  if (std::max(std::abs(t.x), std::max(std::abs(t.y), std::abs(t.z))) > max_camera_distance) {
    char text[160];
    std::snprintf(text, sizeof(text), "camera position (%.6g, %.6g, %.6g) lies beyond %g scene units from the origin",
                  t.x, t.y, t.z, max_camera_distance);
    throw Error(file, prefix + text + ": rays are traced in float, too coarse there to render an object near the "
                                      "origin, and the ray tracer refuses such origins; recentre or rescale the scene",
                line);
  }
}

// Largest image accepted from a scene: a side of 16384 pixels and 64 Mpx in
// all (768 MB as linear float RGB, before any rendering), so that a typo in a
// declared size fails at load instead of allocating gigabytes.
inline constexpr int max_image_side = 16384;
inline constexpr long long max_image_pixels = 64ll << 20;

// Throws Error unless the intrinsics are usable: a positive image size within
// max_image_side and max_image_pixels, positive finite focal lengths, a finite principal point.
inline void check_intrinsics(const Intrinsics& k, const std::filesystem::path& file, const std::string& where,
                             long line = 0) {
  const std::string prefix = where.empty() ? std::string() : where + ": ";
  const std::string size = std::to_string(k.width) + " x " + std::to_string(k.height);
  if (k.width <= 0 || k.height <= 0) throw Error(file, prefix + "image size " + size + " is not positive", line);
  if (k.width > max_image_side || k.height > max_image_side ||
      static_cast<long long>(k.width) * k.height > max_image_pixels)
    throw Error(file, prefix + "image size " + size + " exceeds the limit of " + std::to_string(max_image_side) +
                          " pixels a side and " + std::to_string(max_image_pixels >> 20) + " Mpx in all", line);
  if (!(std::isfinite(k.fx) && k.fx > 0.0 && std::isfinite(k.fy) && k.fy > 0.0))
    throw Error(file, prefix + "focal length is not a positive finite number", line);
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) throw Error(file, prefix + "principal point is not finite", line);
}

namespace detail {

// Finds the image a path names, with or without extension: the path as given
// if it is a file, else the path with each of image_extensions() appended.
inline std::filesystem::path find_image(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(path, ec)) return path;
  for (const auto& ext : image_extensions()) {
    std::filesystem::path candidate = path;
    candidate += ext;
    if (std::filesystem::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

inline std::string size_text(int w, int h) { return std::to_string(w) + " x " + std::to_string(h); }

}  // namespace detail

// Where a frame's mask comes from, before any pixels are read. `file` is the
// mask file that masks.dir or the scene's layout offers (empty: none). Sets
// frame.mask_source and frame.mask_path; returns false when the frame is left
// without a mask. masks alpha with an image that has no alpha channel is an
// Error naming the image.
inline bool choose_mask(Frame& frame, const std::filesystem::path& file, const MaskOptions& o) {
  frame.mask_path.clear();
  frame.mask_source = MaskSource::files;
  switch (o.source) {
    case MaskSource::none: return false;
    case MaskSource::threshold: frame.mask_source = MaskSource::threshold; return true;
    case MaskSource::alpha:
      if (!image_has_alpha(frame.image_path))
        throw Error(frame.image_path, "the image has no alpha channel to take the mask from (masks: alpha; "
                                      "only 8-bit images such as PNG carry one here)");
      frame.mask_source = MaskSource::alpha;
      return true;
    case MaskSource::files: frame.mask_path = file; return !file.empty();
    case MaskSource::automatic:
      if (!file.empty()) {
        frame.mask_path = file;
        return true;
      }
      if (image_has_alpha(frame.image_path)) {
        frame.mask_source = MaskSource::alpha;
        return true;
      }
      return false;
  }
  return false;
}

// The mask file for a frame in masks.dir: DIR/NAME.png, else DIR/FILE_NAME.png
// (e.g. DIR/a.jpg.png, COLMAP's convention); empty when neither exists.
inline std::filesystem::path mask_in_dir(const std::filesystem::path& dir, const Frame& frame) {
  std::error_code ec;
  for (const auto& candidate : {dir / (frame.name + ".png"), dir / (frame.image_path.filename().string() + ".png")})
    if (std::filesystem::is_regular_file(candidate, ec)) return candidate;
  return {};
}

// Throws Error naming the image unless its size is the one `declared_by`
// declares (the intrinsics).
inline void check_image_size(const Frame& frame, int width, int height, const std::filesystem::path& declared_by) {
  const Intrinsics& k = frame.intrinsics;
  if (width != k.width || height != k.height)
    throw Error(frame.image_path, "image is " + detail::size_text(width, height) + " but " + declared_by.string() +
                                      " declares " + detail::size_text(k.width, k.height));
}

// Cameras only: checks the sizes of a frame's image and mask file from their
// headers (no pixels decoded) against the intrinsics `declared_by` defines.
inline void check_frame_headers(const Frame& frame, const std::filesystem::path& declared_by) {
  const Vec2i image = image_size(frame.image_path);
  check_image_size(frame, image.x, image.y, declared_by);
  if (frame.mask_source != MaskSource::files || frame.mask_path.empty()) return;
  const Vec2i mask = image_size(frame.mask_path);
  if (mask != image)
    throw Error(frame.mask_path, "mask is " + detail::size_text(mask.x, mask.y) + " but its image " +
                                     frame.image_path.string() + " is " + detail::size_text(image.x, image.y));
}

// Whether a mask has at least one object pixel.
inline bool has_foreground(const Mask& mask) {
  return std::any_of(mask.inside.begin(), mask.inside.end(), [](std::uint8_t v) { return v != 0; });
}

// Where a frame's mask was taken from, for messages.
inline std::filesystem::path mask_origin(const Frame& frame) {
  return frame.mask_source == MaskSource::files ? frame.mask_path : frame.image_path;
}

namespace detail {

inline void read_frame_image_and_mask(Frame& frame, const std::filesystem::path& declared_by, const MaskOptions& o,
                                      std::vector<std::string>* warnings) {
  const auto check_image_size = [&] { io::check_image_size(frame, frame.image.width, frame.image.height, declared_by); };
  if (frame.mask_source == MaskSource::alpha) {
    const Image8 raw = read_image8(frame.image_path, 4);
    frame.image = from_srgb8(raw.data.data(), raw.width, raw.height, 4);
    check_image_size();
    frame.mask = Mask(raw.width, raw.height);
    bool opaque = true, black_background = true;
    for (std::size_t p = 0; p < frame.mask.inside.size(); ++p) {
      const std::uint8_t* px = &raw.data[p * 4];
      const bool inside = px[3] > o.level;
      frame.mask.inside[p] = inside ? 1 : 0;
      opaque = opaque && inside;
      if (!inside) black_background = black_background && px[0] == 0 && px[1] == 0 && px[2] == 0;
    }
    if (opaque && o.source == MaskSource::automatic) {
      frame.mask = Mask();
      frame.mask_source = MaskSource::files;
      if (warnings)
        warnings->push_back(frame.image_path.string() + ": the alpha channel is opaque everywhere, so it is no mask; "
                                                         "the frame has no mask");
    } else if (!opaque && black_background && warnings) {
      warnings->push_back(frame.image_path.string() + ": every pixel outside the alpha mask is black (a cut-out or "
                                                       "premultiplied image?): the background shows no environment");
    }
    return;
  }
  frame.image = read_image(frame.image_path);
  check_image_size();
  if (frame.mask_source == MaskSource::threshold) {
    const float t = srgb_to_linear(float(o.threshold));
    frame.mask = Mask(frame.image.width, frame.image.height);
    for (std::size_t p = 0; p < frame.mask.inside.size(); ++p) {
      const float* c = &frame.image.rgb[p * 3];
      const float v = std::max(c[0], std::max(c[1], c[2]));
      frame.mask.inside[p] = (o.below ? v < t : v > t) ? 1 : 0;
    }
    return;
  }
  if (frame.mask_path.empty()) return;
  frame.mask = read_mask(frame.mask_path, o.level);
  if (frame.mask.width != frame.image.width || frame.mask.height != frame.image.height)
    throw Error(frame.mask_path, "mask is " + detail::size_text(frame.mask.width, frame.mask.height) +
                                     " but its image " + frame.image_path.string() + " is " +
                                     detail::size_text(frame.image.width, frame.image.height));
}

}  // namespace detail

// Reads a frame's image and mask and checks their sizes against each other
// and against the intrinsics (which `declared_by` defines). The mask comes
// from frame.mask_source (choose_mask): the file, the alpha channel (> level),
// or the threshold on the image. With masks.source automatic, an alpha channel
// that is opaque everywhere is no mask (a warning says so); an alpha mask whose
// background pixels are all black (a cut-out or premultiplied image, where the
// environment cannot be seen) is warned about, and so is a mask with no object
// pixel in a frame that is not environment_only.
inline void read_frame_pixels(Frame& frame, const std::filesystem::path& declared_by, const MaskOptions& o = {},
                              std::vector<std::string>* warnings = nullptr) {
  detail::read_frame_image_and_mask(frame, declared_by, o, warnings);
  if (warnings && !frame.environment_only && !frame.mask.inside.empty() && !has_foreground(frame.mask))
    warnings->push_back(mask_origin(frame).string() + ": the mask of frame " + frame.name +
                        " has no foreground pixel (the object is nowhere in this view)");
}

}  // namespace difftrans::io
