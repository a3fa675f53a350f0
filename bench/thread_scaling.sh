#!/usr/bin/env bash
# Thread scaling of the image passes: bench/thread_scaling.cpp at 1, 2, 4, 8
# and 16 threads (those the machine has cores for; the others are listed as
# not measured), and the parallel efficiency T(1) / (n T(n)) of the primal
# render and the gradient. Writes thread_scaling.json into OUT.
# Usage: bench/thread_scaling.sh [BUILD_DIR] [OUT]   (default build/release, .)
set -eu
build=${1:-build/release}
out=${2:-.}
bin=$build/bench/thread_scaling
[ -x "$bin" ] || { echo "thread_scaling.sh: $bin is not built" >&2; exit 1; }
cores=$(nproc)
mkdir -p "$out"
lines=() skipped=()
for n in 1 2 4 8 16; do
  if [ "$n" -gt "$cores" ]; then skipped+=("$n"); continue; fi
  lines+=("$(DIFFTRANS_THREADS=$n "$bin")")
done
field() { sed -n "s/.*\"$1\": \([0-9.e+-]*\).*/\1/p" <<< "$2"; }
p1=$(field primal_seconds "${lines[0]}")
g1=$(field gradient_seconds "${lines[0]}")
{
  echo "{\"cores\": $cores, \"not_measured\": [$(IFS=,; echo "${skipped[*]:-}")], \"runs\": ["
  for i in "${!lines[@]}"; do
    [ "$i" -gt 0 ] && echo ","
    printf '%s' "${lines[$i]}"
  done
  echo "]}"
} > "$out/thread_scaling.json"
printf '%8s %12s %10s %12s %10s\n' threads primal_s efficiency gradient_s efficiency
for line in "${lines[@]}"; do
  n=$(field threads "$line") p=$(field primal_seconds "$line") g=$(field gradient_seconds "$line")
  awk -v n="$n" -v p="$p" -v g="$g" -v p1="$p1" -v g1="$g1" \
    'BEGIN { printf "%8d %12.4f %10.2f %12.4f %10.2f\n", n, p, p1 / (n * p), g, g1 / (n * g) }'
done
[ ${#skipped[@]} -eq 0 ] || echo "not measured (the machine has $cores cores): ${skipped[*]} threads"
echo "wrote $out/thread_scaling.json"
