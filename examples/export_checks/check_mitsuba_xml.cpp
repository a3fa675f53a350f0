// Test of difftrans export --format mitsuba: parses scene.xml with pugixml and
// checks that it is well-formed, uses only the elements and plugin types the
// exporter writes, references only files that are present beside it (by
// relative paths) and ids it defines, gives a PLY mesh its vertex normals,
// and agrees with the material (IoR; an absorbing medium exactly when the
// material absorbs, sigma_t · scale its sigma or, for a grid, within its
// range) and with the scene's cameras (one sensor per view of the split:
// looking where the camera looks, image right where its right is, the same
// horizontal field of view and film size).
// Prints "check_mitsuba_xml: ok" or the failures, and exits non-zero on any.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <pugixml.hpp>

#include "difftrans/io/dataset.hpp"
#include "difftrans/core/constants.hpp"
#include "difftrans/io/material.hpp"
#include "expected_material.hpp"

namespace {

namespace fs = std::filesystem;

int failures = 0;

void expect(bool ok, const std::string& what) {
  if (!ok) {
    std::cerr << "check_mitsuba_xml: FAILED: " << what << std::endl;
    ++failures;
  }
}

std::vector<double> numbers(const std::string& text) {
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream in(s);
  std::vector<double> v;
  for (double x; in >> x;) v.push_back(x);
  return v;
}

// The value of the property child <TAG name="NAME" value="..."/>, or "".
std::string property(const pugi::xml_node& node, const char* tag, const char* name) {
  for (const pugi::xml_node& c : node.children(tag))
    if (std::string(c.attribute("name").value()) == name) return c.attribute("value").value();
  return "";
}

const std::map<std::string, std::set<std::string>> plugin_types = {
    {"integrator", {"path", "volpath"}}, {"emitter", {"envmap", "constant"}}, {"bsdf", {"dielectric"}},
    {"medium", {"homogeneous"}},         {"shape", {"ply", "obj"}},           {"sensor", {"perspective"}},
    {"sampler", {"independent"}},        {"film", {"hdrfilm"}},               {"rfilter", {"box"}}};
const std::set<std::string> property_tags = {"string", "float", "integer", "rgb", "boolean"};
const std::set<std::string> other_tags = {"scene", "transform", "matrix", "ref"};

void walk(const pugi::xml_node& node, const fs::path& dir, std::set<std::string>& ids, std::vector<std::string>& refs) {
  for (const pugi::xml_node& c : node.children()) {
    if (c.type() != pugi::node_element) continue;
    const std::string tag = c.name();
    if (plugin_types.count(tag)) {
      const std::string type = c.attribute("type").value();
      expect(plugin_types.at(tag).count(type) == 1, "<" + tag + " type=\"" + type + "\"> is not a type the exporter writes");
    } else if (property_tags.count(tag)) {
      expect(!c.attribute("name").empty() && !c.attribute("value").empty(), "<" + tag + "> without name or value");
      if (tag == "string" && std::string(c.attribute("name").value()) == "filename") {
        const fs::path file = c.attribute("value").value();
        expect(file.is_relative(), "filename " + file.string() + " is not relative to the scene file");
        expect(fs::is_regular_file(dir / file), "filename " + file.string() + " is not present beside the scene file");
      }
    } else if (tag == "ref") {
      refs.push_back(c.attribute("id").value());
    } else if (tag == "matrix") {
      expect(numbers(c.attribute("value").value()).size() == 16, "<matrix> without 16 numbers");
    } else if (!other_tags.count(tag)) {
      expect(false, "<" + tag + "> is not an element the exporter writes");
    }
    if (!c.attribute("id").empty() && tag != "ref") {
      expect(ids.insert(c.attribute("id").value()).second, std::string("id '") + c.attribute("id").value() + "' repeats");
    }
    walk(c, dir, ids, refs);
  }
}

// Column `col` of to_world's upper 3 x 4 part (row-major text).
difftrans::Vec3d column(const std::vector<double>& m, int col) { return {m[size_t(col)], m[size_t(4 + col)], m[size_t(8 + col)]}; }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Checks a Mitsuba 3 scene written by difftrans export"};
  std::string xml, scene_dir, split = "test";
  app.add_option("xml", xml, "the exported scene.xml")->required();
  difftrans::checks::ExpectedMaterial expected;
  expected.add(app);
  app.add_option("--scene", scene_dir, "the scene directory whose cameras became the sensors");
  app.add_option("--split", split, "which split of --scene")->check(CLI::IsMember({"train", "test", "all"}));
  CLI11_PARSE(app, argc, argv);
  using namespace difftrans;
  const io::Material material = expected.resolve();

  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_file(xml.c_str());
  if (!parsed) {
    std::cerr << "check_mitsuba_xml: FAILED: " << xml << ": not well-formed XML: " << parsed.description()
              << " at byte " << parsed.offset << std::endl;
    return 1;
  }
  const pugi::xml_node root = doc.document_element();
  expect(std::string(root.name()) == "scene", "the root element is <" + std::string(root.name()) + ">, not <scene>");
  expect(std::string(root.attribute("version").value()) == "3.0.0", "scene version is not 3.0.0");
  std::set<std::string> ids;
  std::vector<std::string> refs;
  walk(root, fs::path(xml).parent_path(), ids, refs);
  for (const auto& r : refs) expect(ids.count(r) == 1, "<ref id=\"" + r + "\"> names no element");

