// Stages of `difftrans reconstruct` that live in their own files: options
// (added to the subcommand) and the function that runs the stage.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "command.hpp"

#include "difftrans/io/dataset.hpp"

namespace difftrans::cli {

// What every long stage shares: checkpoints and starting afresh. A stage
// saves its state to DIR/checkpoint_STAGE.bin every `checkpoint_every`
// iterations (and at least once a minute) and when SIGINT or SIGTERM stops
// it; the next run with the same settings goes on from there.
struct RunOptions {
  bool restart = false;          // ignore checkpoints and finished results in DIR
  int checkpoint_every = 50;     // iterations between checkpoints
};

void add_run_options(CLI::App* cmd, RunOptions& opt);

// The environment from the background pixels: stage_environment.cpp.
struct EnvironmentStageOptions {
  std::string model = "auto";     // auto (scene.json's "environment", else distant) | distant | near
  int margin = 2;                 // pixels around the mask left out
  // distant: equirectangular map
  int env_width = 0;              // 0: from the images' angular resolution (capped at env_max_width)
  int env_max_width = 512;
  double smoothness = 1e-3;
  // near: radiance field (scene/radiance_field_fit.hpp)
  std::string field_resolutions = "32,64";      // grid vertices per axis, one level each (a 128 level overfits 50 views)
  std::string field_iterations = "300,300";     // per level
  int field_batch = 4096;
  float field_extent = 1.4f;      // box half-size / the farthest training camera's distance from the object's centre
  float field_lr = 0.1f;
  float field_tv = 1e-9f;         // smoothness prior weight (density and colour)
  float field_sparsity = 1e-6f;   // density sparsity prior weight
  std::uint64_t field_seed = 1;
};

void add_environment_options(CLI::App* cmd, EnvironmentStageOptions& opt);

// Fits the environment to the training views' background pixels, writing into `out`; returns the stage's JSON record.
io::Json environment_stage(const io::Scene& scene, const std::filesystem::path& out, const EnvironmentStageOptions& opt);

// Stage 1 (geometry from masks): stage_geometry.cpp.
struct GeometryStageOptions {
  int grid = 64;                 // FlexiCubes cubes per axis
  int iterations = 1000;         // FlexiCubes iterations
  int views_per_iteration = 8;   // training views per FlexiCubes iteration
  int refine_iterations = 1000;  // large-steps iterations after remeshing
  int refine_views = 8;          // training views per refinement iteration
  float lr = 0.01f;
  float adam_eps = 1e-8f;
  float lr_decay = 0.0002f;      // lr0 · 10^(−lr_decay · i)
  std::string schedule;          // "MASK_ONLY,PERIOD,DEVELOPABILITY_START"; empty: scaled from the paper's by --iterations
  std::string weights;           // NAME=VALUE,... overriding Stage1Weights (mask, dilation, smoothness, bce, area, dev, developability, weight_l1)
  float margin = 0.1f;           // around the unit box when scene.json has no aabb
  std::string smoothness = "screen";  // screen | edge | none
  std::string init = "hull";     // hull (the masks' visual hull) | sphere (the paper's start)
  int carve_margin = 0;          // carving (Stage1Config::carve_margin): background pixels eroded by this many; < 0: off
  int sheet_views = 4;           // rows of the silhouette comparison strip
  std::size_t metric_samples = 200000;
};

void add_geometry_options(CLI::App* cmd, GeometryStageOptions& opt);

// Runs stage 1 on the scene's training views, writing into `out`; returns the stage's JSON record.
io::Json geometry_stage(const io::Scene& scene, const std::filesystem::path& out, const GeometryStageOptions& opt,
                        const RunOptions& run);

// Stage 2 (IoR, absorption grid and, optionally, vertices through the tracer): stage_materials.cpp.
struct MaterialsStageOptions {
  int iterations = 1000;
  int rays = 8192;               // training rays per iteration
  int freeze = 300;              // iterations before the vertices move (with geometry)
  bool geometry = false;         // move the vertices too (experimental)
  float ior_init = 1.5f;
  float lr_ior = 3e-3f;          // after the warm-up (freeze) iterations, which use 1e-4
  float lr_absorption = 0.02f;   // on the raw (softplus) absorption parameters
  float lr_vertices = 1e-3f;     // large steps / AdamUniform on u = (I + λL) x
  double lambda = 19.0;          // λ of the large-steps parameterization
  float tone = 0.1f;             // weight of the tone (colour direction) loss; the colour L2 has weight 1
  int absorption_res = 16;       // grid vertices per axis
  std::string mesh;              // default: DIR/mesh_stage1.obj
  int test_spp_axis = 2;         // test renders: n x n samples per pixel
};

void add_materials_options(CLI::App* cmd, MaterialsStageOptions& opt);

// Runs stage 2 from the stage-1 mesh and the recovered environment in `out`; returns the stage's JSON record.
io::Json materials_stage(const io::Scene& scene, const std::filesystem::path& out, const MaterialsStageOptions& opt,
                         const RunOptions& run);

}  // namespace difftrans::cli
