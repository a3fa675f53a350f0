// libFuzzer target: the Radiance RGBE reader must turn any bytes into an
// image or an io::Error naming the file — never a crash, a hang (Debian 12's
// stb_image loops forever on a truncated run-length scanline unless the file
// is checked first), an allocation the file cannot justify, or a sanitizer
// report.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "difftrans/io/hdr.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("difftrans-fuzz-rgbe-" + std::to_string(::getpid()) + ".hdr");
  difftrans::io::detail::write_file_bytes(file, data, size);
  try {
    const difftrans::io::Image image = difftrans::io::read_hdr(file);
    if (image.rgb.size() != image.pixel_count() * 3) __builtin_trap();
  } catch (const difftrans::io::Error&) {
  }
  return 0;
}
