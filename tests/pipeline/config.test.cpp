// The stage configurations' one list of fields: what write_fields records,
// read_fields reads back unchanged; bad values are refused naming the key;
// every setting is listed once.
#include <doctest/doctest.h>

#include <set>
#include <string>

#include "pipeline/environment.hpp"
#include "pipeline/geometry.hpp"
#include "pipeline/materials.hpp"

namespace pipeline = difftrans::pipeline;
namespace io = difftrans::io;
using difftrans::Vec3f;

namespace {

// Every key and flag of a config (nested groups as "group.key"), each once.
template <class Config>
void collect(const Config& c, std::set<std::string>& keys, std::set<std::string>& flags, const std::string& prefix = "") {
  Config::fields(c, [&](const pipeline::Field& f, const auto& value) {
    using T = std::decay_t<decltype(value)>;
    CHECK_MESSAGE(keys.insert(prefix + f.key).second, "key listed twice: " << prefix + f.key);
    if (f.flag[0]) CHECK_MESSAGE(flags.insert(f.flag).second, "flag listed twice: " << f.flag);
    if constexpr (pipeline::detail::has_fields<T>::value) collect(value, keys, flags, prefix + f.key + ".");
  });
}

}  // namespace

TEST_CASE("stage configs: a record reads back to the same settings") {
  pipeline::Stage1Config a;
  a.grid_resolution = 48;
  a.box_lo = Vec3f(-1.0f, -2.0f, -3.0f);
  a.init = pipeline::Stage1Init::sphere;
  a.smoothness = pipeline::Stage1Smoothness::edge_normal;
  a.weights.developability = 0.25f;
  a.metric_samples = 1234;
  io::Json j;
  pipeline::write_fields(a, j);
  CHECK(j["init"] == "sphere");
  CHECK(j["smoothness"] == "edge");
  CHECK(j["weights"]["developability"].get<float>() == 0.25f);
  pipeline::Stage1Config b;
  pipeline::read_fields(j, b, "geometry");
  CHECK(pipeline::describe_fields(a) == pipeline::describe_fields(b));
  CHECK(b.box_lo == a.box_lo);
  CHECK(b.init == pipeline::Stage1Init::sphere);

  pipeline::Stage2Config m;
  m.optimize_positions = true;
  m.absorption_res = 8;
  m.trace.max_depth = 7;
  m.weights.tone = 0.5f;
  m.mesh = "some/mesh.obj";
  io::Json jm;
  pipeline::write_fields(m, jm);
  pipeline::Stage2Config n;
  pipeline::read_fields(jm, n, "materials");
  CHECK(pipeline::describe_fields(m) == pipeline::describe_fields(n));
  CHECK(n.trace.max_depth == 7);

  pipeline::EnvironmentConfig e;
  e.model = pipeline::EnvironmentModel::near;
  e.field_resolutions = "16,32";
  io::Json je;
  pipeline::write_fields(e, je);
  CHECK(je["model_requested"] == "near");
  pipeline::EnvironmentConfig f;
  pipeline::read_fields(je, f, "environment");
  CHECK(pipeline::describe_fields(e) == pipeline::describe_fields(f));
}

TEST_CASE("stage configs: absent keys keep their values, bad ones are refused by name") {
  pipeline::Stage1Config c;
  pipeline::read_fields(io::Json::object(), c, "geometry");
  CHECK(pipeline::describe_fields(c) == pipeline::describe_fields(pipeline::Stage1Config{}));
  const auto refused = [](const char* text) {
    pipeline::Stage1Config x;
    try {
      pipeline::read_fields(io::Json::parse(text), x, "geometry");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  CHECK(refused(R"({"grid": 5000})") == "geometry.grid: 5000 lies outside [2.0, 1024.0]");
  CHECK(refused(R"({"grid": "big"})") == "geometry.grid: expected a number");
  CHECK(refused(R"({"init": "cube"})") == "geometry.init: 'cube' is not one of hull, sphere");
  CHECK(refused(R"({"box_lo": [1, 2]})") == "geometry.box_lo: expected [x, y, z]");
  CHECK(refused(R"({"weights": {"bce": "x"}})") == "geometry.weights.bce: expected a number");
  CHECK(refused(R"([1, 2])") == "geometry: not a JSON object");
}

TEST_CASE("stage configs: every key and option is listed once, and no option is shared between stages") {
  std::set<std::string> flags;
  std::set<std::string> k1, k2, k3;
  collect(pipeline::EnvironmentConfig{}, k1, flags);
  collect(pipeline::Stage1Config{}, k2, flags);
  collect(pipeline::Stage2Config{}, k3, flags);
  CHECK(k2.count("weights.mask") == 1);
  CHECK(flags.count("--materials-tone") == 1);  // a nested group's option
  CHECK(flags.size() >= 30);
}
