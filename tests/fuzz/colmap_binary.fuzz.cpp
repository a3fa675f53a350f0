// libFuzzer target: the COLMAP binary readers (cameras.bin, images.bin) must
// turn any bytes into a model or an io::Error naming the file — never a crash,
// a hang, an allocation the file cannot justify or a sanitizer report. The
// first byte picks the reader; the rest is the file.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "difftrans/io/colmap.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("difftrans-fuzz-colmap-" + std::to_string(::getpid()) + ".bin");
  difftrans::io::detail::write_file_bytes(file, data + 1, size - 1);
  try {
    if (data[0] & 1) {
      const auto images = difftrans::io::read_colmap_images_binary(file);
      for (const auto& im : images)
        if (im.name.empty()) __builtin_trap();  // a record without a name must have been refused
    } else {
      const auto cameras = difftrans::io::read_colmap_cameras_binary(file);
      for (const auto& [id, c] : cameras)
        if (!(c.intrinsics.width > 0 && c.intrinsics.height > 0)) __builtin_trap();
    }
  } catch (const difftrans::io::Error&) {
  }
  return 0;
}
