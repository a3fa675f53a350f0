// COLMAP text models (cameras.txt, images.txt): pinhole intrinsics and poses,
// converted from world-to-camera (quaternion + translation, OpenCV axes) to
// camera-to-world in OpenGL axes.
#pragma once

#include <cstdlib>
#include <map>
#include <sstream>

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

struct ColmapCamera {
  std::string model;
  Intrinsics intrinsics;
  std::vector<double> params;  // as in the file, distortion included
};

// Reads cameras.txt: "CAMERA_ID MODEL WIDTH HEIGHT PARAMS...". Pinhole models
// and the OpenCV/radial ones are accepted; non-zero distortion is ignored with a warning.
inline std::map<long, ColmapCamera> read_colmap_cameras(const std::filesystem::path& path,
                                                        std::vector<std::string>* warnings = nullptr) {
  const auto lines = detail::colmap_lines(path);
  std::map<long, ColmapCamera> cameras;
  struct Model {
    const char* name;
    size_t params;
    bool one_focal;
  };
  static const Model models[] = {{"SIMPLE_PINHOLE", 3, true}, {"PINHOLE", 4, false}, {"SIMPLE_RADIAL", 4, true},
                                 {"RADIAL", 5, true},         {"OPENCV", 8, false},  {"FULL_OPENCV", 12, false}};
  for (size_t i = 0; i < lines.text.size(); ++i) {
    if (detail::blank(lines.text[i])) continue;
    const long ln = lines.number[i];
    std::istringstream in(lines.text[i]);
    std::vector<std::string> t;
    for (std::string s; in >> s;) t.push_back(s);
    if (t.size() < 4) throw Error(path, "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...", ln);
    const double id = detail::colmap_number(t[0], path, ln, "camera id");
    const Model* model = nullptr;
    for (const auto& m : models)
      if (t[1] == m.name) model = &m;
    if (!model)
      throw Error(path, "camera model '" + t[1] +
                            "' is not supported (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV)",
                  ln);
    if (t.size() != 4 + model->params)
      throw Error(path, "camera model " + t[1] + " takes " + std::to_string(model->params) + " parameters, found " +
                            std::to_string(t.size() - 4), ln);
    ColmapCamera cam;
    cam.model = t[1];
    const double w = detail::colmap_number(t[2], path, ln, "width");
    const double h = detail::colmap_number(t[3], path, ln, "height");
    if (w != std::floor(w) || h != std::floor(h) || w < 1 || h < 1 || w > 1e6 || h > 1e6)
      throw Error(path, "image size " + t[2] + " x " + t[3] + " is not a positive integer size", ln);
    for (size_t k = 4; k < t.size(); ++k) cam.params.push_back(detail::colmap_number(t[k], path, ln, "parameter"));
    Intrinsics& k = cam.intrinsics;
    k.width = int(w);
    k.height = int(h);
    const size_t first_distortion = model->one_focal ? 3 : 4;
    k.fx = cam.params[0];
    k.fy = model->one_focal ? cam.params[0] : cam.params[1];
    k.cx = cam.params[first_distortion - 2];
    k.cy = cam.params[first_distortion - 1];
    check_intrinsics(k, path, "camera " + t[0], ln);
    for (size_t p = first_distortion; p < cam.params.size(); ++p)
      if (cam.params[p] != 0.0) {
        if (warnings)
          warnings->push_back(path.string() + ":" + std::to_string(ln) + ": camera " + t[0] +
                              " has lens distortion, which is ignored (images are treated as pinhole)");
        break;
      }
    if (id != std::floor(id)) throw Error(path, "camera id '" + t[0] + "' is not an integer", ln);
    if (!cameras.emplace(long(id), std::move(cam)).second)
      throw Error(path, "camera id " + t[0] + " appears twice", ln);
  }
  if (cameras.empty()) throw Error(path, "no cameras");
  return cameras;
}

