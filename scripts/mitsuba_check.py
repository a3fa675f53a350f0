#!/usr/bin/env python3
"""Checks that `difftrans export --format mitsuba` means what difftrans renders.

Needs the mitsuba wheel (pip install mitsuba numpy, e.g. in a virtual
environment; not a dependency of the project) and a built difftrans command.

It synthesizes a small scene (difftrans synth), exports its ground truth as a
Mitsuba 3 scene (difftrans export --mesh/--material/--env/--scene), renders the
test cameras with difftrans render and with Mitsuba (one render per sensor of
scene.xml), and compares them with difftrans evaluate (PSNR over the image and
inside the object's mask, on the tone-mapped images of docs/metrics.md). Writes
WORK/side_by_side.png (rows: difftrans | Mitsuba | 4 x |difference|) and
WORK/comparison.json, prints the figures, and exits non-zero when the mean
PSNR falls below --min-psnr.

Usage: scripts/mitsuba_check.py [--difftrans build/release/examples/difftrans]
           [--preset horse-green] [--work /tmp/mitsuba_check] [--spp 1024]
           [--variant scalar_rgb] [--resolution 96] [--test-views 4] [--env MAP|preset]
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

try:
    import mitsuba as mi
except ImportError:
    sys.exit("mitsuba_check: needs the mitsuba wheel (pip install mitsuba numpy)")


def run(cmd):
    print("+ " + " ".join(cmd), file=sys.stderr)
    r = subprocess.run(cmd, stdout=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit(f"mitsuba_check: {cmd[0]} {cmd[1]} failed ({r.returncode})")
    return r.stdout


def preview(rgb):
    """Linear RGB -> 8-bit sRGB (clamped), for the side-by-side picture."""
    x = np.clip(rgb, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (x * 255 + 0.5).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--difftrans", default="build/release/examples/difftrans")
    ap.add_argument("--preset", default="horse-green", help="synth preset (spot-clear, bunny-clear, horse-green, monkey-bands)")
    ap.add_argument("--env", default="data/envmaps/blouberg_sunrise_2_1k.hdr",
                    help="environment map for synth ('preset': the preset's own; a sun makes both renderers noisy)")
    ap.add_argument("--work", default="/tmp/mitsuba_check")
    ap.add_argument("--spp", type=int, default=1024, help="Mitsuba samples per pixel")
    ap.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (scalar_rgb, llvm_ad_rgb, ...)")
    ap.add_argument("--resolution", type=int, default=96)
    ap.add_argument("--test-views", type=int, default=4)
    ap.add_argument("--max-depth", type=int, default=16)
    ap.add_argument("--spp-axis", type=int, default=16, help="difftrans render: n x n samples per pixel")
    ap.add_argument("--min-psnr", type=float, default=30.0, help="fail below this mean PSNR (dB)")
    a = ap.parse_args()

    dt, work = a.difftrans, a.work
    scene = os.path.join(work, "scene")
    export = os.path.join(work, "mitsuba")
    ours = os.path.join(work, "difftrans")
    theirs = os.path.join(work, "mitsuba_renders")
    gt = lambda name: os.path.join(scene, "gt", name)

    env = [] if a.env == "preset" else ["--env", a.env]
    run([dt, "synth", "--preset", a.preset, "--variant", "test", "--resolution", str(a.resolution), "--views", "4",
         "--test-views", str(a.test_views), "--spp-axis", "1", "--overwrite", "--out", scene] + env)
    run([dt, "export", "--format", "mitsuba", "--mesh", gt("mesh.obj"), "--material", gt("material.json"),
         "--env", gt("envmap.hdr"), "--scene", scene, "--split", "test", "--spp", str(a.spp),
         "--max-depth", str(a.max_depth), "--overwrite", "--out", export])
    run([dt, "render", "--mesh", gt("mesh.obj"), "--material", gt("material.json"), "--env", gt("envmap.hdr"),
         "--scene", scene, "--split", "test", "--max-depth", str(a.max_depth), "--spp-axis", str(a.spp_axis),
         "--overwrite", "--out", ours])

    mi.set_variant(a.variant)
    ms = mi.load_file(os.path.join(export, "scene.xml"))
    # a second Mitsuba render with another seed: its distance to the first is Mitsuba's own noise
    os.makedirs(os.path.join(theirs, "images"), exist_ok=True)
    os.makedirs(os.path.join(theirs, "images_seed1"), exist_ok=True)
    rows = []
    for i, sensor in enumerate(ms.sensors()):
        name = sensor.id()
        img = np.array(mi.render(ms, sensor=i, spp=a.spp, seed=0), dtype=np.float32)[:, :, :3]
        mi.Bitmap(img).write(os.path.join(theirs, "images", name + ".exr"))
        again = np.array(mi.render(ms, sensor=i, spp=a.spp, seed=1), dtype=np.float32)[:, :, :3]
        mi.Bitmap(again).write(os.path.join(theirs, "images_seed1", name + ".exr"))
        mine = np.array(mi.Bitmap(os.path.join(ours, "images", name + ".exr")), dtype=np.float32)[:, :, :3]
        if len(rows) < 4:
            rows.append(np.concatenate([preview(mine), preview(img), preview(4 * np.abs(img - mine))], axis=1))
        print(f"mitsuba_check: rendered {name}", file=sys.stderr)
    if rows:
        mi.Bitmap(np.concatenate(rows, axis=0)).write(os.path.join(work, "side_by_side.png"))

    metrics = json.loads(run([dt, "evaluate", "--pred-images", os.path.join(theirs, "images"),
                              "--gt-images", os.path.join(ours, "images"), "--masks", os.path.join(ours, "masks"),
                              "--out", os.path.join(work, "comparison.json")]))
    noise = json.loads(run([dt, "evaluate", "--pred-images", os.path.join(theirs, "images_seed1"),
                            "--gt-images", os.path.join(theirs, "images"), "--masks", os.path.join(ours, "masks"),
                            "--out", os.path.join(work, "mitsuba_noise.json")]))
    print(f"mitsuba_check: {a.preset}, {metrics['count']} views, Mitsuba {mi.__version__} {a.variant} at {a.spp} spp "
          f"vs difftrans render: PSNR {metrics['psnr']:.2f} dB, in the mask {metrics['psnr_mask']:.2f} dB, "
          f"SSIM {metrics['ssim']:.4f}; {os.path.join(work, 'side_by_side.png')}")
    print(f"mitsuba_check: Mitsuba's own noise (seed 0 vs seed 1): PSNR {noise['psnr']:.2f} dB, "
          f"in the mask {noise['psnr_mask']:.2f} dB")
    for e in metrics["images"]:
        print(f"  {e['name']}: PSNR {e['psnr']:.2f} dB, mask {e.get('psnr_mask', float('nan')):.2f} dB")
    if metrics["psnr"] < a.min_psnr:
        sys.exit(f"mitsuba_check: mean PSNR {metrics['psnr']:.2f} dB is below {a.min_psnr} dB")


if __name__ == "__main__":
    main()
