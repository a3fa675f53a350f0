// 8-bit images through stb_image / stb_image_write (implementation in
// Debian's libstb): PNG in and out as sRGB, and object masks (> 127 inside).
#pragma once

#include <stb_image.h>
#include <stb_image_write.h>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>

#include "difftrans/io/image.hpp"

namespace difftrans::io {

// 8-bit pixels as stored, `channels` per pixel, row-major from the top-left.
struct Image8 {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<std::uint8_t> data;
};

namespace detail {

// Checks a JPEG file's structure the way stb_image would decode it, before it
// does: stb_image reads bytes missing at the end as zeros, so a cut file would
// load with grey where the data ends, and a frame header declaring 16384 x
// 16384 in a few hundred bytes would decode 3 GB of it. Refused here: image data
// with no end-of-image marker after it (in entropy-coded data a 0xFF byte is
// always followed by 0 or a restart marker, so FF D9 ends the image), and more
// pixels than the data can encode (at least one bit per 8 x 8 block).
inline void check_jpeg(const std::string& bytes, const std::filesystem::path& path) {
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(bytes[i]); };
  std::size_t at = 2;  // after SOI (FF D8)
  long long pixels = 0;
  while (true) {
    if (at + 4 > bytes.size()) throw Error(path, "truncated: the file ends inside its headers (byte " + std::to_string(at) + ")");
    if (byte(at) != 0xFF) throw Error(path, "corrupt JPEG: no marker at byte " + std::to_string(at));
    while (at + 4 <= bytes.size() && byte(at + 1) == 0xFF) ++at;  // fill bytes
    const unsigned marker = byte(at + 1);
    if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
      at += 2;
      continue;
    }
    if (marker == 0xD9) throw Error(path, "corrupt JPEG: the image ends before its image data");
    const std::size_t length = std::size_t(byte(at + 2)) << 8 | byte(at + 3);
    if (length < 2 || at + 2 + length > bytes.size())
      throw Error(path, "truncated: the file ends inside a header segment (byte " + std::to_string(at) + ")");
    const bool frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (frame && length >= 7)
      pixels = static_cast<long long>(std::size_t(byte(at + 5)) << 8 | byte(at + 6)) *
               static_cast<long long>(std::size_t(byte(at + 7)) << 8 | byte(at + 8));
    at += 2 + length;
    if (marker == 0xDA) break;  // start of scan: entropy-coded data follows
  }
  if (bytes.find("\xFF\xD9", at) == std::string::npos)
    throw Error(path, "truncated: the image data has no end-of-image marker (the file was cut at " +
                          std::to_string(bytes.size()) + " bytes?)");
  if (pixels > 512 * static_cast<long long>(bytes.size()))
    throw Error(path, "declares " + std::to_string(pixels) + " pixels, more than its " + std::to_string(bytes.size()) +
                          " bytes can encode (one bit per 8 x 8 block at the least)");
}

// Checks a PNG file's chunks before stb_image decodes it (stb_image checks no
// CRC and allocates the declared size before inflating): every chunk whole up
// to IEND, and no more pixels than the image data can inflate to (deflate
// expands at most 1032 times).
inline void check_png(const std::string& bytes, const std::filesystem::path& path) {
  const auto u32 = [&](std::size_t i) {
    return std::uint32_t(static_cast<unsigned char>(bytes[i])) << 24 | std::uint32_t(static_cast<unsigned char>(bytes[i + 1])) << 16 |
           std::uint32_t(static_cast<unsigned char>(bytes[i + 2])) << 8 | std::uint32_t(static_cast<unsigned char>(bytes[i + 3]));
  };
  std::size_t at = 8;  // after the signature
  std::uint64_t data = 0, raw = 0;
  while (true) {
    if (at + 12 > bytes.size())
      throw Error(path, "truncated: the file ends at byte " + std::to_string(bytes.size()) + " before its IEND chunk");
    const std::uint64_t length = u32(at);
    const std::string type = bytes.substr(at + 4, 4);
    if (length > bytes.size() - at - 12)
      throw Error(path, "truncated: the " + type + " chunk at byte " + std::to_string(at) + " declares " +
                            std::to_string(length) + " bytes, more than the file holds");
    if (type == "IHDR" && length >= 13) {
      static const int channels[] = {1, 0, 3, 1, 2, 0, 4};  // by colour type
      const unsigned colour = static_cast<unsigned char>(bytes[at + 17]), depth = static_cast<unsigned char>(bytes[at + 16]);
      const int n = colour < 7 ? channels[colour] : 0;
      // filtered scanlines: one filter byte each, then the packed samples
      raw = std::uint64_t(u32(at + 12)) * (1 + (std::uint64_t(u32(at + 8)) * std::uint64_t(n) * depth + 7) / 8);
    } else if (type == "IDAT") {
      data += length;
    }
    at += 12 + length;
    if (type == "IEND") break;
  }
  if (raw > 1032 * data + 1024)
    throw Error(path, "declares " + std::to_string(raw) + " bytes of pixel data, more than its " + std::to_string(data) +
                          " compressed bytes can hold");
}

}  // namespace detail

// Reads an 8-bit image (PNG; stb also reads JPEG, BMP, TGA) converted to
// `channels` per pixel (1 grey, 3 RGB, 4 RGBA; 0 = as stored). 16-bit PNGs
// are reduced to 8 bits.
inline Image8 read_image8(const std::filesystem::path& path, int channels = 0) {
  const std::string bytes = detail::read_file_text(path);
  if (bytes.size() >= 3 && bytes.compare(0, 3, "\xFF\xD8\xFF") == 0) detail::check_jpeg(bytes, path);
  if (bytes.size() >= 8 && bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) detail::check_png(bytes, path);
  int w = 0, h = 0, n = 0;
  if (bytes.size() > std::size_t(std::numeric_limits<int>::max())) throw Error(path, "file too large to decode");
  std::unique_ptr<stbi_uc, void (*)(void*)> pixels(
      stbi_load_from_memory(reinterpret_cast<const stbi_uc*>(bytes.data()), int(bytes.size()), &w, &h, &n, channels),
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
