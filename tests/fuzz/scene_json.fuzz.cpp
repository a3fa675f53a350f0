// libFuzzer target: a scene directory's transforms JSON. The input is written
// as transforms_train.json next to a tiny images/ folder and loaded with
// cameras only (image headers read); the loader must give frames with finite, rigid cameras or an
// io::Error — never a crash, hang or sanitizer report.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "difftrans/io/dataset.hpp"

namespace {
std::filesystem::path scene_dir() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() / ("difftrans_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d / "images");
    std::filesystem::create_directories(d / "masks");
    // 8 x 8 images (the seeds declare w = h = 8): their headers are read to check the declared size
    difftrans::io::write_image(d / "images/r_0.png", difftrans::io::Image(8, 8, 0.5f));
    difftrans::io::write_image(d / "images/r_1.exr", difftrans::io::Image(8, 8, 0.5f));
    difftrans::io::write_mask(d / "masks/r_0.png", difftrans::io::Mask(8, 8, true));
    return d;
  }();
  return dir;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = scene_dir() / "transforms_train.json";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(data), std::streamsize(size));
  difftrans::io::LoadOptions options;
  options.read_pixels = false;
  std::vector<std::string> warnings;
  try {
    const auto split = difftrans::io::load_transforms(path, options, &warnings);
    for (const auto& f : split.frames)
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
          if (!std::isfinite(f.camera_to_world[c][r])) __builtin_trap();  // accepted cameras are finite
  } catch (const difftrans::io::Error&) {
  }
  return 0;
}
