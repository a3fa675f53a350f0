#!/usr/bin/env bash
# Checks that scripts/blender_scene.py renders what difftrans renders: the
# same scenes (a glass slab, spot-clear, horse-green with its absorption) made
# by `difftrans synth` and re-rendered by Blender's Cycles, compared with
# `difftrans evaluate` over the whole image (the background: the environment's
# convention), inside the masks (the refraction, the Fresnel weights, the
# absorption) and mask for mask; Cycles against itself with another seed is the
# noise floor of the comparison. Writes WORK/blender_check.json and
# WORK/NAME/side_by_side (the two renders' previews are in the scene folders).
#
# Usage: scripts/blender_check.sh [--difftrans PATH] [--work DIR] [--spp N] [--views N]
#            [--resolution R] [--env MAP] [--min-psnr DB]
# Needs: blender (Debian package), python3, a built difftrans.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
dt=$root/build/release/examples/difftrans
work=/tmp/blender_check
spp=256
views=4
resolution=64
env=$root/data/envmaps/blouberg_sunrise_2_1k.hdr
min_psnr=30
while [ $# -gt 0 ]; do
  case $1 in
    --difftrans) dt=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --views) views=$2; shift 2 ;;
    --resolution) resolution=$2; shift 2 ;;
    --env) env=$2; shift 2 ;;
    --min-psnr) min_psnr=$2; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "blender_check: unknown option $1" >&2; exit 2 ;;
  esac
done
command -v blender > /dev/null || { echo "blender_check: needs blender (apt-get install blender)" >&2; exit 2; }
[ -x "$dt" ] || { echo "blender_check: $dt is not an executable (build difftrans first)" >&2; exit 2; }

rm -rf "$work"
mkdir -p "$work"
spp_axis=$(python3 -c "import math; print(max(1, round(math.sqrt($spp))))")
common=(--variant test --views "$views" --test-views 0 --resolution "$resolution" --spp-axis "$spp_axis" --env "$env")
# the slab: 1 x 0.4 x 0.2, each face a grid of squares about 0.02 across, so
# that its interpolated normals bend only along the edges (on a slab of 12
# triangles they bend across whole faces, and the two renderers treat a
# shading normal far from the geometric one differently: docs/independent-renders.md)
python3 - "$work/slab.obj" <<'PY'
import sys
size, step = (1.0, 0.4, 0.2), 0.02
index, verts, faces = {}, [], []
def vertex(p):
    key = tuple(round(c, 6) for c in p)
    if key not in index:
        index[key] = len(verts) + 1
        verts.append(key)
    return index[key]
for axis in range(3):
    u, v = (axis + 1) % 3, (axis + 2) % 3
    nu, nv = max(1, round(size[u] / step)), max(1, round(size[v] / step))
    for side in (-1, 1):
        for i in range(nu):
            for j in range(nv):
                quad = []
                for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    p = [0.0, 0.0, 0.0]
                    p[axis] = side * size[axis] / 2
                    p[u] = -size[u] / 2 + size[u] * (i + di) / nu
                    p[v] = -size[v] / 2 + size[v] * (j + dj) / nv
                    quad.append(vertex(p))
                if side < 0:
                    quad.reverse()
                faces += [(quad[0], quad[1], quad[2]), (quad[0], quad[2], quad[3])]
with open(sys.argv[1], "w") as f:
    f.writelines(f"v {x} {y} {z}\n" for x, y, z in verts)
    f.writelines(f"f {a} {b} {c}\n" for a, b, c in faces)
PY
"$dt" synth --mesh "$work/slab.obj" --ior 1.5 "${common[@]}" --out "$work/slab/difftrans" 2> "$work/slab.log"
"$dt" synth --preset spot-clear "${common[@]}" --out "$work/spot-clear/difftrans" 2> "$work/spot-clear.log"
"$dt" synth --preset horse-green "${common[@]}" --out "$work/horse-green/difftrans" 2> "$work/horse-green.log"

