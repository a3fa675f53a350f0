// COLMAP models: text (cameras.txt, images.txt) and binary (cameras.bin,
// images.bin, COLMAP's default output), read and written. Pinhole intrinsics
// (distortion-free models only: images with lens distortion must be
// undistorted first) and poses, converted from world-to-camera (quaternion +
// translation, OpenCV axes) to camera-to-world in OpenGL axes and back.
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

namespace detail {

// The lines of a COLMAP text file with their numbers; `#` comments dropped.
struct TextLines {
  std::vector<std::string> text;
  std::vector<long> number;
};

inline TextLines colmap_lines(const std::filesystem::path& path) {
  const std::string all = read_file_text(path);
  TextLines lines;
  size_t pos = 0;
  long n = 0;
  while (pos < all.size()) {
    size_t end = all.find('\n', pos);
    if (end == std::string::npos) end = all.size();
    std::string l = all.substr(pos, end - pos);
    if (!l.empty() && l.back() == '\r') l.pop_back();
    ++n;
    if (l.empty() || l[0] != '#') {
      lines.text.push_back(l);
      lines.number.push_back(n);
    }
    pos = end + 1;
  }
  return lines;
}

inline bool blank(const std::string& s) {
  return s.find_first_not_of(" \t") == std::string::npos;
}

inline double colmap_number(const std::string& token, const std::filesystem::path& file, long line,
                            const char* what) {
  char* stop = nullptr;
  const double v = std::strtod(token.c_str(), &stop);
  if (token.empty() || *stop != '\0') throw Error(file, std::string(what) + " '" + token + "' is not a number", line);
  if (!std::isfinite(v)) throw Error(file, std::string(what) + " '" + token + "' is not finite", line);
  return v;
}

}  // namespace detail

// Reads cameras.txt: "CAMERA_ID MODEL WIDTH HEIGHT PARAMS..." (make_colmap_camera says which models load).
inline std::map<std::uint32_t, ColmapCamera> read_colmap_cameras(const std::filesystem::path& path) {
  const auto lines = detail::colmap_lines(path);
  std::map<std::uint32_t, ColmapCamera> cameras;
  for (size_t i = 0; i < lines.text.size(); ++i) {
    if (detail::blank(lines.text[i])) continue;
    const long ln = lines.number[i];
    std::istringstream in(lines.text[i]);
    std::vector<std::string> t;
    for (std::string s; in >> s;) t.push_back(s);
    if (t.size() < 4) throw Error(path, "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...", ln);
    const double id = detail::colmap_number(t[0], path, ln, "camera id");
    if (id != std::floor(id) || id < 0 || id > 4294967295.0)
      throw Error(path, "camera id '" + t[0] + "' is not an integer in 0..4294967295", ln);
    const ColmapModel* model = find_colmap_model(t[1]);
    if (!model) throw Error(path, "camera model '" + t[1] + "' is not a COLMAP model (" + colmap_model_names() + ")", ln);
    const double w = detail::colmap_number(t[2], path, ln, "width");
    const double h = detail::colmap_number(t[3], path, ln, "height");
    std::vector<double> params;
    for (size_t k = 4; k < t.size(); ++k) params.push_back(detail::colmap_number(t[k], path, ln, "parameter"));
    ColmapCamera cam = make_colmap_camera(*model, w, h, params, path, "camera " + t[0], ln);
    if (!cameras.emplace(std::uint32_t(id), std::move(cam)).second)
      throw Error(path, "camera id " + t[0] + " appears twice", ln);
  }
  if (cameras.empty()) throw Error(path, "no cameras");
  return cameras;
}

// Reads images.txt: two lines per image, "IMAGE_ID QW QX QY QZ TX TY TZ
// CAMERA_ID NAME" (NAME may contain spaces) and the 2D points (skipped).
inline std::vector<ColmapImage> read_colmap_images(const std::filesystem::path& path) {
  const auto lines = detail::colmap_lines(path);
  std::vector<ColmapImage> images;
  for (size_t i = 0; i < lines.text.size(); ++i) {
    if (detail::blank(lines.text[i])) continue;  // (a POINTS2D line is consumed below, even when blank)
    const long ln = lines.number[i];
    const std::string& raw = lines.text[i];
    ++i;  // skip the POINTS2D line
    std::istringstream in(raw);
    std::vector<std::string> t;
    for (std::string s; in >> s;) t.push_back(s);
    if (t.size() < 10) throw Error(path, "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", ln);
    ColmapImage im;
    const double id = detail::colmap_number(t[0], path, ln, "image id");
    if (id != std::floor(id) || id < 0 || id > 4294967295.0)
      throw Error(path, "image id '" + t[0] + "' is not an integer in 0..4294967295", ln);
    im.id = std::uint32_t(id);
    double v[8];
    for (int k = 0; k < 8; ++k)
      v[k] = detail::colmap_number(t[size_t(k) + 1], path, ln, k < 4 ? "quaternion" : "translation");
    im.q_wxyz = glm::dvec4(v[0], v[1], v[2], v[3]);
    im.t = Vec3d(v[4], v[5], v[6]);
    const double cam_id = detail::colmap_number(t[8], path, ln, "camera id");
    if (cam_id != std::floor(cam_id) || cam_id < 0 || cam_id > 4294967295.0)
      throw Error(path, "camera id '" + t[8] + "' is not an integer in 0..4294967295", ln);
    im.camera_id = std::uint32_t(cam_id);
    size_t at = 0;
    for (int k = 0; k < 9; ++k) {
      at = raw.find_first_not_of(" \t", at);
      at = raw.find_first_of(" \t", at);
    }
    im.name = raw.substr(raw.find_first_not_of(" \t", at));
    im.name.erase(im.name.find_last_not_of(" \t") + 1);
    im.where = "image " + t[0];
    im.line = ln;
    images.push_back(std::move(im));
  }
  return images;
}

