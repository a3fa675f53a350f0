#!/usr/bin/env bash
# SIGINT and SIGTERM during `difftrans reconstruct --stages materials`: the
# fit stops after its current iteration with exit status 128 + signal, says
# where its checkpoint is, keeps the earlier stages' record, and the next run
# goes on from the checkpoint to the end.
# Usage: check_interrupt.sh DIFFTRANS SCENE OUT
set -u
bin=$1 scene=$2 out=$3
# the log and the markers live beside OUT: reconstruct replaces OUT as a
# whole each time it publishes (output_folder.hpp), so a file another program
# writes inside OUT during the run is not kept
aside=$out.check
# (the whole log of the last run: whether and where it resumed is at its top)
fail() { echo "check_interrupt: $*" >&2; [ -f "$aside/log" ] && tail -40 "$aside/log" >&2; exit 1; }
rm -rf "$out" "$aside"
mkdir -p "$aside"
stage2=(--materials-rays 1024 --materials-freeze 5 --absorption-res 3 --test-spp-axis 1 --checkpoint-every 3)

"$bin" reconstruct "$scene" --out "$out" --stages environment,geometry --grid 10 --iterations 12 --batch 2 \
  --refine-iterations 4 --refine-batch 2 --metric-samples 2000 > /dev/null 2> "$aside/log" || fail "stage 1 failed"

# stops a long fit with signal $1 once it has written a new checkpoint; sets
# rc (its exit status) and it (the iteration it says it saved)
stop_with() {
  local sig=$1 pid
  "$bin" reconstruct "$scene" --out "$out" --stages materials --materials-iterations 100000 "${stage2[@]}" \
    > /dev/null 2> "$aside/log" &
  pid=$!
  for _ in $(seq 600); do  # up to 60 s
    if [ -f "$out/checkpoint_stage2.bin" ] && [ "$out/checkpoint_stage2.bin" -nt "$aside/last_stop" ]; then break; fi
    sleep 0.1
  done
  sleep 0.3
  kill -"$sig" "$pid"
  wait "$pid"
  rc=$?
  touch "$aside/last_stop"
  it=$(sed -n 's/.*the fit at iteration \([0-9]*\) is saved in.*/\1/p' "$aside/log")
  [ -n "$it" ] || fail "no 'the fit at iteration N is saved' after SIG$sig (exit status $rc)"
}

touch -d '2000-01-01' "$aside/last_stop"
stop_with INT
first=$it
[ "$rc" = 130 ] || fail "SIGINT: exit status $rc, expected 130"
grep -q "stopped by SIGINT" "$aside/log" || fail "SIGINT: no 'stopped by SIGINT'"
grep -q '"geometry"' "$out/reconstruct.json" || fail "the geometry record is gone from reconstruct.json"

stop_with TERM
second=$it
[ "$rc" = 143 ] || fail "SIGTERM: exit status $rc, expected 143"
grep -q "resuming from .*checkpoint_stage2.bin at iteration $first" "$aside/log" || fail "SIGTERM run did not resume at $first"
[ "$second" -gt "$first" ] || fail "SIGTERM run saved iteration $second, not past $first"

end=$((second + 4))
"$bin" reconstruct "$scene" --out "$out" --stages materials --materials-iterations "$end" "${stage2[@]}" \
  > "$aside/result.json" 2> "$aside/log" || fail "the resumed run failed"
grep -q "resuming from .*checkpoint_stage2.bin at iteration $second" "$aside/log" || fail "final run did not resume at $second"
grep -q "\"resumed_at\": $second" "$aside/result.json" || fail "reconstruct.json does not say resumed_at $second"
grep -q '"geometry"' "$aside/result.json" || fail "the geometry record is gone"
echo "check_interrupt: SIGINT saved iteration $first (exit 130), SIGTERM resumed and saved $second (exit 143), finished at $end"
