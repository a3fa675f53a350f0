// difftrans export --format mitsuba: a Mitsuba 3 scene (scene.xml, version
// 3.0.0) that renders what difftrans render renders: the mesh beside it with a
// dielectric BSDF and, when absorbing, a purely absorbing homogeneous interior
// medium; the environment as an envmap (or constant) emitter, resampled and
// turned to match our equirectangular convention; each camera as a perspective sensor; a path
// (or, with a medium, volpath) integrator of the same depth. Every file is
// referenced relative to scene.xml.
#include "export.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <string>

#include "stage_output.hpp"

namespace difftrans::cli {
namespace {

namespace fs = std::filesystem;

std::string num(double x) {
  char b[40];
  std::snprintf(b, sizeof(b), "%.9g", x);
  return b;
}

std::string rgb_text(const Vec3d& c) { return num(c.x) + ", " + num(c.y) + ", " + num(c.z); }

// Text for an XML attribute value or comment.
std::string xml_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}
// Text for a comment: as it is, except that a comment may not contain "--".
std::string comment_text(const std::string& s) {
  std::string out = s;
  for (std::size_t p; (p = out.find("--")) != std::string::npos;) out.replace(p, 2, "- -");
  return out;
}

// A 4x4 matrix (glm, column-major) as Mitsuba's row-major "m00 m01 ... m33".
std::string matrix_text(const Mat4<double>& m) {
  std::string s;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) s += (s.empty() ? "" : " ") + num(m[c][r]);
  return s;
}

// Our cameras look down -Z with +X to the right of the image and +Y up
// (OpenGL); Mitsuba's perspective sensor looks down +Z with +Y up and +X to
// the image's left. Its camera axes are ours with X and Z negated: a half
// turn about Y, so to_world = camera_to_world · diag(-1, 1, -1, 1).
Mat4<double> mitsuba_sensor_to_world(const Mat4<double>& camera_to_world) {
  Mat4<double> m = camera_to_world;
  m[0] = -m[0];
  m[2] = -m[2];
  return m;
}

// A sensor id: the frame's name (letters, digits, '_', '-', '.'), unique.
std::string sensor_id(const std::string& name, std::set<std::string>& used) {
  std::string id;
  for (char c : name) id += (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.') ? c : '_';
  if (id.empty() || !std::isalpha(static_cast<unsigned char>(id[0]))) id = "view_" + id;
  std::string unique = id;
  for (int k = 2; used.count(unique); ++k) unique = id + "_" + std::to_string(k);
  used.insert(unique);
  return unique;
}

// The map resampled for Mitsuba's envmap. Both interpolate bilinearly and
// wrap in u with texel centres at u = (col + 0.5) / width, but Mitsuba puts
// row j at v = j / (rows - 1), the poles on the first and last rows, where
// ours puts row r at v = (r + 0.5) / height and holds the first and last rows
// constant within half a texel of the poles. Ours is linear in v between the
// knots 0, 0.5/h, 1.5/h, ..., 1: the 2h + 1 rows at v = k / (2h) (our rows at
// odd k, the means of two neighbours at even k, our first and last rows at
// the poles) make Mitsuba's lookup equal to ours.
io::Image mitsuba_envmap(const io::Image& map) {
  const int w = map.width, h = map.height;
  io::Image out(w, 2 * h + 1);
  for (int k = 0; k <= 2 * h; ++k)
    for (int x = 0; x < w; ++x) {
      Vec3f c;
      if (k % 2 == 1) c = map.at(x, (k - 1) / 2);
      else if (k == 0) c = map.at(x, 0);
      else if (k == 2 * h) c = map.at(x, h - 1);
      else c = Vec3f(0.5 * (Vec3d(map.at(x, k / 2 - 1)) + Vec3d(map.at(x, k / 2))));
      out.set(x, k, c);
    }
  return out;
}

}  // namespace