  // material
  const pugi::xml_node bsdf = root.child("bsdf");
  const std::vector<double> ior = numbers(property(bsdf, "float", "int_ior"));
  expect(ior.size() == 1 && std::abs(ior[0] - material.ior) < 1e-6, "dielectric int_ior differs from the material's IoR");
  expect(property(bsdf, "float", "ext_ior") == "1", "ext_ior is not 1");
  const pugi::xml_node medium = root.child("medium");
  const pugi::xml_node shape = root.child("shape");
  expect(!shape.empty() && !shape.child("ref").empty(), "no shape with a BSDF");
  bool absorbing = false;
  if (material.absorption == io::AbsorptionType::homogeneous)
    absorbing = material.sigma.x > 0 || material.sigma.y > 0 || material.sigma.z > 0;
  if (material.absorption == io::AbsorptionType::grid)
    absorbing = std::any_of(material.grid.sigma.begin(), material.grid.sigma.end(), [](float s) { return s > 0; });
  expect(absorbing == !medium.empty(), absorbing ? "the material absorbs but there is no medium" : "clear glass has a medium");
  const std::string integrator = root.child("integrator").attribute("type").value();
  expect(integrator == (absorbing ? "volpath" : "path"), "integrator '" + integrator + "' for a " +
                                                             (absorbing ? "medium" : "scene without a medium"));
  if (!medium.empty()) {
    std::vector<double> sigma = numbers(property(medium, "rgb", "sigma_t"));
    const std::string scale_text = property(medium, "float", "scale");
    const std::vector<double> scale = numbers(scale_text.empty() ? "1" : scale_text);
    expect(scale.size() == 1, "the medium's scale is not a number");
    for (double& v : sigma) v *= scale.empty() ? 1.0 : scale[0];
    expect(std::all_of(sigma.begin(), sigma.end(), [&](double v) { return v >= 0 && v <= scale[0] * (1 + 1e-9); }),
           "sigma_t is not in [0, 1] (Mitsuba reads RGB values as reflectances)");
    const std::vector<double> albedo = numbers(property(medium, "rgb", "albedo"));
    expect(albedo == std::vector<double>{0, 0, 0}, "the medium's albedo is not 0");
    expect(sigma.size() == 3, "sigma_t is not 3 numbers");
    bool interior = false;
    for (const pugi::xml_node& r : shape.children("ref"))
      interior = interior || (std::string(r.attribute("name").value()) == "interior" &&
                              std::string(r.attribute("id").value()) == medium.attribute("id").value());
    expect(interior, "the shape does not reference the medium as its interior");
    for (int c = 0; c < 3 && sigma.size() == 3; ++c) {
      if (material.absorption == io::AbsorptionType::homogeneous) {
        expect(std::abs(sigma[size_t(c)] - material.sigma[c]) <= 1e-6 * (1 + material.sigma[c]),
               "sigma_t differs from the material's sigma in channel " + std::to_string(c));
      } else {
        float lo = std::numeric_limits<float>::infinity(), hi = 0.0f;
        for (std::size_t i = std::size_t(c); i < material.grid.sigma.size(); i += 3)
          lo = std::min(lo, material.grid.sigma[i]), hi = std::max(hi, material.grid.sigma[i]);
        expect(sigma[size_t(c)] >= lo * (1 - 1e-6) && sigma[size_t(c)] <= hi * (1 + 1e-6),
               "grid: sigma_t outside the grid's range in channel " + std::to_string(c));
      }
    }
  }
  expect(!root.child("emitter").empty(), "no emitter");
  // a PLY mesh carries the renderer's vertex normals (Mitsuba would compute others)
  if (std::string(shape.attribute("type").value()) == "ply") {
    const fs::path ply = fs::path(xml).parent_path() / property(shape, "string", "filename");
    std::ifstream in(ply, std::ios::binary);
    std::string header;
    for (std::string line; std::getline(in, line) && line != "end_header";) header += line + "\n";
    expect(header.find("property float nx\nproperty float ny\nproperty float nz\n") != std::string::npos,
           ply.string() + " has no vertex normals");
  }

