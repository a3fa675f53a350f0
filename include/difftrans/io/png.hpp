// 8-bit images through stb_image / stb_image_write (implementation in
// Debian's libstb): PNG in and out as sRGB, and object masks (> 127 inside).
#pragma once

#include <stb_image.h>
#include <stb_image_write.h>

#include <memory>

#include "difftrans/io/image.hpp"

namespace difftrans::io {

// 8-bit pixels as stored, `channels` per pixel, row-major from the top-left.
struct Image8 {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<std::uint8_t> data;
};

// Reads an 8-bit image (PNG; stb also reads JPEG, BMP, TGA) converted to
// `channels` per pixel (1 grey, 3 RGB, 4 RGBA; 0 = as stored). 16-bit PNGs
// are reduced to 8 bits.
inline Image8 read_image8(const std::filesystem::path& path, int channels = 0) {
  detail::require_readable(path);
  int w = 0, h = 0, n = 0;
  std::unique_ptr<stbi_uc, void (*)(void*)> pixels(stbi_load(path.string().c_str(), &w, &h, &n, channels),
                                                   stbi_image_free);
  if (!pixels) {
    const char* why = stbi_failure_reason();
    throw Error(path, std::string("cannot decode image: ") + (why ? why : "unknown reason"));
  }
  Image8 out;
  out.width = w;
  out.height = h;
  out.channels = channels > 0 ? channels : n;
  out.data.assign(pixels.get(), pixels.get() + size_t(w) * size_t(h) * size_t(out.channels));
  return out;
}

// Reads an sRGB PNG as linear RGB (alpha is dropped, grey is repeated).
inline Image read_png(const std::filesystem::path& path) {
  const Image8 raw = read_image8(path, 3);
  return from_srgb8(raw.data.data(), raw.width, raw.height, 3);
}

// Reads a mask: the image converted to grey, > level (default 127) is object.
inline Mask read_mask(const std::filesystem::path& path, int level = mask_threshold) {
  const Image8 raw = read_image8(path, 1);
  Mask mask(raw.width, raw.height);
  for (size_t i = 0; i < raw.data.size(); ++i) mask.inside[i] = raw.data[i] > level ? 1 : 0;
  return mask;
}

inline void write_png8(const std::filesystem::path& path, const Image8& image) {
  if (image.width <= 0 || image.height <= 0 || image.channels < 1 || image.channels > 4 ||
      image.data.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels))
    throw Error(path, "cannot write an empty or inconsistent image");
  if (!stbi_write_png(path.string().c_str(), image.width, image.height, image.channels, image.data.data(),
                      image.width * image.channels))
    throw Error(path, "cannot write PNG");
}

// Writes a linear image tone-mapped as docs/conventions.md says (8-bit sRGB).
inline void write_png(const std::filesystem::path& path, const Image& image) {
  check_shape(image, path);
  check_finite(image, path);
  write_png8(path, {image.width, image.height, 3, tone_map(image)});
}

// Writes a mask as 8-bit grey, 255 inside and 0 outside.
inline void write_mask(const std::filesystem::path& path, const Mask& mask) {
  Image8 out{mask.width, mask.height, 1, std::vector<std::uint8_t>(mask.inside.size())};
  for (size_t i = 0; i < out.data.size(); ++i) out.data[i] = mask.inside[i] ? 255 : 0;
  write_png8(path, out);
}

}  // namespace difftrans::io
