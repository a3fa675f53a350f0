// COLMAP's camera models and poses: the distortion-free pinhole models,
// cameras and images as read from a model, and the conversion between
// COLMAP's world-to-camera pose (quaternion + translation, OpenCV axes) and a
// camera-to-world matrix in OpenGL axes. The readers are in colmap_text.hpp
// and colmap_binary.hpp; colmap.hpp loads a model directory as a split.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "difftrans/io/frames.hpp"

namespace difftrans::io {

// Camera-to-world (OpenGL axes) from COLMAP's world-to-camera rotation
// q = (qw, qx, qy, qz) (normalized here) and translation t (OpenCV axes:
// x right, y down, z forward).
inline Mat4<double> colmap_to_camera_to_world(const glm::dvec4& q_wxyz, const Vec3d& t) {
  const double n = std::sqrt(q_wxyz.x * q_wxyz.x + q_wxyz.y * q_wxyz.y + q_wxyz.z * q_wxyz.z + q_wxyz.w * q_wxyz.w);
  const double w = q_wxyz.x / n, x = q_wxyz.y / n, y = q_wxyz.z / n, z = q_wxyz.w / n;
  Mat3<double> r;  // world-to-camera; glm is column-major: r[column][row]
  r[0][0] = 1 - 2 * (y * y + z * z); r[1][0] = 2 * (x * y - w * z);     r[2][0] = 2 * (x * z + w * y);
  r[0][1] = 2 * (x * y + w * z);     r[1][1] = 1 - 2 * (x * x + z * z); r[2][1] = 2 * (y * z - w * x);
  r[0][2] = 2 * (x * z - w * y);     r[1][2] = 2 * (y * z + w * x);     r[2][2] = 1 - 2 * (x * x + y * y);
  const Mat3<double> rt = glm::transpose(r);
  const Vec3d centre = -(rt * t);
  Mat4<double> m(1.0);
  m[0] = glm::dvec4(rt[0], 0.0);
  m[1] = glm::dvec4(-rt[1], 0.0);  // OpenCV y down -> OpenGL y up
  m[2] = glm::dvec4(-rt[2], 0.0);  // OpenCV z forward -> OpenGL camera looks down -z
  m[3] = glm::dvec4(centre, 1.0);
  return m;
}

// COLMAP's world-to-camera rotation (w, x, y, z; w >= 0) and translation
// (OpenCV axes) of a camera-to-world matrix in OpenGL axes: the inverse of
// colmap_to_camera_to_world.
struct ColmapPose {
  glm::dvec4 q_wxyz{1.0, 0.0, 0.0, 0.0};  // stored as (x = w, y = x, z = y, w = z), as colmap_to_camera_to_world takes it
  Vec3d t{0.0};
};

inline ColmapPose camera_to_world_to_colmap(const Mat4<double>& m) {
  Mat3<double> rt;  // camera-to-world rotation in OpenCV axes = R^T
  rt[0] = Vec3d(m[0]);
  rt[1] = -Vec3d(m[1]);
  rt[2] = -Vec3d(m[2]);
  const Mat3<double> r = glm::transpose(rt);
  const auto at = [&](int row, int col) { return r[col][row]; };
  double w, x, y, z;
  const double trace = at(0, 0) + at(1, 1) + at(2, 2);
  if (trace > 0.0) {
    const double s = 2.0 * std::sqrt(trace + 1.0);
    w = 0.25 * s, x = (at(2, 1) - at(1, 2)) / s, y = (at(0, 2) - at(2, 0)) / s, z = (at(1, 0) - at(0, 1)) / s;
  } else if (at(0, 0) >= at(1, 1) && at(0, 0) >= at(2, 2)) {
    const double s = 2.0 * std::sqrt(1.0 + at(0, 0) - at(1, 1) - at(2, 2));
    w = (at(2, 1) - at(1, 2)) / s, x = 0.25 * s, y = (at(0, 1) + at(1, 0)) / s, z = (at(0, 2) + at(2, 0)) / s;
  } else if (at(1, 1) >= at(2, 2)) {
    const double s = 2.0 * std::sqrt(1.0 + at(1, 1) - at(0, 0) - at(2, 2));
    w = (at(0, 2) - at(2, 0)) / s, x = (at(0, 1) + at(1, 0)) / s, y = 0.25 * s, z = (at(1, 2) + at(2, 1)) / s;
  } else {
    const double s = 2.0 * std::sqrt(1.0 + at(2, 2) - at(0, 0) - at(1, 1));
    w = (at(1, 0) - at(0, 1)) / s, x = (at(0, 2) + at(2, 0)) / s, y = (at(1, 2) + at(2, 1)) / s, z = 0.25 * s;
  }
  const double sign = w < 0.0 ? -1.0 : 1.0;
  const double n = sign * std::sqrt(w * w + x * x + y * y + z * z);
  ColmapPose pose;
  pose.q_wxyz = glm::dvec4(w / n, x / n, y / n, z / n);
  pose.t = -(r * Vec3d(m[3]));
  return pose;
}

// A COLMAP camera model: its id in binary files, its name in text files and
// its parameters in order. Fisheye models do not project like a pinhole even
// with zero distortion; the others do when their distortion parameters are 0.
struct ColmapModel {
  int id;
  const char* name;
  std::vector<const char*> params;
  bool fisheye;

