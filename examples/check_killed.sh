#!/usr/bin/env bash
# SIGKILL at any moment of `difftrans reconstruct` leaves the output folder
# whole: as it was, or as the run's last publication made it (after a stage or
# a checkpoint), never half-written. The run is killed the moment each stage's
# first output file appears (where the folder of the old design was caught with
# files of a stage whose record was not yet written), then at three times
# spread over a run, during the start-up copy, and with a second command on
# the same folder; after every kill the folder's record and files must agree,
# and the command run again goes on to the end with the uninterrupted run's
# result.
# Usage: check_killed.sh DIFFTRANS SCENE OUT
set -u
bin=$1 scene=$2 out=$3
aside=$out.check  # logs, markers and the reference run, beside OUT
fail() { echo "check_killed: $*" >&2; [ -f "$aside/log" ] && tail -5 "$aside/log" >&2; exit 1; }
rm -rf "$out" "$out.partial" "$out.next" "$out.previous" "$aside"
mkdir -p "$aside"
settings=(--stages environment,geometry,materials --env-model distant --grid 10 --iterations 12 --batch 2 --refine-iterations 4
  --refine-batch 2 --metric-samples 2000 --materials-iterations 12 --materials-rays 256 --absorption-res 4
  --test-spp-axis 1 --checkpoint-every 3 --seed 7)

now_ms() { date +%s%3N; }
t0=$(now_ms)
"$bin" reconstruct "$scene" --out "$aside/reference" "${settings[@]}" > "$aside/reference.json" 2> "$aside/log" ||
  fail "the uninterrupted run failed"
whole_ms=$(($(now_ms) - t0))

# what each stage leaves, by its key in reconstruct.json
declare -A leaves=(
  [environment]="envmap.hdr environment_comparison.png"
  [geometry]="mesh_stage1_raw.obj mesh_stage1.obj stage1_silhouettes.png stage1_loss.svg"
  [materials]="material_stage2.json mesh_stage2.obj stage2_loss.svg stage2_test/metrics.json"
)

# the folder after a kill: absent (nothing published yet), or a record and the
# files of exactly the stages it records, each complete
check_whole() {
  local what=$1 record=$out/reconstruct.json stage f recorded
  [ -e "$out.previous" ] && [ ! -e "$out" ] && return 0  # put back by the next run (checked below)
  [ -d "$out" ] || return 0
  [ -f "$record" ] || fail "$what: $out exists without reconstruct.json: $(ls "$out" | tr '\n' ' ')"
  [ "$(tail -c 2 "$record" | tr -d '\n')" = "}" ] || fail "$what: $record is cut short"
  for stage in environment geometry materials; do
    recorded=no
    grep -q "^  \"$stage\": {" "$record" && recorded=yes
    for f in ${leaves[$stage]}; do
      if [ $recorded = yes ] && [ ! -s "$out/$f" ]; then fail "$what: $record records $stage but $f is missing or empty"; fi
      if [ $recorded = no ] && [ -e "$out/$f" ]; then
        fail "$what: $out/$f is there but reconstruct.json does not record $stage (a half-written folder)"
      fi
    done
  done
  for f in "$out"/*.obj; do
    [ -e "$f" ] || continue
    [ "$(tail -c 1 "$f" | od -An -c | tr -d ' ')" = '\n' ] || fail "$what: $f is cut short"
  done
  return 0
}

# runs the command and kills it (SIGKILL) when `trigger` returns 0
kills=0
run_and_kill() {
  local what=$1 trigger=$2 pid
  touch "$aside/started"
  "$bin" reconstruct "$scene" --out "$out" "${settings[@]}" > /dev/null 2> "$aside/log" &
  pid=$!
  while kill -0 "$pid" 2> /dev/null; do
    if $trigger; then
      kill -KILL "$pid" 2> /dev/null && kills=$((kills + 1))
      break
    fi
    sleep 0.005
  done
  wait "$pid" 2> /dev/null
  check_whole "$what"
}

# the moment a stage's first file appears in the work folder (or, in a design
# without one, in OUT itself), before its record
appears() { [ -e "$out.partial/$watched" ] || { [ -e "$out/$watched" ] && [ "$out/$watched" -nt "$aside/started" ]; }; }
for watched in envmap.hdr mesh_stage1_raw.obj mesh_stage1.obj material_stage2.json mesh_stage2.obj stage2_test; do
  run_and_kill "killed when $watched appeared" appears
done

# at times spread over a run, and inside the start-up copy of OUT
deadline=0
after() { [ "$(now_ms)" -ge "$deadline" ]; }
for percent in 20 50 80; do
  deadline=$(($(now_ms) + whole_ms * percent / 100))
  run_and_kill "killed after ${percent} % of a run's time" after
done
copying() { [ -d "$out.partial" ]; }
run_and_kill "killed while copying OUT into its work folder" copying

# a second command on the same folder stops at once and leaves the first's work alone
"$bin" reconstruct "$scene" --out "$out" "${settings[@]}" > /dev/null 2> "$aside/log" &
first=$!
# (the first holds the work folder once it has started its first stage)
for _ in $(seq 1000); do grep -q "^environment" "$aside/log" && break; sleep 0.01; done
if "$bin" reconstruct "$scene" --out "$out" "${settings[@]}" > /dev/null 2> "$aside/second.log"; then
  kill -KILL "$first"
  fail "a second command on the same folder ran"
fi
grep -q "another difftrans command is writing into this folder" "$aside/second.log" ||
  { kill -KILL "$first"; fail "the second command did not say why it stopped: $(tail -1 "$aside/second.log")"; }
[ -d "$out.partial" ] || [ ! -e /proc/"$first" ] || { kill -KILL "$first"; fail "the second command removed the first's work folder"; }
kill -KILL "$first" 2> /dev/null
wait "$first" 2> /dev/null
check_whole "killed after a second command was refused"

# a kill between the two renames of the fallback publication (no atomic exchange) leaves OUT.previous alone
if [ -d "$out" ]; then
  mv "$out" "$out.previous"
  restored=yes
fi

"$bin" reconstruct "$scene" --out "$out" "${settings[@]}" > "$aside/result.json" 2> "$aside/log" ||
  fail "the run after the kills failed"
check_whole "the finished run"
if [ -n "${restored:-}" ]; then
  grep -q "restored from $out.previous" "$aside/log" || fail "OUT.previous was not put back: $(tail -1 "$aside/log")"
fi
for leftover in "$out.partial" "$out.next" "$out.previous"; do
  [ -e "$leftover" ] && fail "$leftover is left after the finished run"
done
grep -q "^  \"materials\": {" "$out/reconstruct.json" || fail "the finished run's record has no materials"
# the same result as the uninterrupted run (same seed): the final IoR and stage-1 chamfer distance
for key in '"ior"' '"chamfer"'; do
  a=$(grep -o "$key: [-0-9.e+]*" "$aside/reference.json" | tail -1)
  b=$(grep -o "$key: [-0-9.e+]*" "$aside/result.json" | tail -1)
  [ -n "$a" ] && [ "$a" = "$b" ] || fail "resumed after $kills kills: $b, uninterrupted: $a"
done
echo "check_killed: $kills kills, the folder whole after each; the finished run ends as the uninterrupted one ($(grep -o '"ior": [-0-9.e+]*' "$aside/result.json" | tail -1))"
