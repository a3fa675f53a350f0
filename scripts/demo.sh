#!/usr/bin/env bash
# The main job on an embedded default scene: installs the dependencies, builds
# the difftrans command (Release), renders the spot-clear benchmark scene
# (test variant), renders its ground truth again from the test cameras and
# under another environment map (a relight), evaluates the images, then
# reconstructs it (environment, stage 1, stage 2, short runs), relights the
# reconstruction and exports it as glTF and as a Mitsuba scene.
# Usage: scripts/demo.sh [build-dir]   (default: build/release; output in out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
jobs=$(nproc 2>/dev/null || echo 2)
out=out/demo
data=${DIFFTRANS_DATA:-data}
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

step "reconstruct: the environment (distant map or near field, chosen from the out-of-mask pixels),
   stage-1 geometry (FlexiCubes 32³ from the masks, 200 + 200 iterations) and stage 2 (the absorption
   model chosen from held-out views, then the vertices, IoR and absorption through the tracer, 200
   iterations, the vertices moving in 60 to 160): a short run; the defaults are 64³, 1000 + 1000 and
   400 + 1500 + 300"
rm -f "$out/reconstruct/reconstruct.json"
"$dt" reconstruct "$out/scene" --out "$out/reconstruct" --stages environment,geometry,materials --grid 32 \
  --iterations 200 --refine-iterations 200 --restart --materials-iterations 200 --materials-freeze 60 \
  --materials-geometry-iterations 100 --materials-blur-halving 50 |
  grep -E '^ {4,6}"(psnr_background_test|psnr_map_seen|seen_fraction|chamfer|f1|genus|ior|ior_true|psnr|psnr_mask)"'

step "relight: the reconstruction under blouberg_sunrise_2 against the ground truth under it"
"$dt" relight --mesh "$out/reconstruct/mesh_stage2.obj" --material "$out/reconstruct/material_stage2.json" \
  --scene "$out/scene" --env "$data/envmaps/blouberg_sunrise_2_1k.hdr" --out "$out/relight_reconstruction" --overwrite |
  grep -E '"(psnr|psnr_mask|ssim)"' | head -3

step "export: the reconstruction as glTF 2.0 (.glb: transmission, IoR, volume) and as a Mitsuba 3 scene"
"$dt" export "$out/reconstruct" --format gltf --out "$out/export_gltf" --overwrite > /dev/null
"$dt" export "$out/reconstruct" --format mitsuba --out "$out/export_mitsuba" --overwrite > /dev/null
ls "$out/export_gltf" "$out/export_mitsuba"

echo
echo "demo: done in $(( $(date +%s) - start )) s. Pictures:"
echo "  environment        $out/reconstruct/envmap.hdr, $out/reconstruct/environment_comparison.png"
echo "  geometry           $out/reconstruct/mesh_stage1.obj, stage1_silhouettes.png (mask | silhouette | difference), stage1_loss.svg"
echo "  materials          $out/reconstruct/material_stage2.json, stage2_loss.svg, stage2_test/contact_sheet.png"
echo "  relit reconstruction $out/relight_reconstruction/ (contact sheet: truth | reconstruction | error)"
echo "  scene previews     $out/scene/previews/*.png (masks in $out/scene/masks/)"
echo "  relit previews     $out/relight/previews/*.png"
echo "  contact sheet      $out/relight/contact_sheet.png (training-environment image | relit | error)"
echo "  metrics            $out/render/evaluate.json, $out/relight/evaluate.json"
echo "  exported           $out/export_gltf/object.glb (any glTF viewer, Blender), $out/export_mitsuba/scene.xml (Mitsuba 3)"