io::Json write_mitsuba(const ExportInput& in, const AbsorptionSummary& absorption, const fs::path& dir) {
  io::Json files = io::Json::object();
  // the mesh with the renderer's vertex normals (PLY); an OBJ without them, Mitsuba computes its own
  const std::string mesh_name = "mesh." + in.mesh_format;
  if (in.mesh_format == "ply") {
    const std::vector<Vec3f> normals = export_vertex_normals(in.mesh);
    io::write_ply(dir / mesh_name, in.mesh, false, &normals);
  } else {
    warn("mitsuba: " + mesh_name + " carries no vertex normals; Mitsuba computes its own (angle-weighted), so the "
         "shading differs slightly from difftrans render's (--mesh-format ply keeps them)");
    io::write_mesh(dir / mesh_name, in.mesh);
  }
  files["mesh"] = mesh_name;

  // the environment map, resampled to Mitsuba's rows (float OpenEXR), or a constant
  const std::string env_name = in.env && !in.env->file.empty() ? "envmap.exr" : "";
  if (!env_name.empty()) {
    if (in.env->map.width % 2 != 0)
      warn("mitsuba: " + in.env->file.string() + " has an odd width (" + std::to_string(in.env->map.width) +
           "): the half turn that aligns Mitsuba's u with ours is off by half a texel");
    io::write_image(dir / env_name, mitsuba_envmap(in.env->map));
    files["environment"] = env_name;
  }

  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
    << "<!-- Written by difftrans export: mesh " << comment_text(in.mesh_source.string()) << ", material "
    << comment_text(in.material_source) << ". Render a sensor with mitsuba.render(scene, sensor=i). -->\n"
    << "<scene version=\"3.0.0\">\n";

  // integrator: max_depth counts the emitter's vertex, so N surface interactions are N + 1
  const bool medium = absorption.absorbing();
  x << "  <!-- " << in.max_depth << " surface interactions per path, as difftrans render --max-depth "
    << in.max_depth << " (Mitsuba's max_depth also counts the emitter) -->\n"
    << "  <integrator type=\"" << (medium ? "volpath" : "path") << "\">\n"
    << "    <integer name=\"max_depth\" value=\"" << in.max_depth + 1 << "\"/>\n"
    << "    <integer name=\"rr_depth\" value=\"" << in.max_depth + 1 << "\"/>\n"
    << "  </integrator>\n";

  // environment
  if (!env_name.empty()) {
    x << "  <!-- " << comment_text(in.env->file.string()) << ", equirectangular, +Y up, its rows resampled to Mitsuba's\n"
      << "       (row j at v = j / (rows - 1)). Ours puts -Z at the centre, u = 0.5 + atan2(x, -z) / 2pi; Mitsuba's\n"
      << "       lookup puts it on the seam, u = atan2(x, -z) / 2pi: a half turn about +Y maps one onto the other. -->\n"
      << "  <emitter type=\"envmap\">\n"
      << "    <string name=\"filename\" value=\"" << xml_escape(env_name) << "\"/>\n"
      << "    <transform name=\"to_world\">\n"
      << "      <matrix value=\"-1 0 0 0 0 1 0 0 0 0 -1 0 0 0 0 1\"/>\n"
      << "    </transform>\n"
      << "  </emitter>\n";
  } else if (in.env) {
    x << "  <emitter type=\"constant\">\n"
      << "    <rgb name=\"radiance\" value=\"" << rgb_text(Vec3d(in.env->constant)) << "\"/>\n"
      << "  </emitter>\n";
  }

  // the object
  x << "  <bsdf type=\"dielectric\" id=\"glass\">\n"
    << "    <float name=\"int_ior\" value=\"" << num(in.material.ior) << "\"/>\n"
    << "    <float name=\"ext_ior\" value=\"1\"/>\n"
    << "  </bsdf>\n";
  if (medium) {
    // Mitsuba reads an RGB sigma_t as a reflectance (each channel in [0, 1]): the largest channel goes to scale
    const Vec3d& sigma = absorption.sigma;
    const double scale = std::max(sigma.x, std::max(sigma.y, sigma.z));
    x << "  <!-- " << comment_text(absorption.how) << ": sigma = sigma_t * scale = (" << rgb_text(sigma) << ")\n"
      << "       per unit length of the mesh's coordinates; albedo 0: it absorbs and does not scatter\n"
      << "       (Beer-Lambert, as difftrans renders it). -->\n"
      << "  <medium type=\"homogeneous\" id=\"interior\">\n"
      << "    <rgb name=\"sigma_t\" value=\"" << rgb_text(sigma / scale) << "\"/>\n"
      << "    <float name=\"scale\" value=\"" << num(scale) << "\"/>\n"
      << "    <rgb name=\"albedo\" value=\"0, 0, 0\"/>\n"
      << "  </medium>\n";
  } else if (absorption.type != "none") {
    x << "  <!-- " << comment_text(absorption.how) << ": zero, no medium -->\n";
  }
  x << "  <shape type=\"" << in.mesh_format << "\" id=\"object\">\n"
    << "    <string name=\"filename\" value=\"" << xml_escape(mesh_name) << "\"/>\n"
    << "    <ref name=\"bsdf\" id=\"glass\"/>\n";
  if (medium) x << "    <ref name=\"interior\" id=\"interior\"/>\n";
  x << "  </shape>\n";

  // sensors
  std::set<std::string> ids;
  io::Json sensors = io::Json::array();
  bool warned_aspect = false;
  for (const io::Frame& f : in.cameras) {
    const io::Intrinsics& k = f.intrinsics;
    if (std::abs(k.fx - k.fy) > 1e-6 * k.fx && !warned_aspect) {
      warn("mitsuba: camera " + f.name + " has fx != fy; Mitsuba's perspective sensor has square pixels (fov from fx)");
      warned_aspect = true;
    }
    const std::string id = sensor_id(f.name, ids);
    sensors.push_back(id);
    const double fov_x = k.fov_x() * 180.0 / pi_v<double>;
    // Mitsuba's principal point lies at (0.5 - offset_x, 0.5 - offset_y) of the film's width and height
    const double off_x = 0.5 - k.cx / k.width, off_y = 0.5 - k.cy / k.height;
    x << "  <sensor type=\"perspective\" id=\"" << xml_escape(id) << "\">\n"
      << "    <string name=\"fov_axis\" value=\"x\"/>\n"
      << "    <float name=\"fov\" value=\"" << num(fov_x) << "\"/>\n";
    if (std::abs(off_x) > 1e-9) x << "    <float name=\"principal_point_offset_x\" value=\"" << num(off_x) << "\"/>\n";
    if (std::abs(off_y) > 1e-9) x << "    <float name=\"principal_point_offset_y\" value=\"" << num(off_y) << "\"/>\n";
    x << "    <transform name=\"to_world\">\n"
      << "      <matrix value=\"" << matrix_text(mitsuba_sensor_to_world(f.camera_to_world)) << "\"/>\n"
      << "    </transform>\n"
      << "    <sampler type=\"independent\">\n"
      << "      <integer name=\"sample_count\" value=\"" << in.spp << "\"/>\n"
      << "    </sampler>\n"
      << "    <film type=\"hdrfilm\">\n"
      << "      <integer name=\"width\" value=\"" << k.width << "\"/>\n"
      << "      <integer name=\"height\" value=\"" << k.height << "\"/>\n"
      << "      <string name=\"pixel_format\" value=\"rgb\"/>\n"
      << "      <rfilter type=\"box\"/>\n"
      << "    </film>\n"
      << "  </sensor>\n";
  }
  x << "</scene>\n";
  const std::string text = x.str();
  io::detail::write_file_bytes(dir / "scene.xml", text.data(), text.size());
  files["scene"] = "scene.xml";
  files["sensors"] = sensors;
  progress("export: scene.xml: " + std::to_string(in.cameras.size()) + " sensors, " +
           (medium ? "volpath with an absorbing medium" : "path") + ", max_depth " + std::to_string(in.max_depth + 1));
  return files;
}

}  // namespace difftrans::cli
