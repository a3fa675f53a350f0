#!/usr/bin/env bash
# Installs the dependencies, builds everything (library tests, CUDA device
# code where nvcc is, benchmarks, examples) and runs the whole test suite.
# Usage: scripts/test.sh [build-dir]   (default: build/release)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
jobs=$(nproc 2>/dev/null || echo 2)

bash scripts/install-deps.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$jobs"
ctest --test-dir "$build" --output-on-failure -j "$jobs"
