#!/usr/bin/env bash
# The device checks in one go, on a machine with an NVIDIA GPU and nvcc:
# configure a CUDA build, build the device tests and the device benchmark,
# run them, and print a short summary last. Logs go to $LOG_DIR (default
# build/gpu/logs).
#
#   bash scripts/gpu_check.sh [PREFIX]     PREFIX: where the dependencies are
#                                          installed, if not in /usr
# Environment: BUILD (build folder, default build/gpu), CUDA_ARCH (default 90),
# TARGETS (default: the device tests and bench_device_speed), STEPS (default:
# "tests bench"). The bench step writes speed.jsonl: the four meshes at 512²
# and spot at 1024² (depth 16, 4 spp) with all cores, then the host passes
# with 2 threads.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD:-$root/build/gpu}
logs=${LOG_DIR:-$build/logs}
prefix=${1:-}
mkdir -p "$logs"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
nvcc --version | tail -2
args=(-S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DDIFFTRANS_CUDA=ON
      -DCMAKE_CUDA_ARCHITECTURES="${CUDA_ARCH:-90}")
[ -n "$prefix" ] && args+=(-DCMAKE_PREFIX_PATH="$prefix")
t0=$(date +%s)
cmake "${args[@]}" >"$logs/configure.txt" 2>&1 || { tail -30 "$logs/configure.txt"; exit 1; }
targets=${TARGETS:-test_cuda_launch test_cuda_render test_cuda_render_kernels bench_device_speed}
# shellcheck disable=SC2086
cmake --build "$build" --target $targets >"$logs/build.txt" 2>&1 || { grep -B2 -A12 "error" "$logs/build.txt" | head -80; exit 1; }
echo "gpu_check: configured and built in $(( $(date +%s) - t0 )) s; warnings: $(grep -c 'warning' "$logs/build.txt")"
grep -A4 "warning" "$logs/build.txt" | head -20
status=0
for step in ${STEPS:-tests bench}; do
  case $step in
    tests)
      for t in test_cuda_launch test_cuda_render_kernels test_cuda_render; do
        exe=$(find "$build/tests" -name "$t" -type f | head -1)
        [ -z "$exe" ] && { echo "gpu_check: $t not built"; status=1; continue; }
        s=$(date +%s)
        "$exe" >"$logs/$t.txt" 2>&1; rc=$?
        echo "gpu_check: $t exit $rc in $(( $(date +%s) - s )) s"
        [ $rc -ne 0 ] && status=1
      done ;;
    bench)
      exe=$build/bench/bench_device_speed
      s=$(date +%s)
      { "$exe" --size 512 && "$exe" --size 1024 spot && DIFFTRANS_THREADS=2 "$exe" --host-only --repeats 1 --size 512; } \
        >"$logs/speed.jsonl" 2>"$logs/speed_errors.txt" || status=1
      echo "gpu_check: bench_device_speed in $(( $(date +%s) - s )) s"
      cat "$logs/speed.jsonl" ;;
    *) echo "gpu_check: unknown step $step"; status=1 ;;
  esac
done
for f in "$logs"/test_cuda_*.txt; do echo "== $(basename "$f")"; grep -v "^  .* ok " "$f" | head -60; done
exit $status