namespace detail {

// Little-endian fields of a COLMAP binary file, each read checked against the
// bytes left; errors name the file, the byte offset and the record.
class BinaryReader {
 public:
  explicit BinaryReader(const std::filesystem::path& path) : path_(path), data_(read_file_text(path)) {}

  const std::filesystem::path& path() const { return path_; }
  std::size_t offset() const { return at_; }
  std::size_t size() const { return data_.size(); }
  std::size_t remaining() const { return data_.size() - at_; }
  // What is being read, for errors ("image 3 of 10").
  void context(const std::string& c) { context_ = c; }

  [[noreturn]] void fail(std::size_t offset, const std::string& what) const {
    throw Error(path_, "byte " + std::to_string(offset) + (context_.empty() ? "" : ", " + context_) + ": " + what);
  }

  void need(std::size_t n, const char* what) const {
    if (remaining() < n)
      fail(at_, std::string("the file ends inside ") + what + " (" + std::to_string(n) + " bytes needed, " +
                    std::to_string(remaining()) + " left of " + std::to_string(size()) + ")");
  }

  std::uint64_t u64(const char* what) { return unsigned_le(8, what); }
  std::uint32_t u32(const char* what) { return std::uint32_t(unsigned_le(4, what)); }
  std::int32_t i32(const char* what) {
    const std::uint32_t u = u32(what);
    std::int32_t v;
    std::memcpy(&v, &u, 4);
    return v;
  }
  std::int64_t i64(const char* what) {
    const std::uint64_t u = u64(what);
    std::int64_t v;
    std::memcpy(&v, &u, 8);
    return v;
  }
  double f64(const char* what) {
    const std::uint64_t u = u64(what);
    double v;
    std::memcpy(&v, &u, 8);
    return v;
  }
  // A NUL-terminated string (the NUL is consumed).
  std::string cstring(const char* what) {
    const std::size_t end = data_.find('\0', at_);
    if (end == std::string::npos)
      fail(at_, std::string("the file ends inside ") + what + " (no terminating NUL in the " +
                    std::to_string(remaining()) + " bytes left)");
    std::string s = data_.substr(at_, end - at_);
    at_ = end + 1;
    return s;
  }
  void skip(std::size_t n, const char* what) {
    need(n, what);
    at_ += n;
  }
  // A record count: `count` records of at least `min_record` bytes must fit in what is left.
  void check_count(std::uint64_t count, std::size_t min_record, std::size_t count_offset, const char* what) const {
    if (count > remaining() / min_record)
      fail(count_offset, std::string(what) + " count " + std::to_string(count) + " needs at least " +
                             (count > std::numeric_limits<std::uint64_t>::max() / min_record
                                  ? std::string("more")
                                  : std::to_string(count * min_record)) +
                             " bytes, but only " + std::to_string(remaining()) + " follow");
  }
  // Bytes after the last record are an error.
  void check_end(const char* what) const {
    if (at_ != data_.size())
      throw Error(path_, "byte " + std::to_string(at_) + ": " + std::to_string(remaining()) + " bytes after the last " +
                             what + " (the count at byte 0 says there are no more)");
  }

 private:
  std::uint64_t unsigned_le(int n, const char* what) {
    need(std::size_t(n), what);
    std::uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | std::uint64_t(static_cast<unsigned char>(data_[at_ + std::size_t(i)]));
    at_ += std::size_t(n);
    return v;
  }

