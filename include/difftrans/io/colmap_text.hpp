// COLMAP text models (cameras.txt, images.txt): readers whose errors name the
// file, the line and the value. Lens distortion is refused (undistort first).
#pragma once

#include "difftrans/io/colmap_types.hpp"

namespace difftrans::io {

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
  if (token.empty() || *stop != '\0') throw Error(file, std::string(what) + " " + excerpt(token) + " is not a number", line);
  if (!std::isfinite(v)) throw Error(file, std::string(what) + " " + excerpt(token) + " is not finite", line);
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
      throw Error(path, "camera id " + detail::excerpt(t[0]) + " is not an integer in 0..4294967295", ln);
    const ColmapModel* model = find_colmap_model(t[1]);
    if (!model) throw Error(path, "camera model " + detail::excerpt(t[1]) + " is not a COLMAP model (" + colmap_model_names() + ")", ln);
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
      throw Error(path, "image id " + detail::excerpt(t[0]) + " is not an integer in 0..4294967295", ln);
    im.id = std::uint32_t(id);
    double v[8];
    for (int k = 0; k < 8; ++k)
      v[k] = detail::colmap_number(t[size_t(k) + 1], path, ln, k < 4 ? "quaternion" : "translation");
    im.q_wxyz = glm::dvec4(v[0], v[1], v[2], v[3]);
    im.t = Vec3d(v[4], v[5], v[6]);
    const double cam_id = detail::colmap_number(t[8], path, ln, "camera id");
    if (cam_id != std::floor(cam_id) || cam_id < 0 || cam_id > 4294967295.0)
      throw Error(path, "camera id " + detail::excerpt(t[8]) + " is not an integer in 0..4294967295", ln);
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

}  // namespace difftrans::io