  // sensors against the scene's cameras
  std::vector<pugi::xml_node> sensors;
  for (const pugi::xml_node& s : root.children("sensor")) sensors.push_back(s);
  if (!scene_dir.empty()) {
    io::LoadOptions lo;
    lo.read_pixels = false;
    const io::Scene scene = io::load_scene(scene_dir, lo);
    std::vector<io::Frame> frames;
    for (const io::Split* s : {&scene.train, &scene.test})
      if (split == "all" || (split == "train") == (s == &scene.train))
        for (const auto& f : s->frames)
          if (!f.environment_only) frames.push_back(f);
    expect(sensors.size() == frames.size(), std::to_string(sensors.size()) + " sensors for " +
                                                std::to_string(frames.size()) + " cameras");
    for (std::size_t i = 0; i < std::min(sensors.size(), frames.size()); ++i) {
      const io::Frame& f = frames[i];
      const pugi::xml_node s = sensors[i];
      const std::string name = "sensor " + std::string(s.attribute("id").value());
      const std::vector<double> m = numbers(s.child("transform").child("matrix").attribute("value").value());
      if (m.size() != 16) continue;
      // Mitsuba: the sensor looks down its +Z; its image's right is its -X; its up is +Y
      const Vec3d look = column(m, 2), right = -column(m, 0), up = column(m, 1), position = column(m, 3);
      expect(glm::length(look - f.forward()) < 1e-6, name + " does not look where camera " + f.name + " looks");
      expect(glm::length(right - Vec3d(f.camera_to_world[0])) < 1e-6, name + ": image right differs from camera " + f.name + "'s");
      expect(glm::length(up - f.up()) < 1e-6, name + ": up differs from camera " + f.name + "'s");
      expect(glm::length(position - f.position()) < 1e-6, name + ": position differs");
      expect(property(s, "string", "fov_axis") == "x", name + ": fov_axis is not x");
      const std::vector<double> fov = numbers(property(s, "float", "fov"));
      const double fov_x = 2.0 * std::atan(0.5 * f.intrinsics.width / f.intrinsics.fx) * 180.0 / difftrans::pi_v<double>;
      expect(fov.size() == 1 && std::abs(fov[0] - fov_x) < 1e-5, name + ": fov differs from camera " + f.name + "'s");
      const pugi::xml_node film = s.child("film");
      expect(property(film, "integer", "width") == std::to_string(f.intrinsics.width) &&
                 property(film, "integer", "height") == std::to_string(f.intrinsics.height),
             name + ": film size differs from camera " + f.name + "'s");
      expect(std::string(film.child("rfilter").attribute("type").value()) == "box", name + ": the film's filter is not box");
    }
  }
  if (failures) {
    std::cerr << "check_mitsuba_xml: " << failures << " failures in " << xml << std::endl;
    return 1;
  }
  std::cout << "check_mitsuba_xml: ok: " << sensors.size() << " sensors, " << ids.size() << " ids, integrator "
            << integrator << (absorbing ? ", absorbing medium" : ", no medium") << std::endl;
  return 0;
}
