#!/usr/bin/env bash
# Where the IoR error of a reconstruction comes from: stage 2's materials fit
# (the materials alone, `--materials-geometry=false`) repeated on each pairing of a mesh and a map,
# the true ones (SCENE/gt/) and the recovered ones (RUN/mesh_stage1.obj,
# RUN/envmap.hdr). A fit that reaches the true IoR on the true mesh under the
# recovered map and misses it on the stage-1 mesh puts the error on the mesh;
# the table gives each mesh's shading-normal error (metrics/normals.hpp,
# docs/metrics.md) beside it. Optionally also a joint fit (--joint: stage 2's
# defaults, the vertices refined too) from the stage-1 mesh.
#
#   bash scripts/ior_floors.sh SCENE RUN WORK_DIR [--joint] [-- extra reconstruct options...]
#
# RUN is a finished `difftrans reconstruct SCENE --stages environment,geometry`
# (or later) output folder. Needs a built `difftrans` ($DIFFTRANS or
# build/release/examples/difftrans) and jq. A finished fit (its
# reconstruct.json has a materials record) is kept: rerun to resume.
set -euo pipefail
usage="usage: ior_floors.sh SCENE RUN WORK_DIR [--joint] [-- reconstruct options]"
scene=${1:?$usage} run=${2:?$usage} work=${3:?$usage}
shift 3
joint=0
while [ $# -gt 0 ]; do
  case $1 in
    --joint) joint=1; shift ;;
    --) shift; break ;;
    *) echo "ior_floors: unknown option $1 (extra reconstruct options go after --)" >&2; exit 2 ;;
  esac
done
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${DIFFTRANS:-$here/build/release/examples/difftrans}
[ -x "$bin" ] || { echo "ior_floors: $bin not found; build first" >&2; exit 1; }
command -v jq >/dev/null || { echo "ior_floors: jq is needed (apt-get install jq)" >&2; exit 1; }
for f in "$scene/gt/mesh.obj" "$scene/gt/envmap.hdr" "$scene/gt/material.json" "$run/mesh_stage1.obj" "$run/envmap.hdr"; do
  [ -f "$f" ] || { echo "ior_floors: $f is missing (SCENE needs gt/, RUN a finished stage 1)" >&2; exit 1; }
done
mkdir -p "$work"
# fit NAME MESH(gt|stage1) MAP(gt|recovered) [options]
fit() {
  local name=$1 mesh=$2 map=$3 out=$work/$1
  shift 3
  if [ -f "$out/reconstruct.json" ] && jq -e '.materials.ior' "$out/reconstruct.json" >/dev/null 2>&1; then return; fi
  rm -rf "$out"; mkdir -p "$out"
  if [ "$map" = gt ]; then cp "$scene/gt/envmap.hdr" "$out/envmap.hdr"; else cp "$run/envmap.hdr" "$out/envmap.hdr"; fi
  local use_mesh=()
  if [ "$mesh" = gt ]; then
    use_mesh=(--materials-mesh "$scene/gt/mesh.obj")
  else
    cp "$run/mesh_stage1.obj" "$out/"
    [ -f "$run/reconstruct.json" ] && cp "$run/reconstruct.json" "$out/"
  fi
  echo "ior_floors: $name" >&2
  "$bin" reconstruct "$scene" --out "$out" --stages materials "${use_mesh[@]}" "$@" >/dev/null 2>"$out.log" ||
    { echo "ior_floors: $name failed, see $out.log" >&2; exit 1; }
}
fit true-mesh_true-map gt gt --materials-geometry=false "$@"
fit true-mesh_recovered-map gt recovered --materials-geometry=false "$@"
fit stage1-mesh_true-map stage1 gt --materials-geometry=false "$@"
fit stage1-mesh_recovered-map stage1 recovered --materials-geometry=false "$@"
[ $joint = 1 ] && fit joint_recovered-map stage1 recovered "$@"

normals() {  # normals MESH: mean and 90th percentile of the shading-normal error, degrees
  "$bin" evaluate --pred "$1" --gt "$scene/gt/mesh.obj" 2>/dev/null |
    jq -r '"\(.normal_error_deg.mean * 100 | round / 100) / \(.normal_error_deg.p90 * 100 | round / 100) | \(.chamfer * 1e7 | round / 1e7)"'
}
echo "| mesh | map | IoR (true) | IoR error | in-mask test PSNR | normals off, ° mean / p90 | CD |"
echo "|---|---|---|---|---|---|---|"
for name in true-mesh_true-map true-mesh_recovered-map stage1-mesh_true-map stage1-mesh_recovered-map joint_recovered-map; do
  r=$work/$name/reconstruct.json
  [ -f "$r" ] || continue
  mesh=$scene/gt/mesh.obj
  case $name in
    stage1*) mesh=$work/$name/mesh_stage1.obj ;;
    joint*) mesh=$work/$name/mesh_stage2.obj ;;
  esac
  m=${name%%_*} e=${name#*_}
  jq -r --arg m "${m//-/ }" --arg e "${e//-/ }" --arg n "$(normals "$mesh")" '.materials as $x |
    "| \($m) | \($e) | \($x.ior * 10000 | round / 10000) (\($x.ior_true)) | \($x.ior_error * 10000 | round / 10000) | \($x.test.psnr_mask * 100 | round / 100) | \($n) |"' "$r"
done
