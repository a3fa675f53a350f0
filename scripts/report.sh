#!/usr/bin/env bash
# The benchmark page from a fresh clone, in one command: installs the
# dependencies, builds the difftrans command (Release) and runs
# `difftrans report` with the options given (default: the quick suite into
# report/, so the page is report/index.html). Stopped, the same command goes
# on where it stopped (finished runs are reused).
# Usage: scripts/report.sh [--suite tiny|quick|full] [--out DIR] [--work DIR] [--rerun]
#   e.g. bash scripts/report.sh --suite quick     # about an hour on 2 cores
# Then, to look at it as a person would: bash scripts/report_screenshot.sh report
set -euo pipefail
cd "$(dirname "$0")/.."
build=${DIFFTRANS_BUILD:-build/release}
bash scripts/install-deps.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" --target difftrans_command
args=("$@")
[[ " ${args[*]} " == *" --suite "* ]] || args=(--suite quick "${args[@]}")
[[ " ${args[*]} " == *" --out "* ]] || args+=(--out report)
exec "$build/examples/difftrans" report "${args[@]}"
