// Output helpers shared by the stages of difftrans reconstruct: numbers as
// text, loss curves as SVG, meshes between flat arrays and io::Mesh.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>
#include <sys/resource.h>

#include "difftrans/io/json.hpp"
#include "difftrans/io/mesh.hpp"
#include "difftrans/metrics/mesh_quality.hpp"
#include "difftrans/metrics/normals.hpp"

namespace difftrans::cli {

inline io::Mesh to_io_mesh(const std::vector<float>& pos, const std::vector<std::int32_t>& tris) {
  io::Mesh m;
  for (std::size_t i = 0; i + 2 < pos.size(); i += 3) m.positions.emplace_back(pos[i], pos[i + 1], pos[i + 2]);
  for (std::size_t f = 0; f + 2 < tris.size(); f += 3) m.triangles.emplace_back(tris[f], tris[f + 1], tris[f + 2]);
  return m;
}

// The shading-normal error (metrics/normals.hpp) as reconstruct.json and
// evaluate write it, in degrees.
inline io::Json normal_error_json(const metrics::NormalError& e) {
  io::Json j;
  j["mean"] = e.mean_deg;
  j["median"] = e.median_deg;
  j["p90"] = e.p90_deg;
  j["rms"] = e.rms_deg;
  return j;
}

// A mesh's quality (metrics/mesh_quality.hpp) as reconstruct.json and
// evaluate write it.
inline io::Json mesh_quality_json(const metrics::MeshQuality& q) {
  return {{"mean_dihedral_degrees", q.mean_dihedral_degrees},
          {"max_dihedral_degrees", q.max_dihedral_degrees},
          {"self_intersections", q.self_intersections},
          {"genus", q.genus},
          {"components", q.components},
          {"closed", q.closed}};
}

// A short text that changes when the bytes change (FNV-1a, 64 bits): tells a
// checkpoint made from these inputs from one made from others.
template <class T>
inline std::string fingerprint(const std::vector<T>& values) {
  static_assert(std::is_trivially_copyable_v<T>, "fingerprints are taken of plain bytes");
  std::uint64_t h = 14695981039346656037ull;
  const auto* bytes = reinterpret_cast<const unsigned char*>(values.data());
  for (std::size_t i = 0; i < values.size() * sizeof(T); ++i) h = (h ^ bytes[i]) * 1099511628211ull;
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

// The process's peak resident memory so far, in MB.
inline double peak_memory_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

inline std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// The loss curves as an SVG: log10 of each series against the iteration.
inline void write_loss_svg(const std::filesystem::path& path,
                    const std::vector<std::pair<std::string, std::vector<double>>>& series) {
  const double W = 800, H = 400, L = 60, R = 20, T = 20, B = 40;
  double lo = 1e300, hi = -1e300;
  std::size_t n = 1;
  for (const auto& s : series) {
    n = std::max(n, s.second.size());
    for (double v : s.second)
      if (v > 0 && std::isfinite(v)) {
        lo = std::min(lo, std::log10(v));
        hi = std::max(hi, std::log10(v));
      }
  }
  if (!(hi >= lo)) lo = -1, hi = 0;
  if (hi - lo < 1e-6) hi = lo + 1;
  lo = std::floor(lo), hi = std::ceil(hi);
  const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd"};
  std::ofstream f(path);
  f << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H << "\" font-family=\"sans-serif\" "
    << "font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  for (double d = lo; d <= hi + 1e-9; d += 1) {
    const double y = T + (H - T - B) * (1 - (d - lo) / (hi - lo));
    f << "<line x1=\"" << L << "\" x2=\"" << W - R << "\" y1=\"" << y << "\" y2=\"" << y << "\" stroke=\"#ddd\"/>"
      << "<text x=\"4\" y=\"" << y + 4 << "\">1e" << int(d) << "</text>\n";
  }
  f << "<text x=\"" << W / 2 << "\" y=\"" << H - 8 << "\">iteration (0 .. " << n - 1 << ")</text>\n";
  for (std::size_t k = 0; k < series.size(); ++k) {
    f << "<polyline fill=\"none\" stroke-width=\"1\" stroke=\"" << colors[k % 4] << "\" points=\"";
    const auto& v = series[k].second;
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!(v[i] > 0) || !std::isfinite(v[i])) continue;
      const double x = L + (W - L - R) * double(i) / double(std::max<std::size_t>(1, n - 1));
      const double y = T + (H - T - B) * (1 - (std::log10(v[i]) - lo) / (hi - lo));
      f << fixed(x, 1) << ',' << fixed(y, 1) << ' ';
    }
    f << "\"/>\n<text x=\"" << W - R - 220 << "\" y=\"" << T + 16 * (k + 1) << "\" fill=\"" << colors[k % 4] << "\">"
      << series[k].first << "</text>\n";
  }
  f << "</svg>\n";
}

}  // namespace difftrans::cli
