// Radiance RGBE (.hdr) images, linear float RGB, through stb_image /
// stb_image_write (implementation in Debian's libstb).
#pragma once

#include <stb_image.h>
#include <stb_image_write.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include "difftrans/io/image.hpp"

namespace difftrans::io {

namespace detail {

// Walks an RGBE file the way stb_image decodes it — header lines up to a blank
// one, "-Y H +X W", then per scanline either the new run-length encoding
// (2, 2, width, then four channels of runs and literals) or, from the first
// scanline that is not, flat 4-byte pixels to the end — and throws Error at
// the first byte that does not fit: a truncated or corrupt file is refused
// here, before the decoder (the stb_image of Debian 12 loops forever on a
// truncated run-length scanline and reads missing bytes as zeros), and a
// declared size the file cannot hold is refused before anything is allocated.
inline void check_rgbe(const std::string& bytes, const std::filesystem::path& path) {
  std::size_t at = 0;
  const auto line = [&]() -> std::string {
    const std::size_t end = bytes.find('\n', at);
    if (end == std::string::npos) throw Error(path, "the header ends without a blank line and a size line");
    std::string l = bytes.substr(at, end - at);
    at = end + 1;
    return l;
  };
  const std::string magic = line();
  if (magic.rfind("#?", 0) != 0) throw Error(path, "not a Radiance HDR file");
  bool rgbe = false;
  for (std::string l = line(); !l.empty(); l = line())
    if (l == "FORMAT=32-bit_rle_rgbe") rgbe = true;
    else if (l.rfind("FORMAT=", 0) == 0) throw Error(path, "unsupported " + l.substr(0, 64) + " (expected 32-bit_rle_rgbe)");
  if (!rgbe) throw Error(path, "the header has no FORMAT=32-bit_rle_rgbe line");
  const std::string size_line = line();
  long h = 0, w = 0;
  char tail = 0;
  if (std::sscanf(size_line.c_str(), "-Y %ld +X %ld%c", &h, &w, &tail) != 2 || h <= 0 || w <= 0 || h > (1 << 24) ||
      w > (1 << 24))
    throw Error(path, "size line '" + size_line.substr(0, 64) + "' is not '-Y HEIGHT +X WIDTH' with sizes in [1, 2^24]");
  const auto ends = [&](long row, const char* what) {
    throw Error(path, "truncated: the file ends inside " + std::string(what) + " of scanline " + std::to_string(row) +
                          " of " + std::to_string(h) + " (" + std::to_string(w) + " x " + std::to_string(h) +
                          " pixels, " + std::to_string(bytes.size()) + " bytes)");
  };
  const auto flat_from = [&](long row, long column) {
    const std::uint64_t need = (std::uint64_t(h - row) * std::uint64_t(w) - std::uint64_t(column)) * 4;
    if (bytes.size() - at < need) ends(row, "the uncompressed pixels");
  };
  if (w < 8 || w >= 32768) return flat_from(0, 0);
  // the smallest run-length scanline: 4 header bytes and, per channel, one
  // run of at most 127 values per 2 bytes
  const std::uint64_t min_line = 4 + 4 * 2 * ((std::uint64_t(w) + 126) / 127);
  if ((bytes.size() - at) / min_line < std::uint64_t(h))  // flat pixels (4 w bytes) are longer still
    throw Error(path, "declares " + std::to_string(w) + " x " + std::to_string(h) + " pixels but holds only " +
                          std::to_string(bytes.size() - at) + " bytes of pixel data");
  const auto byte = [&](long row, const char* what) -> unsigned {
    if (at >= bytes.size()) ends(row, what);
    return static_cast<unsigned char>(bytes[at++]);
  };
  for (long row = 0; row < h; ++row) {
    if (bytes.size() - at < 4) ends(row, "the scanline header");
    const unsigned c1 = static_cast<unsigned char>(bytes[at]), c2 = static_cast<unsigned char>(bytes[at + 1]),
                   hi = static_cast<unsigned char>(bytes[at + 2]);
    if (c1 != 2 || c2 != 2 || (hi & 0x80)) return flat_from(row, 0);  // the decoder reads flat pixels from here on
    const long len = long(hi) << 8 | long(static_cast<unsigned char>(bytes[at + 3]));
    at += 4;
    if (len != w)
      throw Error(path, "scanline " + std::to_string(row) + " declares " + std::to_string(len) + " pixels, the image " +
                            std::to_string(w));
    for (int channel = 0; channel < 4; ++channel)
      for (long i = 0; i < w;) {
        unsigned count = byte(row, "a run");
        const bool run = count > 128;
        if (run) count -= 128;
        if (count == 0 || long(count) > w - i)
          throw Error(path, "bad run-length data in scanline " + std::to_string(row) + " at byte " +
                                std::to_string(at - 1) + " (a run of " + std::to_string(count) + " where " +
                                std::to_string(w - i) + " values are left)");
        if (run) byte(row, "a run");
        else if (bytes.size() - at < count) ends(row, "a literal run");
        else at += count;
        i += long(count);
      }
  }
}

}  // namespace detail

inline Image read_hdr(const std::filesystem::path& path) {
  detail::require_readable(path);
  const std::string name = path.string();
  if (!stbi_is_hdr(name.c_str())) throw Error(path, "not a Radiance HDR file");
  detail::check_rgbe(detail::read_file_text(path), path);
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