  std::filesystem::path path_;
  std::string data_;
  std::size_t at_ = 0;
  std::string context_;
};

// Little-endian fields appended to a byte string.
class BinaryWriter {
 public:
  void u64(std::uint64_t v) { unsigned_le(v, 8); }
  void u32(std::uint32_t v) { unsigned_le(v, 4); }
  void i32(std::int32_t v) {
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    u32(u);
  }
  void i64(std::int64_t v) {
    std::uint64_t u;
    std::memcpy(&u, &v, 8);
    u64(u);
  }
  void f64(double v) {
    std::uint64_t u;
    std::memcpy(&u, &v, 8);
    u64(u);
  }
  void cstring(const std::string& s) {
    bytes_ += s;
    bytes_ += '\0';
  }
  const std::string& bytes() const { return bytes_; }
  void save(const std::filesystem::path& path) const { write_file_bytes(path, bytes_.data(), bytes_.size()); }

 private:
  void unsigned_le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) bytes_ += char((v >> (8 * i)) & 0xff);
  }
  std::string bytes_;
};

}  // namespace detail

// Reads cameras.bin: uint64 count, then per camera uint32 id, int32 model id,
// uint64 width, uint64 height and the model's parameters as doubles.
inline std::map<std::uint32_t, ColmapCamera> read_colmap_cameras_binary(const std::filesystem::path& path) {
  detail::BinaryReader in(path);
  const std::uint64_t count = in.u64("the camera count");
  in.check_count(count, 4 + 4 + 8 + 8 + 3 * 8, 0, "camera");
  std::map<std::uint32_t, ColmapCamera> cameras;
  for (std::uint64_t i = 0; i < count; ++i) {
    const std::size_t start = in.offset();
    const std::string record = "camera record " + std::to_string(i + 1) + " of " + std::to_string(count);
    in.context(record);
    const std::uint32_t id = in.u32("the camera id");
    const std::size_t model_at = in.offset();
    const std::int32_t model_id = in.i32("the camera model id");
    const ColmapModel* model = find_colmap_model(long(model_id));
    in.context(record + " (camera " + std::to_string(id) + ")");
    if (!model)
      in.fail(model_at, "camera model id " + std::to_string(model_id) + " is not a COLMAP model (0 to " +
                            std::to_string(colmap_models().back().id) + ": " + colmap_model_names() + ")");
    const std::size_t size_at = in.offset();
    const std::uint64_t width = in.u64("the image width");
    const std::uint64_t height = in.u64("the image height");
    if (width < 1 || height < 1 || width > 1000000 || height > 1000000)
      in.fail(size_at, "image size " + std::to_string(width) + " x " + std::to_string(height) +
                           " is not a positive size (at most 1000000)");
    in.need(8 * model->params.size(), "the camera parameters");
    std::vector<double> params;
    for (std::size_t k = 0; k < model->params.size(); ++k) params.push_back(in.f64("the camera parameters"));
    const std::string where = "byte " + std::to_string(start) + ", " + record + " (camera " + std::to_string(id) + ")";
    ColmapCamera cam = make_colmap_camera(*model, double(width), double(height), params, path, where);
    if (!cameras.emplace(id, std::move(cam)).second) in.fail(start, "camera id " + std::to_string(id) + " appears twice");
  }
  in.context("");
  in.check_end("camera record");
  if (cameras.empty()) throw Error(path, "no cameras");
  return cameras;
}

// Reads images.bin: uint64 count, then per image uint32 id, qvec (4 doubles,
// w x y z), tvec (3 doubles), uint32 camera id, the name NUL-terminated,
// uint64 number of 2D points and per point x, y (doubles) and a 3D point id
// (int64); the points are skipped.
inline std::vector<ColmapImage> read_colmap_images_binary(const std::filesystem::path& path) {
  detail::BinaryReader in(path);
  const std::uint64_t count = in.u64("the image count");
  in.check_count(count, 4 + 7 * 8 + 4 + 1 + 8, 0, "image");
  std::vector<ColmapImage> images;
  images.reserve(std::size_t(count));
  for (std::uint64_t i = 0; i < count; ++i) {
    ColmapImage im;
    const std::size_t start = in.offset();
    const std::string record = "image record " + std::to_string(i + 1) + " of " + std::to_string(count);
    in.context(record);
    im.id = in.u32("the image id");
    in.context(record + " (image " + std::to_string(im.id) + ")");
    double v[7];
    for (double& x : v) x = in.f64("the pose");
    im.q_wxyz = glm::dvec4(v[0], v[1], v[2], v[3]);
    im.t = Vec3d(v[4], v[5], v[6]);
    im.camera_id = in.u32("the camera id");
    const std::size_t name_at = in.offset();
    im.name = in.cstring("the image name");
    if (im.name.empty()) in.fail(name_at, "the image name is empty");
    const std::size_t points_at = in.offset();
    const std::uint64_t points = in.u64("the number of 2D points");
    in.context(record + " (image " + std::to_string(im.id) + ", " + im.name + ")");
    if (points > in.remaining() / 24)
      in.fail(points_at, "2D point count " + std::to_string(points) + " needs " +
                             (points > std::numeric_limits<std::uint64_t>::max() / 24 ? std::string("more than ") +
                                  std::to_string(std::numeric_limits<std::uint64_t>::max())
                                                                                       : std::to_string(points * 24)) +
                             " bytes, but only " + std::to_string(in.remaining()) + " follow");
    in.skip(std::size_t(points) * 24, "the 2D points");
    for (int k = 0; k < 7; ++k)
      if (!std::isfinite(v[k]))
        in.fail(start + 4 + 8 * std::size_t(k), std::string(k < 4 ? "quaternion" : "translation") + " component " +
                                                    detail::exact_text(v[k]) + " is not finite");
    im.where = "byte " + std::to_string(start) + ", " + record + " (image " + std::to_string(im.id) + ")";
    images.push_back(std::move(im));
  }
  in.context("");
  in.check_end("image record");
  return images;
}

