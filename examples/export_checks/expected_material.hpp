// The material the export checks compare against: a material.json
// (--material) or, for a material given on difftrans export's command line,
// --ior with --sigma R,G,B (homogeneous; 0,0,0 is clear glass).
#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "difftrans/io/material.hpp"

namespace difftrans::checks {

struct ExpectedMaterial {
  std::string file;
  std::optional<double> ior;
  std::string sigma;

  void add(CLI::App& app) {
    app.add_option("--material", file, "the material.json it was exported from");
    app.add_option("--ior", ior, "or: the IoR it was exported with");
    app.add_option("--sigma", sigma, "with --ior: the homogeneous absorption R,G,B (0,0,0: clear)");
  }

  io::Material resolve() const {
    if (!file.empty()) return io::read_material(file);
    if (!ior) throw std::runtime_error("give --material, or --ior (with --sigma)");
    io::Material m;
    m.ior = *ior;
    std::vector<float> v;
    std::stringstream ss(sigma.empty() ? "0,0,0" : sigma);
    for (std::string part; std::getline(ss, part, ',');) v.push_back(std::stof(part));
    if (v.size() != 3) throw std::runtime_error("--sigma: '" + sigma + "' is not R,G,B");
    m.sigma = Vec3f(v[0], v[1], v[2]);
    if (v[0] > 0 || v[1] > 0 || v[2] > 0) m.absorption = io::AbsorptionType::homogeneous;
    return m;
  }
};

}  // namespace difftrans::checks
