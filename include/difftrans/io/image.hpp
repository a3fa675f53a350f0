// Linear float RGB images and binary masks, sRGB <-> linear conversion and the
// tone mapping of docs/conventions.md (exposure 1, clamp to [0, 1], sRGB curve, 8 bits).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "difftrans/core/vec.hpp"
#include "difftrans/io/error.hpp"

namespace difftrans::io {

// Linear radiance, RGB interleaved, row-major from the top-left pixel.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;

  Image() = default;
  Image(int w, int h, float fill = 0.0f) : width(w), height(h), rgb(size_t(w) * size_t(h) * 3, fill) {}
  size_t pixel_count() const { return size_t(width) * size_t(height); }
  Vec3f at(int x, int y) const {
    const size_t i = (size_t(y) * size_t(width) + size_t(x)) * 3;
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
  void set(int x, int y, const Vec3f& c) {
    const size_t i = (size_t(y) * size_t(width) + size_t(x)) * 3;
    rgb[i] = c.x;
    rgb[i + 1] = c.y;
    rgb[i + 2] = c.z;
  }
};

// Most pixels of an image read from a file (16384 x 16384, 3 GB as float
// RGB): a size declared beyond it is refused before anything is allocated.
inline constexpr long long max_file_image_pixels = 1ll << 28;

// Object mask: 1 inside the object, 0 outside, row-major from the top-left.
struct Mask {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> inside;

  Mask() = default;
  Mask(int w, int h, bool fill = false) : width(w), height(h), inside(size_t(w) * size_t(h), fill ? 1 : 0) {}
  bool at(int x, int y) const { return inside[size_t(y) * size_t(width) + size_t(x)] != 0; }
  size_t count() const {
    size_t n = 0;
    for (const auto v : inside) n += v != 0;
    return n;
  }
};

// The mask grown (radius > 0: dilation) or shrunk (radius < 0: erosion) by
// |radius| pixels: a pixel is inside after dilation when an inside pixel lies
// within Euclidean distance |radius| of it, and stays inside after erosion
// when every pixel of the image within that distance is inside (pixels beyond
// the image's edge do not count).
inline Mask morph_mask(const Mask& mask, int radius) {
  if (radius == 0) return mask;
  const bool dilate = radius > 0;
  const int r = dilate ? radius : -radius;
  Mask out(mask.width, mask.height);
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x) {
      bool result = !dilate;
      for (int dy = -r; dy <= r && result != dilate; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (dx * dx + dy * dy > r * r || xx < 0 || yy < 0 || xx >= mask.width || yy >= mask.height) continue;
          if (mask.at(xx, yy) == dilate) {
            result = dilate;
            break;
          }
        }
      out.inside[size_t(y) * size_t(mask.width) + size_t(x)] = result ? 1 : 0;
    }
  return out;
}

// A disc of pixels: centre (x, y) in pixels, radius in pixels.
struct Disc {
  float x = 0, y = 0, radius = 0;
};

// The mask with every pixel whose centre lies within one of `discs` flipped
// (inside <-> outside): the blobs a segmentation gets wrong. A pixel in two
// discs is flipped once.
inline Mask flip_discs(const Mask& mask, const std::vector<Disc>& discs) {
  std::vector<std::uint8_t> in_disc(mask.inside.size(), 0);
  for (const Disc& d : discs) {  // the pixels of each disc's bounding box
    const int x0 = std::max(0, int(std::floor(d.x - d.radius))), x1 = std::min(mask.width - 1, int(std::ceil(d.x + d.radius)));
    const int y0 = std::max(0, int(std::floor(d.y - d.radius))), y1 = std::min(mask.height - 1, int(std::ceil(d.y + d.radius)));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const float dx = float(x) + 0.5f - d.x, dy = float(y) + 0.5f - d.y;
        if (dx * dx + dy * dy <= d.radius * d.radius) in_disc[size_t(y) * size_t(mask.width) + size_t(x)] = 1;
      }
  }
  Mask out = mask;
  for (size_t i = 0; i < out.inside.size(); ++i)
    if (in_disc[i]) out.inside[i] = out.inside[i] ? 0 : 1;
  return out;
}

// 8-bit values above this are inside the object (docs/scene-format.md: > 127).
inline constexpr int mask_threshold = 127;

// sRGB transfer curve (IEC 61966-2-1) and its inverse, on [0, 1].
inline float linear_to_srgb(float c) {
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}
inline float srgb_to_linear(float s) {
  return s <= 0.04045f ? s / 12.92f : std::pow((s + 0.055f) / 1.055f, 2.4f);
}

// Tone mapping of one linear value to 8 bits: exposure 1, clamp [0, 1], sRGB
// curve, round to nearest. NaN maps to 0.
inline std::uint8_t tone_map_value(float linear) {
  if (!(linear > 0.0f)) return 0;
  if (linear >= 1.0f) return 255;
  return std::uint8_t(std::lround(double(linear_to_srgb(linear)) * 255.0));
}

// The whole image tone-mapped: 8-bit RGB interleaved.
inline std::vector<std::uint8_t> tone_map(const Image& image) {
  std::vector<std::uint8_t> out(image.rgb.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = tone_map_value(image.rgb[i]);
  return out;
}

// Linear image from 8-bit sRGB data with `channels` per pixel (the first
// three, or the first one repeated for grey).
inline Image from_srgb8(const std::uint8_t* data, int width, int height, int channels) {
  float table[256];
  for (int v = 0; v < 256; ++v) table[v] = srgb_to_linear(float(v) / 255.0f);
  Image image(width, height);
  for (size_t p = 0; p < image.pixel_count(); ++p)
    for (int c = 0; c < 3; ++c) image.rgb[p * 3 + size_t(c)] = table[data[p * size_t(channels) + size_t(channels >= 3 ? c : 0)]];
  return image;
}

// Throws Error naming `file` and the first pixel (x, y, channel) that is NaN or infinite.
inline void check_finite(const Image& image, const std::filesystem::path& file) {
  for (size_t i = 0; i < image.rgb.size(); ++i)
    if (!std::isfinite(image.rgb[i])) {
      const size_t p = i / 3;
      static const char* channel[] = {"R", "G", "B"};
      throw Error(file, "non-finite pixel value " + std::to_string(image.rgb[i]) + " at (x " +
                            std::to_string(p % size_t(image.width)) + ", y " +
                            std::to_string(p / size_t(image.width)) + ") channel " + channel[i % 3]);
    }
}

// Throws Error unless the image has a positive size and matching storage.
inline void check_shape(const Image& image, const std::filesystem::path& file) {
  if (image.width <= 0 || image.height <= 0)
    throw Error(file, "image has no pixels (" + std::to_string(image.width) + " x " + std::to_string(image.height) + ")");
  if (image.rgb.size() != image.pixel_count() * 3)
    throw Error(file, "image storage holds " + std::to_string(image.rgb.size()) + " floats, expected " +
                          std::to_string(image.pixel_count() * 3));
}

}  // namespace difftrans::io
