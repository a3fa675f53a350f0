#!/usr/bin/env bash
# Builds the test suite with AddressSanitizer + UndefinedBehaviorSanitizer
# (host code only) and runs it.
# Usage: scripts/sanitize.sh [--io] [build-dir]
#   --io: only the io tests (every loader, and io/loader_mutations: the
#         loaders against thousands of damaged files); CI runs this part
set -euo pipefail
cd "$(dirname "$0")/.."
io_only=0
if [ "${1:-}" = "--io" ]; then io_only=1; shift; fi
build=${1:-build/sanitize}
jobs=$(nproc 2>/dev/null || echo 2)

bash scripts/install-deps.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDIFFTRANS_SANITIZE=ON \
  -DDIFFTRANS_CUDA=OFF -DDIFFTRANS_BUILD_BENCH=OFF
filter=(-E '^package/')
if [ "$io_only" = 1 ]; then
  targets=$(cd tests/io && ls *.test.cpp | sed 's/\.test\.cpp$//; s/^/test_io_/')
  # shellcheck disable=SC2086  # one target per word
  cmake --build "$build" -j "$jobs" --target $targets
  filter=(-R '^io/')
else
  cmake --build "$build" -j "$jobs"
fi
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir "$build" --output-on-failure -j "$jobs" "${filter[@]}"