  bool one_focal() const { return std::strcmp(params[0], "f") == 0; }
  // The index of the first distortion parameter (after the focal lengths and the principal point).
  std::size_t first_distortion() const { return one_focal() ? 3 : 4; }
};

inline const std::vector<ColmapModel>& colmap_models() {
  static const std::vector<ColmapModel> models = {
      {0, "SIMPLE_PINHOLE", {"f", "cx", "cy"}, false},
      {1, "PINHOLE", {"fx", "fy", "cx", "cy"}, false},
      {2, "SIMPLE_RADIAL", {"f", "cx", "cy", "k"}, false},
      {3, "RADIAL", {"f", "cx", "cy", "k1", "k2"}, false},
      {4, "OPENCV", {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"}, false},
      {5, "OPENCV_FISHEYE", {"fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"}, true},
      {6, "FULL_OPENCV", {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"}, false},
      {7, "FOV", {"fx", "fy", "cx", "cy", "omega"}, false},
      {8, "SIMPLE_RADIAL_FISHEYE", {"f", "cx", "cy", "k"}, true},
      {9, "RADIAL_FISHEYE", {"f", "cx", "cy", "k1", "k2"}, true},
      {10, "THIN_PRISM_FISHEYE", {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "sx1", "sy1"}, true},
      {11, "RAD_TAN_THIN_PRISM_FISHEYE",
       {"fx", "fy", "cx", "cy", "k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3"}, true}};
  return models;
}

inline const ColmapModel* find_colmap_model(const std::string& name) {
  for (const auto& m : colmap_models())
    if (name == m.name) return &m;
  return nullptr;
}

inline const ColmapModel* find_colmap_model(long id) {
  for (const auto& m : colmap_models())
    if (id == m.id) return &m;
  return nullptr;
}

inline std::string colmap_model_names() {
  std::string s;
  for (const auto& m : colmap_models()) s += (s.empty() ? "" : ", ") + std::string(m.name);
  return s;
}

namespace detail {

// A number as errors show it: the fewest digits (at least 6) that read back as the same double.
inline std::string exact_text(double v) {
  char s[64];
  for (int digits = 6; digits <= 17; ++digits) {
    std::snprintf(s, sizeof(s), "%.*g", digits, v);
    if (!std::isfinite(v) || std::strtod(s, nullptr) == v) break;
  }
  return s;
}

}  // namespace detail

struct ColmapCamera {
  std::string model;
  Intrinsics intrinsics;
  std::vector<double> params;  // as in the file, distortion included
};

// The pinhole camera of a COLMAP camera record, or an Error (naming `file`,
// `where` and `line`): the size must be a positive integer size, the
// parameters finite; fisheye models are refused, and so are the others when a
// distortion parameter is not 0 (the message names the model and the non-zero
// parameters with their values). SIMPLE_PINHOLE and PINHOLE, and the
// distortion models with all-zero distortion, are pinhole cameras.
inline ColmapCamera make_colmap_camera(const ColmapModel& model, double width, double height,
                                       const std::vector<double>& params, const std::filesystem::path& file,
                                       const std::string& where, long line = 0) {
  const std::string prefix = where + ": ";
  if (params.size() != model.params.size())
    throw Error(file, prefix + "camera model " + model.name + " takes " + std::to_string(model.params.size()) +
                          " parameters, found " + std::to_string(params.size()), line);
  if (!(width == std::floor(width) && height == std::floor(height) && width >= 1 && height >= 1 && width <= 1e6 &&
        height <= 1e6))
    throw Error(file, prefix + "image size " + detail::exact_text(width) + " x " + detail::exact_text(height) +
                          " is not a positive integer size (at most 1000000)", line);
  for (std::size_t i = 0; i < params.size(); ++i)
    if (!std::isfinite(params[i]))
      throw Error(file, prefix + "parameter " + model.params[i] + " = " + detail::exact_text(params[i]) +
                            " is not finite", line);
  const std::string undistort =
      "; difftrans needs pinhole images: undistort them first (colmap image_undistorter writes undistorted "
      "images and a PINHOLE model)";
  if (model.fisheye)
    throw Error(file, prefix + "camera model " + model.name + " is a fisheye lens model, which is not a pinhole "
                          "projection" + undistort, line);
  std::string nonzero;
  for (std::size_t i = model.first_distortion(); i < params.size(); ++i)
    if (params[i] != 0.0)
      nonzero += (nonzero.empty() ? "" : ", ") + std::string(model.params[i]) + " = " + detail::exact_text(params[i]);
  if (!nonzero.empty())
    throw Error(file, prefix + "camera model " + model.name + " has lens distortion (" + nonzero + ")" + undistort, line);
  ColmapCamera cam;
  cam.model = model.name;
  cam.params = params;
  Intrinsics& k = cam.intrinsics;
  k.width = int(width);
  k.height = int(height);
  k.fx = params[0];
  k.fy = model.one_focal() ? params[0] : params[1];
  k.cx = params[model.first_distortion() - 2];
  k.cy = params[model.first_distortion() - 1];
  check_intrinsics(k, file, where, line);
  return cam;
}

struct ColmapPoint2D {
  double x = 0.0, y = 0.0;
  std::int64_t point3d_id = -1;  // -1: no 3D point
};

// One image of a COLMAP model, as either format stores it.
struct ColmapImage {
  std::uint32_t id = 0;
  glm::dvec4 q_wxyz{1.0, 0.0, 0.0, 0.0};  // as colmap_to_camera_to_world takes it
  Vec3d t{0.0};
  std::uint32_t camera_id = 0;
  std::string name;                          // relative to the image folder
  std::vector<ColmapPoint2D> points2d;       // written by write_colmap_images_binary; the readers skip them
  // where the record is, for errors
  std::string where;  // "image 3" or "byte 120, image 3 (record 2 of 5)"
  long line = 0;      // text files
};

}  // namespace difftrans::io
