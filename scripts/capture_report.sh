#!/usr/bin/env bash
# Real captures, simulated: spot-clear and horse-green (quick variant) made
# capture-like by `difftrans degrade` — 8-bit sRGB PNG; exposure x0.5 and x2
# (8-bit, so x2 clips highlights); COLMAP binary poses with rotation noise 0,
# 0.1, 0.3 and 1 degree and the matching translation (the angle in radians
# times the camera's distance from the scene centre); masks eroded or dilated
# by 1 px — each reconstructed with `difftrans reconstruct --stages
# environment,geometry,materials` and the defaults (masks auto, exposure auto:
# estimated against gt/envmap.hdr for the 8-bit scenes). Prints a Markdown
# table of CD, F1 and IoR error per degradation, read from reconstruct.json.
# The 8-bit and exposure rows start from the clean run's stage-1 meshes (their
# masks and poses are the clean ones; stage 1 reads nothing else).
#
#   bash scripts/capture_report.sh WORK_DIR [extra reconstruct options...]
#
# Environment: CAPTURE_SCENES (default "spot-clear horse-green"),
# CAPTURE_VARIANT (default quick), CAPTURE_ONLY (degradation names, e.g.
# "png8 colmap-0.3"; default all), CAPTURE_TAG (run folder, default runs: use
# another with extra options). Scenes go to WORK_DIR/scenes/SCENE[.DEGRADATION],
# runs to WORK_DIR/TAG/SCENE.DEGRADATION; finished runs (reconstruct.json with
# a materials record) are kept. Each run takes tens of minutes on 2 cores; the
# whole table some hours. Needs a built `difftrans` ($DIFFTRANS or
# build/examples/difftrans) and jq.
set -euo pipefail
work=${1:?usage: capture_report.sh WORK_DIR [reconstruct options...]}
shift
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${DIFFTRANS:-$here/build/examples/difftrans}
[ -x "$bin" ] || { echo "capture_report: $bin not found; build first (bash scripts/test.sh or cmake --build)" >&2; exit 1; }
command -v jq >/dev/null || { echo "capture_report: jq is needed (apt-get install jq)" >&2; exit 1; }
scenes=${CAPTURE_SCENES:-spot-clear horse-green}
variant=${CAPTURE_VARIANT:-quick}
tag=${CAPTURE_TAG:-runs}
# NAME|degrade options (clean: the synthesized scene itself)
degradations=(
  "clean|"
  "png8|--png8"
  "exposure-0.5|--png8 --exposure 0.5"
  "exposure-2|--png8 --exposure 2"
  "colmap-0|--colmap-binary"
  "colmap-0.1|--colmap-binary --pose-noise-deg 0.1"
  "colmap-0.3|--colmap-binary --pose-noise-deg 0.3"
  "colmap-1|--colmap-binary --pose-noise-deg 1"
  "erode-1|--mask-erode 1"
  "dilate-1|--mask-dilate 1"
)
wanted() { [ -z "${CAPTURE_ONLY:-}" ] || [[ " $CAPTURE_ONLY " == *" $1 "* ]]; }
mkdir -p "$work/scenes" "$work/$tag"

for s in $scenes; do
  clean=$work/scenes/$s
  if [ ! -f "$clean/scene.json" ]; then
    echo "capture_report: synth $s ($variant)" >&2
    "$bin" synth --preset "$s" --variant "$variant" --out "$clean" --overwrite 2>"$work/scenes/$s.synth.log"
  fi
  for d in "${degradations[@]}"; do
    name=${d%%|*} options=${d#*|}
    wanted "$name" || continue
    scene=$clean out=$work/$tag/$s.$name
    if [ "$name" != clean ]; then
      scene=$work/scenes/$s.$name
      if [ ! -f "$scene/degrade.json" ]; then
        # shellcheck disable=SC2086  # the options are words
        "$bin" degrade "$clean" --out "$scene" --overwrite --seed 1 $options >/dev/null 2>"$scene.degrade.log"
      fi
    fi
    if ! jq -e '.materials.ior_error' "$out/reconstruct.json" >/dev/null 2>&1; then
      echo "capture_report: $s $name" >&2
      mkdir -p "$out"
      # 8-bit images and exposure change neither masks nor poses, and stage 1
      # reads only those: start from the clean run's stage-1 meshes (reconstruct
      # then reuses them and says "raw_reused": true)
      case $name in png8|exposure-*)
        for m in mesh_stage1_raw.obj mesh_stage1.obj; do
          if [ -f "$work/$tag/$s.clean/$m" ] && [ ! -f "$out/$m" ]; then cp "$work/$tag/$s.clean/$m" "$out/$m"; fi
        done ;;
      esac
      "$bin" reconstruct "$scene" --out "$out" --stages environment,geometry,materials "$@" >/dev/null 2>"$out.log"
    fi
  done
done

echo "| scene | degradation | exposure used | CD | F1 | IoR (true) | IoR error | map PSNR vs gt (seen) |"
echo "|---|---|---|---|---|---|---|---|"
for s in $scenes; do
  for d in "${degradations[@]}"; do
    name=${d%%|*}
    wanted "$name" || continue
    jq -r --arg s "$s" --arg d "$name" '
      def r(n): . * n | round / n;
      "| \($s) | \($d) | \(.exposure.scale | r(1000)) (\(.exposure.source)) | \(.geometry.final.chamfer | r(1e7)) | \(.geometry.final.f1 | r(1000)) | \(.materials.ior | r(1000)) (\(.materials.ior_true)) | \(.materials.ior_error | r(1000)) | \(.environment.psnr_map_seen // "–" | if type == "number" then r(100) else . end) |"' \
      "$work/$tag/$s.$name/reconstruct.json"
  done
done
