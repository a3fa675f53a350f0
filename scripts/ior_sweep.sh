#!/usr/bin/env bash
# The IoR found by the whole pipeline on one shape at several true IoRs (the
# paper's "different IoRs" figure): for each shape and IoR, a quick scene made
# by `difftrans synth` (spot: the spot-clear preset with --ior; sphere: an
# icosphere of 5 levels, `difftrans shape sphere-5`, under the same map) and
# `difftrans reconstruct SCENE --stages environment,geometry,materials` with
# its defaults plus any extra options given. Prints a Markdown table: IoR true
# and found, error, CD and F1 after stage 1 and after stage 2, wall time.
#
#   bash scripts/ior_sweep.sh WORK_DIR [--shapes spot,sphere] [--iors 1.3,1.4,1.5,1.6,1.8]
#        [--variant quick] [--spot-stage1 RUN] [-- extra reconstruct options...]
#
# --spot-stage1 RUN: the spot scenes start from RUN's stage 1 (a finished
# `reconstruct SCENE --stages geometry` of spot-clear at the same variant)
# instead of fitting their own: stage 1 sees the masks only, and the
# cameras and masks of the spot-clear preset do not change with --ior, so
# every spot scene gets the same stage-1 mesh, and the table compares
# stage 2 alone across IoRs (environment and materials run per scene).
#
# Needs a built `difftrans` ($DIFFTRANS or build/release/examples/difftrans),
# jq and GNU time. A finished run (its reconstruct.json has a materials
# record) is kept and not redone: rerun the command to resume.
set -euo pipefail
work=${1:?usage: ior_sweep.sh WORK_DIR [--shapes LIST] [--iors LIST] [--variant V] [-- reconstruct options]}
shift
shapes=spot,sphere
iors=1.3,1.4,1.5,1.6,1.8
variant=quick
spot_stage1=
while [ $# -gt 0 ]; do
  case $1 in
    --shapes) shapes=$2; shift 2 ;;
    --iors) iors=$2; shift 2 ;;
    --variant) variant=$2; shift 2 ;;
    --spot-stage1) spot_stage1=$2; shift 2 ;;
    --) shift; break ;;
    *) echo "ior_sweep: unknown option $1 (extra reconstruct options go after --)" >&2; exit 2 ;;
  esac
done
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${DIFFTRANS:-$here/build/release/examples/difftrans}
[ -x "$bin" ] || { echo "ior_sweep: $bin not found; build first" >&2; exit 1; }
command -v jq >/dev/null || { echo "ior_sweep: jq is needed (apt-get install jq)" >&2; exit 1; }
mkdir -p "$work/scenes" "$work/runs"
rows=()
for shape in ${shapes//,/ }; do
  for ior in ${iors//,/ }; do
    name=$shape-$ior scene=$work/scenes/$shape-$ior out=$work/runs/$shape-$ior
    if [ ! -f "$scene/transforms_train.json" ]; then
      case $shape in
        spot) "$bin" synth --preset spot-clear --variant "$variant" --ior "$ior" --overwrite --out "$scene" \
                >/dev/null 2>"$scene.log" ;;
        sphere) [ -f "$work/sphere.obj" ] || "$bin" shape sphere-5 --out "$work/sphere.obj" >/dev/null
                "$bin" synth --mesh "$work/sphere.obj" --ior "$ior" --env "$here/data/envmaps/venice_sunset_1k.hdr" \
                  --variant "$variant" --overwrite --out "$scene" >/dev/null 2>"$scene.log" ;;
        *) echo "ior_sweep: unknown shape '$shape' (spot, sphere)" >&2; exit 2 ;;
      esac
    fi
    if ! jq -e '.materials.ior' "$out/reconstruct.json" >/dev/null 2>&1; then
      echo "ior_sweep: $name" >&2
      rm -rf "$out"
      stages=environment,geometry,materials
      if [ "$shape" = spot ] && [ -n "$spot_stage1" ]; then
        [ -f "$spot_stage1/mesh_stage1.obj" ] && [ -f "$spot_stage1/reconstruct.json" ] ||
          { echo "ior_sweep: $spot_stage1 holds no finished stage 1 (mesh_stage1.obj, reconstruct.json)" >&2; exit 1; }
        mkdir -p "$out"
        cp "$spot_stage1"/mesh_stage1*.obj "$spot_stage1/reconstruct.json" "$out/"
        stages=environment,materials
      fi
      /usr/bin/time -v "$bin" reconstruct "$scene" --out "$out" --stages $stages "$@" \
        >/dev/null 2>"$out.log" || { echo "ior_sweep: $name failed (see $out.log)" >&2; continue; }
    fi
    wall=$(grep "Elapsed (wall clock)" "$out.log" | awk '{print $NF}')
    rows+=("$(jq -r --arg n "$shape" --arg w "$wall" '.materials as $m | .geometry.final as $g |
      "| \($n) | \($m.ior_true) | \($m.ior * 10000 | round / 10000) | \($m.ior_error * 10000 | round / 10000) | \($g.chamfer * 1e7 | round / 1e7) → \(($m.chamfer // $g.chamfer) * 1e7 | round / 1e7) | \($g.f1 * 1e4 | round / 1e4) → \(($m.f1 // $g.f1) * 1e4 | round / 1e4) | \($w) |"' \
      "$out/reconstruct.json")")
  done
done
echo "| shape | IoR (true) | IoR found | error | CD (stage 1 → 2) | F1 (stage 1 → 2) | wall |"
echo "|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