// Reads a COLMAP text model: model_dir/cameras.txt and model_dir/images.txt;
// images are image_dir/NAME, masks mask_dir/STEM.png or mask_dir/NAME.png
// when mask_dir is given and one exists. Frames come in images.txt order.
inline Split load_colmap(const std::filesystem::path& model_dir, const std::filesystem::path& image_dir,
                         const std::filesystem::path& mask_dir = {}, const LoadOptions& options = {},
                         std::vector<std::string>* warnings = nullptr) {
  const auto cameras = read_colmap_cameras(model_dir / "cameras.txt", warnings);
  const std::filesystem::path images_txt = model_dir / "images.txt";
  const auto lines = detail::colmap_lines(images_txt);
  Split split;
  split.file = images_txt;
  for (size_t i = 0; i < lines.text.size(); ++i) {
    if (detail::blank(lines.text[i])) continue;  // (a POINTS2D line is consumed below, even when blank)
    const long ln = lines.number[i];
    ++i;  // skip the POINTS2D line
    try {
      std::istringstream in(lines.text[i - 1]);
      std::vector<std::string> t;
      for (std::string s; in >> s;) t.push_back(s);
      if (t.size() < 10) throw Error(images_txt, "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", ln);
      double v[8];
      for (int k = 0; k < 8; ++k) v[k] = detail::colmap_number(t[size_t(k) + 1], images_txt, ln, k < 4 ? "quaternion" : "translation");
      const double qn = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
      if (std::abs(qn - 1.0) > 1e-3)
        throw Error(images_txt, "rotation quaternion has norm " + std::to_string(qn) + ", expected 1", ln);
      const double cam_id = detail::colmap_number(t[8], images_txt, ln, "camera id");
      const auto cam = cameras.find(long(cam_id));
      if (cam_id != std::floor(cam_id) || cam == cameras.end())
        throw Error(images_txt, "camera id " + t[8] + " is not in cameras.txt", ln);
      // NAME is the rest of the line after CAMERA_ID (it may contain spaces).
      const std::string& raw = lines.text[i - 1];
      size_t at = 0;
      for (int k = 0; k < 9; ++k) {
        at = raw.find_first_not_of(" \t", at);
        at = raw.find_first_of(" \t", at);
      }
      std::string name = raw.substr(raw.find_first_not_of(" \t", at));
      name.erase(name.find_last_not_of(" \t") + 1);

      Frame f;
      f.name = std::filesystem::path(name).stem().string();
      f.image_path = image_dir / name;
      f.intrinsics = cam->second.intrinsics;
      f.camera_to_world = colmap_to_camera_to_world({v[0], v[1], v[2], v[3]}, {v[4], v[5], v[6]});
      check_camera_matrix(f.camera_to_world, images_txt, "image " + t[0], ln);
      std::error_code ec;
      if (!std::filesystem::is_regular_file(f.image_path, ec))
        throw Error(images_txt, "image " + t[0] + ": file " + f.image_path.string() + " not found", ln);
      if (!mask_dir.empty()) {
        for (const auto& candidate : {mask_dir / (f.name + ".png"), mask_dir / (name + ".png")})
          if (std::filesystem::is_regular_file(candidate, ec)) {
            f.mask_path = candidate;
            break;
          }
        if (f.mask_path.empty() && warnings)
          warnings->push_back(images_txt.string() + ":" + std::to_string(ln) + ": image " + t[0] + " (" + name +
                              ") has no mask in " + mask_dir.string());
      }
      if (options.read_pixels) read_frame_pixels(f, model_dir / "cameras.txt");
      split.frames.push_back(std::move(f));
    } catch (const Error& e) {
      if (!options.skip_bad_frames) throw;
      if (warnings) warnings->push_back(std::string("skipped a frame: ") + e.what());
    }
  }
  if (split.frames.empty()) throw Error(images_txt, "no usable images");
  return split;
}

}  // namespace difftrans::io