for name in slab spot-clear horse-green; do
  for seed in 0 1; do
    blender -b --factory-startup --python-exit-code 1 -P "$root/scripts/blender_scene.py" -- \
      --scene "$work/$name/difftrans" --out "$work/$name/cycles_seed$seed" --spp "$spp" --seed "$seed" \
      --split train > "$work/$name/cycles_seed$seed.log" 2>&1 ||
      { tail -5 "$work/$name/cycles_seed$seed.log" >&2; echo "blender_check: Cycles failed on $name" >&2; exit 1; }
  done
  "$dt" evaluate --pred-images "$work/$name/cycles_seed0/images" --gt-images "$work/$name/difftrans/images" \
    --masks "$work/$name/difftrans/masks" --out "$work/$name/against_difftrans.json" > /dev/null 2>&1
  "$dt" evaluate --pred-images "$work/$name/cycles_seed1/images" --gt-images "$work/$name/cycles_seed0/images" \
    --masks "$work/$name/difftrans/masks" --out "$work/$name/cycles_noise.json" > /dev/null 2>&1
done

python3 - "$work" "$spp" "$spp_axis" "$min_psnr" <<'PY'
import json, os, sys, struct, zlib
work, spp, axis, min_psnr = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])

def png_gray(path):
    """Greyscale or RGB(A) 8-bit PNG -> rows of the first channel (the masks)."""
    d = open(path, "rb").read()
    i, idat = 8, b""
    while i < len(d):
        n = struct.unpack(">I", d[i:i + 4])[0]
        kind = d[i + 4:i + 8]
        if kind == b"IHDR":
            w, h, depth, ctype = struct.unpack(">IIBB", d[i + 8:i + 18])
        elif kind == b"IDAT":
            idat += d[i + 8:i + 8 + n]
        i += 12 + n
    raw = zlib.decompress(idat)
    bpp = {0: 1, 2: 3, 4: 2, 6: 4}[ctype]
    stride, prev, rows = w * bpp, bytearray(w * bpp), []
    for r in range(h):
        f = raw[r * (stride + 1)]
        line = bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b, c = prev[x], (prev[x - bpp] if x >= bpp else 0)
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line[::bpp]))
        prev = line
    return b"".join(rows)

report, ok = {"samples_per_pixel": {"cycles": spp, "difftrans": axis * axis}, "scenes": {}}, True
print(f"{'scene':<12} {'PSNR':>7} {'in mask':>8} {'noise PSNR':>11} {'noise in mask':>14} {'mask pixels differing':>22}")
for name in ("slab", "spot-clear", "horse-green"):
    ours = json.load(open(os.path.join(work, name, "against_difftrans.json")))
    noise = json.load(open(os.path.join(work, name, "cycles_noise.json")))
    masks = os.path.join(work, name, "difftrans", "masks")
    differ = total = 0
    for m in sorted(os.listdir(masks)):
        a = png_gray(os.path.join(masks, m))
        b = png_gray(os.path.join(work, name, "cycles_seed0", "masks", m))
        differ += sum((x > 127) != (y > 127) for x, y in zip(a, b))
        total += len(a)
    report["scenes"][name] = {"psnr": ours["psnr"], "psnr_mask": ours["psnr_mask"], "noise_psnr": noise["psnr"],
                              "noise_psnr_mask": noise["psnr_mask"], "mask_pixels_differing": differ,
                              "mask_pixels": total, "views": ours["count"]}
    print(f"{name:<12} {ours['psnr']:7.2f} {ours['psnr_mask']:8.2f} {noise['psnr']:11.2f} {noise['psnr_mask']:14.2f} "
          f"{differ:>12} of {total}")
    ok = ok and ours["psnr"] >= min_psnr
json.dump(report, open(os.path.join(work, "blender_check.json"), "w"), indent=2)
if not ok:
    sys.exit(f"blender_check: a scene's PSNR is below {min_psnr} dB")
PY
