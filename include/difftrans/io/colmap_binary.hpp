// COLMAP binary models (cameras.bin, images.bin, COLMAP's default output),
// read and written: every count checked against the bytes left, errors naming
// the file, the byte offset, the record and the value.
#pragma once

#include "difftrans/io/colmap_types.hpp"

namespace difftrans::io {

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


}  // namespace difftrans::io
