// libFuzzer target: the PLY reader (ASCII and binary) must turn any input
// into a valid mesh or an io::Error — never a crash, hang or sanitizer report.
#include <cstddef>
#include <cstdint>
#include <string>

#include "difftrans/io/ply.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> warnings;
  try {
    const difftrans::io::Mesh m = difftrans::io::parse_ply(text, "fuzz.ply", &warnings);
    for (const auto& t : m.triangles)
      for (int k = 0; k < 3; ++k)
        if (t[k] < 0 || std::size_t(t[k]) >= m.positions.size()) __builtin_trap();
  } catch (const difftrans::io::Error&) {
  }
  return 0;
}
