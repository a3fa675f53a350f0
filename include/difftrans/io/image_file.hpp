// Reads and writes an image in the format its extension names: .png (sRGB
// 8-bit, converted to and from linear), .hdr and .exr (linear float).
#pragma once

#include "difftrans/io/exr.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/png.hpp"

namespace difftrans::io {

// The extensions read_image accepts, in the order a path without extension tries them.
inline const std::vector<std::string>& image_extensions() {
  static const std::vector<std::string> list = {".exr", ".hdr", ".png", ".jpg", ".jpeg"};
  return list;
}

// Width and height from the file's header, without decoding the pixels.
inline Vec2i image_size(const std::filesystem::path& path) {
  const std::string ext = detail::lower_extension(path);
  detail::require_readable(path);
  if (ext == ".exr") {
    try {
      Imf::InputFile file(path.string().c_str());
      const Imath::Box2i window = file.header().dataWindow();
      return {window.max.x - window.min.x + 1, window.max.y - window.min.y + 1};
    } catch (const std::exception& e) {
      throw Error(path, std::string("cannot read EXR header: ") + e.what());
    }
  }
  int w = 0, h = 0, n = 0;
  if (!stbi_info(path.string().c_str(), &w, &h, &n)) {
    const char* why = stbi_failure_reason();
    throw Error(path, std::string("cannot read image header: ") + (why ? why : "unknown format"));
  }
  return {w, h};
}

// Whether the image has an alpha channel that read_image8 can read (8-bit
// formats with grey + alpha or RGBA; .exr and .hdr: false). Reads the header only.
inline bool image_has_alpha(const std::filesystem::path& path) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".exr" || ext == ".hdr") return false;
  detail::require_readable(path);
  int w = 0, h = 0, n = 0;
  if (!stbi_info(path.string().c_str(), &w, &h, &n)) {
    const char* why = stbi_failure_reason();
    throw Error(path, std::string("cannot read image header: ") + (why ? why : "unknown format"));
  }
  return n == 2 || n == 4;
}

// Linear RGB, whatever the format (.png/.jpg are decoded from sRGB).
inline Image read_image(const std::filesystem::path& path) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".exr") return read_exr(path);
  if (ext == ".hdr") return read_hdr(path);
  if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") return read_png(path);
  throw Error(path, "unsupported image format '" + ext + "' (expected .png, .hdr or .exr)");
}

// .png is tone-mapped (docs/conventions.md); .hdr and .exr keep linear values.
inline void write_image(const std::filesystem::path& path, const Image& image) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".exr") return write_exr(path, image);
  if (ext == ".hdr") return write_hdr(path, image);
  if (ext == ".png") return write_png(path, image);
  throw Error(path, "unsupported image format '" + ext + "' (expected .png, .hdr or .exr)");
}

}  // namespace difftrans::io
