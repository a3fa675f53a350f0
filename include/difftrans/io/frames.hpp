// Cameras and frames of a scene directory as the loaders return them (pinhole
// intrinsics, camera-to-world in OpenGL axes, optional pixels and mask), with
// the checks every loader applies: rigid camera matrices, image/mask sizes.
#pragma once

#include <cmath>
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

struct Frame {
  std::string name;                  // image file name without folder and extension
  std::filesystem::path image_path;  // resolved, with extension
  std::filesystem::path mask_path;   // empty when the frame has no mask
  Intrinsics intrinsics;
  Mat4<double> camera_to_world{1.0};  // OpenGL axes: the camera looks down -Z, +Y is up
  bool environment_only = false;      // fits the environment, not the object
  Image image;                        // empty unless pixels were read
  Mask mask;                          // empty unless pixels were read and there is a mask

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
  bool read_pixels = true;       // false: cameras and paths only; image files are not opened (unless w, h are absent)
  bool skip_bad_frames = false;  // true: a bad frame becomes a warning and is left out, instead of an Error
};

// Largest deviation of R^T R from the identity that counts as rigid.
inline constexpr double rigid_tolerance = 1e-4;

// Throws Error (naming `file`, the field `where` and `line` when known) unless
// the camera-to-world matrix is finite and rigid: orthonormal rotation with
// determinant +1 (within rigid_tolerance) and last row 0 0 0 1.
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
}

// Throws Error unless the intrinsics are usable.
inline void check_intrinsics(const Intrinsics& k, const std::filesystem::path& file, const std::string& where,
                             long line = 0) {
  const std::string prefix = where.empty() ? std::string() : where + ": ";
  if (k.width <= 0 || k.height <= 0)
    throw Error(file, prefix + "image size " + std::to_string(k.width) + " x " + std::to_string(k.height) +
                          " is not positive", line);
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

// Reads a frame's image and mask and checks their sizes against each other
// and against the intrinsics (which `declared_by` defines).
inline void read_frame_pixels(Frame& frame, const std::filesystem::path& declared_by) {
  frame.image = read_image(frame.image_path);
  const Intrinsics& k = frame.intrinsics;
  if (frame.image.width != k.width || frame.image.height != k.height)
    throw Error(frame.image_path, "image is " + detail::size_text(frame.image.width, frame.image.height) + " but " +
                                      declared_by.string() + " declares " + detail::size_text(k.width, k.height));
  if (frame.mask_path.empty()) return;
  frame.mask = read_mask(frame.mask_path);
  if (frame.mask.width != frame.image.width || frame.mask.height != frame.image.height)
    throw Error(frame.mask_path, "mask is " + detail::size_text(frame.mask.width, frame.mask.height) +
                                     " but its image " + frame.image_path.string() + " is " +
                                     detail::size_text(frame.image.width, frame.image.height));
}

}  // namespace difftrans::io
