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
# "tests bench syntax"). The syntax step compiles every header alone and
# every source file with the build's C++ compiler (-fsyntax-only) and prints
# what names it misses: a newer compiler's standard library includes less
# behind the scenes. The bench step writes speed.jsonl: the four meshes at 512²
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
for step in ${STEPS:-tests bench syntax}; do
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
    syntax)
      cxx=$(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' "$build/CMakeCache.txt")
      inc=${prefix:+$prefix/include}
      inc=${inc:-/usr/include}
      flags=(-std=c++17 -fsyntax-only -I"$root/include" -I"$root/tests" -I"$root/bench" -I"$root/examples"
             -isystem "$inc/stb" -isystem "$inc/OpenEXR" -isystem "$inc/Imath" -isystem "$inc/eigen3" -DDIFFTRANS_HAVE_EMBREE=1
             -DDIFFTRANS_DATA_DIR=\"data\" -DDIFFTRANS_BUILD_FLAGS=\"\")
      [ -n "$prefix" ] && flags+=(-isystem "$inc")
      s=$(date +%s)
      # one file: a header alone (H) or a source file (S); prints its error lines
      check_one() {
        if [ "$1" = H ]; then $CXX_SYNTAX -x c++ -include "$2" /dev/null; else $CXX_SYNTAX "$2"; fi 2>&1 |
          grep -E "error" | sed "s|^|$2: |"
      }
      export -f check_one
      export CXX_SYNTAX="$cxx ${flags[*]}"
      ( cd "$root" && { ls include/difftrans/*/*.hpp | sed 's/^/H /'; find tests examples bench -name '*.cpp' | sed 's/^/S /'; } |
        xargs -P "$(nproc)" -L1 bash -c 'check_one "$0" "$1"' ) > "$logs/syntax.txt" 2>&1 || true
      echo "gpu_check: syntax of headers and sources with $($cxx -dumpfullversion) in $(( $(date +%s) - s )) s:" \
        "$(wc -l < "$logs/syntax.txt") error lines"
      head -40 "$logs/syntax.txt" ;;
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
