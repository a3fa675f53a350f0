#!/usr/bin/env bash
# The main job on an embedded default scene: installs the dependencies, builds
# the difftrans command (Release), renders the spot-clear benchmark scene
# (test variant), renders its ground truth again from the test cameras and
# under another environment map (a relight), and evaluates the images.
# Usage: scripts/demo.sh [build-dir]   (default: build/release; output in out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
jobs=$(nproc 2>/dev/null || echo 2)
out=out/demo
data=${DIFFTRANS_DATA:-../shared/data}
start=$(date +%s)

bash scripts/install-deps.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$jobs" --target difftrans_command
dt="$build/examples/difftrans"
export DIFFTRANS_DATA="$data"

step() { echo; echo "== $*"; }

step "synth: spot-clear, test variant (64 x 64, 24 + 8 views, 16 samples per pixel, depth 16)"
"$dt" synth --preset spot-clear --variant test --out "$out/scene" --overwrite
"$dt" info "$out/scene"

step "render: the ground truth from the test cameras under its training environment (reproduces the scene)"
"$dt" render --mesh "$out/scene/gt/mesh.obj" --material "$out/scene/gt/material.json" \
  --env "$out/scene/gt/envmap.hdr" --scene "$out/scene" --split test --out "$out/render" --overwrite > "$out/render.json"
"$dt" evaluate --pred-images "$out/render/images" --scene "$out/scene" --out "$out/render/evaluate.json" > /dev/null
echo "render: metrics against the scene's test images in $out/render/evaluate.json (identical images: psnr null = infinite)"

step "relight: the ground truth under blouberg_sunrise_2, compared with the training-environment images"
"$dt" render --mesh "$out/scene/gt/mesh.obj" --material "$out/scene/gt/material.json" \
  --env "$data/envmaps/blouberg_sunrise_2_1k.hdr" --scene "$out/scene" --split test --out "$out/relight" --overwrite \
  > "$out/relight.json"

step "evaluate: the relit images against the scene's test images"
"$dt" evaluate --pred-images "$out/relight/images" --scene "$out/scene" --out "$out/relight/evaluate.json" |
  grep -E '^  "(psnr|psnr_mask|ssim|count)"'

step "reconstruct: the environment (distant map fitted to the out-of-mask pixels) and stage-1 geometry
   (FlexiCubes 32³ from the masks, 200 + 200 iterations: a short run; the defaults are 64³, 1000 + 1000)"
"$dt" reconstruct "$out/scene" --out "$out/reconstruct" --stages environment,geometry --grid 32 \
  --iterations 200 --refine-iterations 200 --restart |
  grep -E '"(psnr_background_test|psnr_map_seen|seen_fraction|chamfer|f1|genus)"'

echo
echo "demo: done in $(( $(date +%s) - start )) s. Pictures:"
echo "  environment        $out/reconstruct/envmap.hdr, $out/reconstruct/environment_comparison.png"
echo "  geometry           $out/reconstruct/mesh_stage1.obj, stage1_silhouettes.png (mask | silhouette | difference), stage1_loss.svg"
echo "  scene previews     $out/scene/previews/*.png (masks in $out/scene/masks/)"
echo "  relit previews     $out/relight/previews/*.png"
echo "  contact sheet      $out/relight/contact_sheet.png (training-environment image | relit | error)"
echo "  metrics            $out/render/evaluate.json, $out/relight/evaluate.json"
