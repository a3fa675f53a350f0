// Radiance RGBE (.hdr) images, linear float RGB, through stb_image /
// stb_image_write (implementation in Debian's libstb).
#pragma once

#include <stb_image.h>
#include <stb_image_write.h>

#include <memory>

#include "difftrans/io/image.hpp"

namespace difftrans::io {

inline Image read_hdr(const std::filesystem::path& path) {
  detail::require_readable(path);
  const std::string name = path.string();
  if (!stbi_is_hdr(name.c_str())) throw Error(path, "not a Radiance HDR file");
  int w = 0, h = 0, n = 0;
  std::unique_ptr<float, void (*)(void*)> pixels(stbi_loadf(name.c_str(), &w, &h, &n, 3), stbi_image_free);
  if (!pixels) {
    const char* why = stbi_failure_reason();
    throw Error(path, std::string("cannot decode HDR image: ") + (why ? why : "unknown reason"));
  }
  Image image;
  image.width = w;
  image.height = h;
  image.rgb.assign(pixels.get(), pixels.get() + size_t(w) * size_t(h) * 3);
  check_finite(image, path);
  return image;
}

// RGBE stores non-negative values; negative ones are written as 0.
inline void write_hdr(const std::filesystem::path& path, const Image& image) {
  check_shape(image, path);
  check_finite(image, path);
  if (!stbi_write_hdr(path.string().c_str(), image.width, image.height, 3, image.rgb.data()))
    throw Error(path, "cannot write HDR image");
}

}  // namespace difftrans::io
