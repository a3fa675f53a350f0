#!/usr/bin/env bash
# Stage 2 (the vertices, IoR and absorption, as the defaults run it) on the
# quick benchmark scenes, after stage 1: for each
# scene, the environment stage and the materials stage in a copy of the
# stage-1 run of scripts/stage1_report.sh, plus two bounds rendered from the
# test cameras with the ground-truth material and the recovered environment —
# on the stage-1 mesh (the best materials can do on that geometry) and on the
# true mesh (what the environment allows). Prints a Markdown table.
#
#   bash scripts/stage1_report.sh WORK_DIR --only full   # first (or reuse its runs)
#   bash scripts/stage2_report.sh WORK_DIR [extra reconstruct options...]
#   STAGE2_TAG=materials bash scripts/stage2_report.sh WORK_DIR --materials-geometry=false   # the materials alone, into WORK_DIR/materials/
#
# Needs a built `difftrans` ($DIFFTRANS or build/release/examples/difftrans), jq and
# GNU time. Finished runs (their stage2_test/metrics.json) are kept.
set -euo pipefail
work=${1:?usage: stage2_report.sh WORK_DIR [reconstruct options...]}
shift
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${DIFFTRANS:-$here/build/release/examples/difftrans}
[ -x "$bin" ] || { echo "stage2_report: $bin not found; build first" >&2; exit 1; }
command -v jq >/dev/null || { echo "stage2_report: jq is needed (apt-get install jq)" >&2; exit 1; }
scenes="spot-clear bunny-clear horse-green monkey-bands"
tag=${STAGE2_TAG:-stage2}
for s in $scenes; do
  src=$work/runs/$s.full scene=$work/scenes/$s out=$work/$tag/$s
  [ -f "$src/mesh_stage1.obj" ] || { echo "stage2_report: $src/mesh_stage1.obj missing: run stage1_report.sh first" >&2; exit 1; }
  if [ ! -f "$out/stage2_test/metrics.json" ]; then
    rm -rf "$out"; mkdir -p "$work/$tag"; cp -r "$src" "$out"
    echo "stage2_report: $s" >&2
    "$bin" reconstruct "$scene" --out "$out" --stages environment >/dev/null 2>"$out.env.log"
    /usr/bin/time -v "$bin" reconstruct "$scene" --out "$out" --stages materials "$@" >/dev/null 2>"$out.log"
    for m in stage1 gt; do
      mesh=$out/mesh_stage1.obj; [ $m = gt ] && mesh=$scene/gt/mesh.obj
      "$bin" render --mesh "$mesh" --material "$scene/gt/material.json" --env "$out/envmap.hdr" --scene "$scene" \
        --split test --out "$out/bound_$m" --overwrite >/dev/null 2>>"$out.bounds.log"
    done
  fi
done
# Error maps (vertex colours by distance to the true surface; open them in a
# mesh viewer, or look at the pictures beside them): OUT/error_stage1.ply and
# .png and, when the vertices moved, OUT/error_stage2.ply and .png; the
# fraction of vertices beyond tau goes in the table.
beyond() {  # beyond MESH SCENE PLY: the fraction of MESH's vertices farther than tau from the truth, in %
  "$bin" evaluate --pred "$1" --gt "$2/gt/mesh.obj" --error-map "$3" 2>/dev/null |
    jq -r '.error_map.fraction_above_tau * 1000 | round / 10'
}
echo "| scene | IoR (true) | IoR error | test PSNR | in-mask PSNR | SSIM | CD (stage 1 → 2) | F1 (stage 1 → 2) | vertices beyond τ, % (stage 1 → 2) | mean dihedral ° (stage 1 → 2) | bound: true material on stage-1 mesh (in-mask) | bound: true mesh + material (in-mask) | fit time | peak RSS MB |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for s in $scenes; do
  out=$work/$tag/$s
  r=$out/reconstruct.json
  e1=$(beyond "$out/mesh_stage1.obj" "$work/scenes/$s" "$out/error_stage1.ply") e2=$e1
  [ -f "$out/mesh_stage2.obj" ] && e2=$(beyond "$out/mesh_stage2.obj" "$work/scenes/$s" "$out/error_stage2.ply")
  b1=$(jq -r '.psnr_mask * 100 | round / 100' "$out/bound_stage1/metrics.json")
  b2=$(jq -r '.psnr_mask * 100 | round / 100' "$out/bound_gt/metrics.json")
  rss=$(grep "Maximum resident set size" "$out.log" | awk '{printf "%.0f", $NF/1024}')
  jq -r --arg s "$s" --arg b1 "$b1" --arg b2 "$b2" --arg rss "$rss" --arg e1 "$e1" --arg e2 "$e2" '.materials as $m |
    .geometry.final as $g | ($m.mesh_quality // {}) as $q |
    "| \($s) | \($m.ior * 1000 | round / 1000) (\($m.ior_true)) | \($m.ior_error * 1000 | round / 1000) | \($m.test.psnr * 100 | round / 100) | \($m.test.psnr_mask * 100 | round / 100) | \($m.test.ssim * 1000 | round / 1000) | \($g.chamfer * 1e7 | round / 1e7) → \(($m.chamfer // $g.chamfer) * 1e7 | round / 1e7) | \($g.f1 * 1e4 | round / 1e4) → \(($m.f1 // $g.f1) * 1e4 | round / 1e4) | \($e1) → \($e2) | \(if $q.stage1 then "\($q.stage1.mean_dihedral_degrees * 100 | round / 100) → \($q.stage2.mean_dihedral_degrees * 100 | round / 100)" else "–" end) | \($b1) | \($b2) | \($m.fit_seconds | round) s | \($rss) |"' "$r"
done
