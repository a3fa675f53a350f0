// Stages of `difftrans reconstruct` that live in their own files: options
// (added to the subcommand) and the function that runs the stage.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "command.hpp"
#include "output_folder.hpp"

#include "difftrans/io/dataset.hpp"
#include "pipeline/environment.hpp"
#include "pipeline/geometry.hpp"
#include "pipeline/materials.hpp"

namespace difftrans::cli {

// What every long stage shares: checkpoints and starting afresh. A stage
// saves its state to DIR/checkpoint_STAGE.bin every `checkpoint_every`
// iterations (and at least once a minute) and when SIGINT or SIGTERM stops
// it; the next run with the same settings goes on from there.
struct RunOptions {
  bool restart = false;          // ignore checkpoints and finished results in DIR
  int checkpoint_every = 50;     // iterations between checkpoints
  std::string device = "cpu";    // where stage 2 traces its training rays: cpu, cuda or auto
};

void add_run_options(CLI::App* cmd, RunOptions& opt);

// The environment from the background pixels: stage_environment.cpp.
void add_environment_options(CLI::App* cmd, pipeline::EnvironmentConfig& config);

// Fits the environment to the training views' background pixels, writing into `out`; returns the stage's JSON record.
io::Json environment_stage(const io::Scene& scene, const std::filesystem::path& out,
                           const pipeline::EnvironmentConfig& config);

// Stage 1 (geometry from masks): stage_geometry.cpp. The config's own options,
// and two that set several of its fields at once.
struct GeometryOptions {
  pipeline::Stage1Config config;
  std::string schedule;  // "MASK_ONLY,PERIOD,DEVELOPABILITY_START"; empty: scaled from the paper's by --iterations
  std::string weights;   // NAME=VALUE,... over Stage1Weights' fields
};

void add_geometry_options(CLI::App* cmd, GeometryOptions& opt);

// Runs stage 1 on the scene's training views, writing into `out`'s work
// folder and publishing it after each checkpoint; returns the stage's JSON record.
io::Json geometry_stage(const io::Scene& scene, RunFolder& out, const GeometryOptions& opt, const RunOptions& run);

// Stage 2 (IoR, absorption grid and, optionally, vertices through the tracer): stage_materials.cpp.
void add_materials_options(CLI::App* cmd, pipeline::Stage2Config& config);

// Runs stage 2 from the stage-1 mesh and the recovered environment in `out`'s
// work folder, publishing it after each checkpoint; returns the stage's JSON record.
io::Json materials_stage(const io::Scene& scene, RunFolder& out, const pipeline::Stage2Config& config,
                         const RunOptions& run);

}  // namespace difftrans::cli