// Writes cameras.bin for any model of colmap_models() (by name; the
// parameters as given).
inline void write_colmap_cameras_binary(const std::filesystem::path& path,
                                        const std::map<std::uint32_t, ColmapCamera>& cameras) {
  detail::BinaryWriter out;
  out.u64(cameras.size());
  for (const auto& [id, cam] : cameras) {
    const ColmapModel* model = find_colmap_model(cam.model);
    if (!model) throw Error(path, "camera " + std::to_string(id) + ": '" + cam.model + "' is not a COLMAP model");
    if (cam.params.size() != model->params.size())
      throw Error(path, "camera " + std::to_string(id) + ": model " + cam.model + " takes " +
                            std::to_string(model->params.size()) + " parameters, given " +
                            std::to_string(cam.params.size()));
    out.u32(id);
    out.i32(model->id);
    out.u64(std::uint64_t(cam.intrinsics.width));
    out.u64(std::uint64_t(cam.intrinsics.height));
    for (double p : cam.params) out.f64(p);
  }
  out.save(path);
}

inline void write_colmap_images_binary(const std::filesystem::path& path, const std::vector<ColmapImage>& images) {
  detail::BinaryWriter out;
  out.u64(images.size());
  for (const auto& im : images) {
    out.u32(im.id);
    for (int k = 0; k < 4; ++k) out.f64(im.q_wxyz[k]);
    for (int k = 0; k < 3; ++k) out.f64(im.t[k]);
    out.u32(im.camera_id);
    if (im.name.empty() || im.name.find('\0') != std::string::npos)
      throw Error(path, "image " + std::to_string(im.id) + ": the name is empty or holds a NUL");
    out.cstring(im.name);
    out.u64(im.points2d.size());
    for (const auto& p : im.points2d) {
      out.f64(p.x);
      out.f64(p.y);
      out.i64(p.point3d_id);
    }
  }
  out.save(path);
}

// Writes the frames of a split as a COLMAP binary model in model_dir:
// cameras.bin (one PINHOLE camera per distinct intrinsics), images.bin (names
// relative to image_dir, ids from 1 in frame order, no 2D points) and an empty
// points3D.bin, so that COLMAP itself can open the model too.
inline void write_colmap_binary(const std::filesystem::path& model_dir, const Split& split,
                                const std::filesystem::path& image_dir) {
  std::map<std::uint32_t, ColmapCamera> cameras;
  std::vector<ColmapImage> images;
  for (const Frame& f : split.frames) {
    const Intrinsics& k = f.intrinsics;
    std::uint32_t camera_id = 0;
    for (const auto& [id, cam] : cameras) {
      const Intrinsics& c = cam.intrinsics;
      if (c.width == k.width && c.height == k.height && c.fx == k.fx && c.fy == k.fy && c.cx == k.cx && c.cy == k.cy)
        camera_id = id;
    }
    if (camera_id == 0) {
      camera_id = std::uint32_t(cameras.size() + 1);
      cameras[camera_id] = ColmapCamera{"PINHOLE", k, {k.fx, k.fy, k.cx, k.cy}};
    }
    ColmapImage im;
    im.id = std::uint32_t(images.size() + 1);
    const ColmapPose pose = camera_to_world_to_colmap(f.camera_to_world);
    im.q_wxyz = pose.q_wxyz;
    im.t = pose.t;
    im.camera_id = camera_id;
    im.name = f.image_path.lexically_relative(image_dir).generic_string();
    if (im.name.empty() || im.name.rfind("..", 0) == 0)
      throw Error(f.image_path, "is not inside the image folder " + image_dir.string() + " of the COLMAP model");
    images.push_back(std::move(im));
  }
  std::filesystem::create_directories(model_dir);
  write_colmap_cameras_binary(model_dir / "cameras.bin", cameras);
  write_colmap_images_binary(model_dir / "images.bin", images);
  detail::BinaryWriter points;
  points.u64(0);
  points.save(model_dir / "points3D.bin");
}

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
