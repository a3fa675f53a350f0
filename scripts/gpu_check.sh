#!/usr/bin/env bash
# The device checks in one go, on a machine with an NVIDIA GPU and nvcc:
# configure a CUDA build, build the device tests and the device benchmark,
# run them, and print a short summary last. Logs go to $LOG_DIR (default
# build/gpu/logs).
#
#   bash scripts/gpu_check.sh [PREFIX]     PREFIX: where the dependencies are
#                                          installed, if not in /usr; or an
#                                          archive of scripts/pack_deps.sh,
#                                          unpacked into $DEPS_DIR (default
#                                          /tmp/difftrans-deps) first
# Environment: BUILD (build folder, default build/gpu), CUDA_ARCH (default 90),
# TARGETS (default: the device tests, bench_device_speed and the difftrans
# command, equal_quality), STEPS (default: "tests command bench syntax";
# "views", "pipeline": the two halves of "command"; "quality": time at equal
# error on the device; "profile" runs Nsight Compute on a small device pass),
# DEVICE (what the
# command step passes to --device; default cuda), RENDER_TEST_ARGS (e.g.
# "quick": the device render test at 64² only), COMMAND_DIR (where the command
# step works; default $LOG_DIR/command), DEADLINE (epoch seconds: steps not
# begun by then are skipped). The syntax step compiles every header alone and
# every source file with the build's C++ compiler (-fsyntax-only) and prints
# what names it misses: a newer compiler's standard library includes less
# behind the scenes. The bench step writes speed.jsonl: the four meshes at 512²
# and spot at 1024² (depth 16, 4 spp) with all cores, then the host passes
# with 2 threads (the four at 512², spot at 1024²).
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD:-$root/build/gpu}
logs=${LOG_DIR:-$build/logs}
prefix=${1:-}
if [ -n "$prefix" ] && [ -f "$prefix" ]; then
  # an archive of scripts/pack_deps.sh: unpacked, its CMake files' /usr/ paths
  # pointed at the unpacked copy, its libraries and ninja put on the paths
  deps=${DEPS_DIR:-/tmp/difftrans-deps}
  mkdir -p "$deps" && tar -C "$deps" -xJf "$prefix" || { echo "gpu_check: cannot unpack $prefix" >&2; exit 1; }
  if [ ! -f "$deps/.rewritten" ]; then
    grep -rlI "/usr/" "$deps/usr/lib/x86_64-linux-gnu/cmake" "$deps/usr/lib/cmake" "$deps/usr/share/cmake" \
      "$deps/usr/share/nanoflann" "$deps/usr/share/eigen3" 2>/dev/null | xargs -r sed -i "s|/usr/|$deps/usr/|g"
    touch "$deps/.rewritten"
  fi
  export LD_LIBRARY_PATH=$deps/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
  command -v ninja >/dev/null || export PATH=$deps/bin:$PATH
  prefix=$deps/usr
fi
command -v nvcc >/dev/null || export PATH=$PATH:/usr/local/cuda/bin
mkdir -p "$logs"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
nvcc --version | tail -2
args=(-S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DDIFFTRANS_CUDA=ON
      -DCMAKE_CUDA_ARCHITECTURES="${CUDA_ARCH:-90}")
