#!/usr/bin/env bash
# Stage 1 on the quick variant of the four benchmark scenes and a procedural
# genus-5 block (full method and mask only), and the ablation on two of them;
# prints a Markdown table of CD, F1, genus, wall and CPU time and peak memory
# (issue 5's measurement). Runs are grep-able by name: runs/SCENE.TAG/.
#
#   bash scripts/stage1_report.sh WORK_DIR [--only full|ablation]
#
# Needs a built `difftrans` (build/release/examples/difftrans, or $DIFFTRANS), GNU time
# (/usr/bin/time) and jq. Each run takes a few minutes on 2 cores; the whole
# report about an hour. Finished runs (their reconstruct.json) are not redone.
set -euo pipefail
work=${1:?usage: stage1_report.sh WORK_DIR [--only full|ablation]}
only=${3:-all}
[ "${2:-}" = "--only" ] || only=all
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${DIFFTRANS:-$here/build/release/examples/difftrans}
[ -x "$bin" ] || { echo "stage1_report: $bin not found; build first (bash scripts/test.sh or cmake --build)" >&2; exit 1; }
command -v jq >/dev/null || { echo "stage1_report: jq is needed (apt-get install jq)" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "stage1_report: /usr/bin/time is needed (apt-get install time)" >&2; exit 1; }
mkdir -p "$work"

scene() {  # scene NAME: synthesize the quick variant once
  local name=$1 dir=$work/scenes/$1
  [ -f "$dir/scene.json" ] && return
  if [ "$name" = holes-5 ]; then
    "$bin" shape holes-5 --out "$work/holes-5.obj" >/dev/null
    "$bin" synth --mesh "$work/holes-5.obj" --ior 1.5 --env "${DIFFTRANS_DATA:-$here/data}/envmaps/blouberg_sunrise_2_1k.hdr" \
      --variant quick --out "$dir" 2>"$work/$name.synth.log"
  else
    "$bin" synth --preset "$name" --variant quick --out "$dir" 2>"$work/$name.synth.log"
  fi
}

run() {  # run SCENE TAG [options...]: one stage-1 run, skipped when finished
  local name=$1 tag=$2; shift 2
  local out=$work/runs/$name.$tag
  [ -f "$out/reconstruct.json" ] && return
  scene "$name"
  echo "stage1_report: $name $tag $*" >&2
  mkdir -p "$out"
  /usr/bin/time -v "$bin" reconstruct "$work/scenes/$name" --out "$out" --stages geometry --restart "$@" \
    >"$out.stdout" 2>"$out.log"
}

off="bce=0,area=0,dev=0,developability=0,weight_l1=0"
scenes="spot-clear bunny-clear horse-green monkey-bands holes-5"
ablation="holes-5 monkey-bands"
if [ "$only" != ablation ]; then
  for s in $scenes; do run "$s" full; done
  # mask only on every scene: the full method should beat it everywhere
  for s in $scenes; do run "$s" mask --weights "dilation=0,smoothness=0,$off" --refine-iterations 0; done
fi
if [ "$only" != full ]; then
  for s in $ablation; do
    run "$s" full
    run "$s" mask --weights "dilation=0,smoothness=0,$off" --refine-iterations 0
    run "$s" dilation --weights "smoothness=0,$off" --refine-iterations 0
    run "$s" smooth --weights "$off" --refine-iterations 0
    run "$s" nocarve --carve-margin -1
  done
fi

# the table: one row per finished run (raw = FlexiCubes mesh, final = after remeshing + refinement)
wall() { grep "Elapsed (wall clock)" "$1" | awk '{print $NF}'; }
rss() { grep "Maximum resident set size" "$1" | awk '{printf "%.0f", $NF/1024}'; }
cpu() { awk '/User time|System time/ {t += $NF} END {printf "%.0f", t}' "$1"; }
echo "| scene | run | mesh | CD | F1 | genus (gt) | components | wall | CPU s | peak RSS (MB) |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for f in "$work"/runs/*/reconstruct.json; do
  [ -f "$f" ] || continue
  d=$(dirname "$f"); base=$(basename "$d"); name=${base%.*}; tag=${base##*.}
  for m in raw final; do
    [ "$m" = final ] && [ "$(jq -r '.geometry.refine_seconds // 0' "$f")" = 0 ] && continue
    jq -r --arg n "$name" --arg t "$tag" --arg m "$m" --arg w "$(wall "$d.log")" --arg r "$(rss "$d.log")" --arg c "$(cpu "$d.log")" \
      '.geometry as $g | "| \($n) | \($t) | \($m) | \($g[$m].chamfer | .*1e6 | round / 1e6) | \($g[$m].f1 | .*1000 | round / 1000) | \($g[$m].genus) (\($g.gt_genus)) | \($g[$m].components) | \($w) | \($c) | \($r) |"' "$f"
  done
done
