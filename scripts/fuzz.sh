#!/usr/bin/env bash
# Builds the libFuzzer targets of the input loaders (tests/fuzz/*.fuzz.cpp:
# OBJ, PLY, scene JSON, COLMAP binary, Radiance RGBE)
# with clang + ASan + UBSan and runs each for a bounded time on a seed corpus.
# Usage: scripts/fuzz.sh [seconds per target, default 60] [target ...]
# Crashes are written to build/fuzz/<target>/crash-*; the script exits 1 then.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
bash scripts/install-deps.sh
if ! command -v clang++ >/dev/null 2>&1 || ! ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a >/dev/null 2>&1; then
  sudo_cmd=(); [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends clang libclang-rt-dev || \
    "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev
fi

out=build/fuzz
mkdir -p "$out"
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(mesh_obj mesh_ply scene_json colmap_binary hdr_rgbe)
flags=(-std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -Iinclude -I/usr/include/stb -I/usr/include/OpenEXR -I/usr/include/Imath)
libs=(-ltinyobjloader -lstb -lOpenEXR-3_1 -lImath-3_1)

seed() {  # seed corpus per target
  local dir=$1 kind=$2
  mkdir -p "$dir"
  case $kind in
    mesh_obj)
      head -c 4000 data/meshes/spot.obj > "$dir/spot_head.obj" 2>/dev/null || true
      printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3/1/1 4//2\nf -1 -2 -3\n' > "$dir/small.obj" ;;
    mesh_ply)
      printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n' > "$dir/tri_ascii.ply"
      { printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n'
        printf '\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80\x3f\x00\x00\x00\x00'
        printf '\x03\x00\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00'; } > "$dir/tri_binary.ply" ;;
    colmap_binary)  # first byte: 0 = cameras.bin, 1 = images.bin; then the file (little-endian)
      python3 - "$dir" <<'PY'
import struct, sys
d = sys.argv[1]
cam = struct.pack('<QIiQQ4d', 1, 1, 1, 8, 8, 10.0, 10.0, 4.0, 4.0)          # one PINHOLE camera
img = struct.pack('<QI7dI', 1, 1, 1, 0, 0, 0, 0, 0, 3, 1) + b'a.png\0' + struct.pack('<Q2dq', 1, 1.5, 2.5, -1)
open(d + '/cameras.bin', 'wb').write(b'\0' + cam)
open(d + '/images.bin', 'wb').write(b'\1' + img)
PY
      ;;
    hdr_rgbe)  # a run-length encoded map (width 16) and an uncompressed one (width 4), and a cut of the first
      python3 - "$dir" <<'PY'
import struct, sys
d = sys.argv[1]
head = lambda w, h: b'#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n' % (h, w)
rle_line = bytes([2, 2, 0, 16]) + b''.join(bytes([128 + 16, v]) for v in (120, 60, 30, 129))
open(d + '/rle.hdr', 'wb').write(head(16, 2) + rle_line * 2)
open(d + '/flat.hdr', 'wb').write(head(4, 2) + bytes([100, 50, 25, 128]) * 8)
open(d + '/cut.hdr', 'wb').write(head(16, 2) + rle_line + rle_line[:7])
PY
      ;;
    scene_json)
      printf '{"camera_angle_x": 0.69, "w": 8, "h": 8, "frames": [{"file_path": "images/r_0", "mask_path": "masks/r_0.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}' > "$dir/one_frame.json"
      printf '{"fl_x": 10, "fl_y": 10, "cx": 4, "cy": 4, "w": 8, "h": 8, "frames": [{"file_path": "images/r_1.exr", "environment_only": true, "transform_matrix": [[0,0,1,2],[0,1,0,0],[-1,0,0,0]]}]}' > "$dir/intrinsics.json" ;;
  esac
}

failed=0
for t in "${targets[@]}"; do
  echo "== $t: building"
  clang++ "${flags[@]}" "tests/fuzz/$t.fuzz.cpp" -o "$out/$t" "${libs[@]}"
  mkdir -p "$out/$t.corpus" "$out/$t.artifacts"
  seed "$out/$t.seeds" "$t"
  echo "== $t: fuzzing for ${seconds}s"
  if ! "$out/$t" "$out/$t.corpus" "$out/$t.seeds" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
       -artifact_prefix="$out/$t.artifacts/" -print_final_stats=1 2> "$out/$t.log"; then
    echo "!! $t: found a problem, see $out/$t.log and $out/$t.artifacts/"; failed=1
  fi
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb|cov:" "$out/$t.log" | tail -3 || true
done
exit $failed