[ -n "$prefix" ] && args+=(-DCMAKE_PREFIX_PATH="$prefix")
t0=$(date +%s)
cmake "${args[@]}" >"$logs/configure.txt" 2>&1 || { tail -30 "$logs/configure.txt"; exit 1; }
targets=${TARGETS:-test_cuda_launch test_cuda_render test_cuda_render_kernels test_cuda_host_launch test_cuda_tree_gradient bench_device_speed difftrans_command equal_quality}
# shellcheck disable=SC2086
cmake --build "$build" --target $targets >"$logs/build.txt" 2>&1 || { grep -B2 -A12 "error" "$logs/build.txt" | head -80; exit 1; }
echo "gpu_check: configured and built in $(( $(date +%s) - t0 )) s; warnings: $(grep -c 'warning' "$logs/build.txt")"
grep -A4 "warning" "$logs/build.txt" | head -20
status=0
for step in ${STEPS:-tests command bench syntax}; do
  if [ -n "${DEADLINE:-}" ] && [ "$(date +%s)" -ge "$DEADLINE" ]; then
    echo "gpu_check: step $step skipped (past DEADLINE)"
    continue
  fi
  case $step in
    tests)
      for t in test_cuda_launch test_cuda_render_kernels test_cuda_host_launch test_cuda_tree_gradient test_cuda_render; do
        exe=$(find "$build/tests" -name "$t" -type f | head -1)
        [ -z "$exe" ] && { echo "gpu_check: $t not built"; status=1; continue; }
        s=$(date +%s)
        args=()
        [ "$t" = test_cuda_render ] && [ -n "${RENDER_TEST_ARGS:-}" ] && args=($RENDER_TEST_ARGS)
        "$exe" "${args[@]}" >"$logs/$t.txt" 2>&1; rc=$?
        echo "gpu_check: $t exit $rc in $(( $(date +%s) - s )) s"
        [ $rc -ne 0 ] && status=1
      done ;;
    syntax)
      cxx=$(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' "$build/CMakeCache.txt")
      inc=${prefix:+$prefix/include}
      inc=${inc:-/usr/include}
      # a source file sees its own top folder first (tests/support and bench/support share names)
      flags=(-std=c++17 -fsyntax-only -I"$root/include" -I"$root/tests" -I"$root/bench" -I"$root/examples"
             -I"$root/examples/difftrans/gpu"
             -isystem "$inc/stb" -isystem "$inc/OpenEXR" -isystem "$inc/Imath" -isystem "$inc/eigen3" -DDIFFTRANS_HAVE_EMBREE=1
             -DDIFFTRANS_DATA_DIR=\"data\" -DDIFFTRANS_BUILD_FLAGS=\"\")
      [ -n "$prefix" ] && flags+=(-isystem "$inc")
      s=$(date +%s)
      # one file: a header alone (H) or a source file (S); prints its error lines
      check_one() {
        if [ "$1" = H ]; then $CXX_BIN $CXX_FLAGS -x c++ -include "$2" /dev/null
        else $CXX_BIN -I"${2%%/*}" $CXX_FLAGS "$2"; fi 2>&1 |
          grep -E "error" | sed "s|^|$2: |"
      }
      export -f check_one
      export CXX_BIN=$cxx CXX_FLAGS="${flags[*]}"
      ( cd "$root" && { ls include/difftrans/*/*.hpp | sed 's/^/H /'; find tests examples bench -name '*.cpp' | sed 's/^/S /'; } |
        xargs -P "$(nproc)" -L1 bash -c 'check_one "$0" "$1"' ) > "$logs/syntax.txt" 2>&1 || true
      echo "gpu_check: syntax of headers and sources with $($cxx -dumpfullversion) in $(( $(date +%s) - s )) s:" \
        "$(wc -l < "$logs/syntax.txt") error lines"
      head -40 "$logs/syntax.txt" ;;
    bench)
      exe=$build/bench/bench_device_speed
      s=$(date +%s)
      { "$exe" --size 512 && "$exe" --size 1024 spot && DIFFTRANS_THREADS=2 "$exe" --host-only --repeats 1 --size 512 &&
        DIFFTRANS_THREADS=2 "$exe" --host-only --repeats 1 --size 1024 spot; } \
        >"$logs/speed.jsonl" 2>"$logs/speed_errors.txt" || status=1
      echo "gpu_check: bench_device_speed in $(( $(date +%s) - s )) s"
      cat "$logs/speed.jsonl" ;;
    command|views|pipeline|quality)
      # the difftrans command on the device. views: render --device cuda
      # against the host on the quick spot-clear scene's test views;
      # pipeline: that scene reconstructed with stage 2's training rays on the
      # device, then stage 2 again on the host from the same stage 1;
      # command: both; quality: time per view at equal error on the device
      # (bench/equal_quality.cpp --device cuda, test view 0)
      dt=$build/examples/difftrans
      w=${COMMAND_DIR:-$logs/command}  # its scenes, images and runs (COMMAND_DIR: elsewhere; the logs are copied back)
      mkdir -p "$w" "$logs/command"
      export DIFFTRANS_DATA=$root/data
      timed() {  # timed NAME COMMAND...: runs it, logs to $w/NAME.txt, prints its exit status and time
        local name=$1; shift
        local s; s=$(date +%s)
        "$@" >"$w/$name.txt" 2>&1; local rc=$?
        echo "gpu_check: $name exit $rc in $(( $(date +%s) - s )) s"
        [ $rc -ne 0 ] && { status=1; tail -5 "$w/$name.txt"; }
        return $rc
      }
      sc=$w/scene
      [ -f "$sc/gt/mesh.obj" ] || timed synth "$dt" synth --preset spot-clear --variant quick --out "$sc" || continue
      if [ "$step" = command ] || [ "$step" = views ]; then
        for d in cpu ${DEVICE:-cuda}; do
          timed "render_$d" "$dt" render --mesh "$sc/gt/mesh.obj" --material "$sc/gt/material.json" --env "$sc/gt/envmap.hdr" \
            --scene "$sc" --split test --out "$w/render_$d" --device "$d"
          grep -E '"(device|seconds|seconds_per_view|segments)"' "$w/render_$d.txt" | head -6
        done
        timed render_compare "$dt" evaluate --pred-images "$w/render_${DEVICE:-cuda}/images" --gt-images "$w/render_cpu/images" &&
          grep -E '"(psnr|max_abs|count)"' "$w/render_compare.txt" | head -4
      fi
      if [ "$step" = command ] || [ "$step" = pipeline ]; then
        rm -rf "$w/rec_device" "$w/stage2_host"
        timed pipeline_device "$dt" reconstruct "$sc" --out "$w/rec_device" --stages environment,geometry,materials \
          --device "${DEVICE:-cuda}"
        grep -E '^(environment|geometry|materials): (CD|IoR|training|absorption|it [0-9]+/[0-9]+ .*done)' \
          "$w/pipeline_device.txt" | head -12
        if [ -f "$w/rec_device/mesh_stage1.obj" ]; then
          mkdir -p "$w/stage2_host" && cp -r "$w/rec_device/." "$w/stage2_host/"
          timed stage2_host "$dt" reconstruct "$sc" --out "$w/stage2_host" --stages materials --device cpu --restart
          grep -E '^materials: (IoR|training|absorption|it [0-9]+/[0-9]+ .*done)' "$w/stage2_host.txt" | head -6
        fi
      fi
      if [ "$step" = quality ]; then
        timed equal_quality "$build/bench/equal_quality" --scene "$sc" --view 0 --device cuda --targets 27,32,34 \
          --out "$w/equal_quality" && tail -8 "$w/equal_quality.txt"
        cp "$w/equal_quality/equal_quality.json" "$logs/command/" 2>/dev/null
      fi
      if [ "$w" != "$logs/command" ]; then
        cp "$w"/*.txt "$logs/command/" 2>/dev/null
        for r in rec_device stage2_host; do [ -f "$w/$r/reconstruct.json" ] && cp "$w/$r/reconstruct.json" "$logs/command/$r.json"; done
      fi ;;
    profile)
      # Nsight Compute on the device image of spot at 512² (depth 16, 4 spp):
      # every launch of the wavefront's first pass, then the first launch of
      # the thread-per-pixel image and of the gradient: speed of light,
      # occupancy, launch statistics, warp states
      ncu=$(command -v ncu || ls /usr/local/cuda/bin/ncu 2>/dev/null)
      [ -z "$ncu" ] && { echo "gpu_check: no ncu"; continue; }
      s=$(date +%s)
      sections=(--section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats --section MemoryWorkloadAnalysis)
      timeout 150 "$ncu" --kernel-name-base mangled -k regex:WavefrontStep -c 17 "${sections[@]}" "$build/bench/bench_device_speed" --device-only \
        --size 512 --spp 4 --repeats 1 spot >"$logs/ncu_wavefront.txt" 2>&1
      echo "gpu_check: ncu (wavefront) exit $? in $(( $(date +%s) - s )) s"
      timeout 150 "$ncu" --kernel-name-base mangled -k regex:'RenderPixel|PooledGradientPixel' -c 2 "${sections[@]}" "$build/bench/bench_device_speed" \
        --device-only --size 512 --spp 4 --repeats 1 spot >"$logs/ncu.txt" 2>&1
      echo "gpu_check: ncu (per pixel, gradient) exit $? in $(( $(date +%s) - s )) s"
      for f in ncu_wavefront ncu; do
        grep -E "for_each_index|Duration|Compute \(SM\) Throughput|Memory Throughput|L1/TEX Hit|Achieved Occupancy|Registers Per|Theoretical Occupancy|Warp Cycles Per Issued|Grid Size|Local Memory|ERR" \
          "$logs/$f.txt" | sed 's/  */ /g' | head -200 > "$logs/$f.summary.txt"
        head -60 "$logs/$f.summary.txt"
      done ;;
    *) echo "gpu_check: unknown step $step"; status=1 ;;
  esac
done
for f in "$logs"/test_cuda_*.txt; do echo "== $(basename "$f")"; grep -v "^  .* ok " "$f" | head -60; done
exit $status
