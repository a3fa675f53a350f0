#!/usr/bin/env python3
"""How a reconstructed sphere's surface is wrong: the radius vertex by vertex
(mean and spread), the correlation of two vertices' radial errors against
their distance along the sphere (how much of the error lives at the scale of
one edge), and optionally the mesh with every vertex moved radially onto the
true sphere (same triangles), for `difftrans evaluate` to tell the error of the
positions from that of the triangulation.

    python3 scripts/sphere_noise.py MESH.obj [--radius 0.5] [--center X,Y,Z]
        [--pairs 400000] [--bin 0.01] [--bins 12] [--projected OUT.obj]

The sphere is the true one of the scene (`difftrans shape sphere-N` makes
radius 0.5 at the origin). Pure Python, no dependencies; pairs are drawn at
random with a fixed seed.
"""
import argparse
import math
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from obj_file import ObjError, read_obj  # noqa: E402 (after the path)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mesh")
    p.add_argument("--radius", type=float, default=0.5)
    p.add_argument("--center", default="0,0,0")
    p.add_argument("--pairs", type=int, default=400000)
    p.add_argument("--bin", type=float, default=0.01, help="width of a distance bin (arc length)")
    p.add_argument("--bins", type=int, default=12)
    p.add_argument("--projected", help="write the mesh moved radially onto the sphere here")
    a = p.parse_args()
    c = tuple(float(x) for x in a.center.split(","))
    try:
        vertices, faces = read_obj(a.mesh)
    except ObjError as e:
        sys.exit(f"sphere_noise: {e}")
    offset = [tuple(v[i] - c[i] for i in range(3)) for v in vertices]
    radius = [math.sqrt(sum(x * x for x in o)) for o in offset]
    if min(radius) <= 0.0:
        sys.exit("sphere_noise: a vertex sits at the centre")
    mean = sum(radius) / len(radius)
    error = [r - mean for r in radius]
    variance = sum(e * e for e in error) / len(error)
    unit = [tuple(x / r for x in o) for o, r in zip(offset, radius)]
    edges = [(f[k], f[(k + 1) % len(f)]) for f in faces for k in range(len(f))]
    edge = sum(math.dist(vertices[i], vertices[j]) for i, j in edges) / len(edges) if edges else float("nan")
    print(f"{a.mesh}: {len(vertices)} vertices, mean edge {edge:.4f}")
    print(f"radius {mean:.5f} (true {a.radius}), standard deviation {math.sqrt(variance):.5f}")
    rng = random.Random(1)
    sums = [[0, 0.0] for _ in range(a.bins)]
    n = len(vertices)
    for _ in range(a.pairs):
        i, j = rng.randrange(n), rng.randrange(n)
        if i == j:
            continue
        cos = max(-1.0, min(1.0, sum(x * y for x, y in zip(unit[i], unit[j]))))
        b = int(math.acos(cos) * a.radius / a.bin)
        if b < a.bins:
            sums[b][0] += 1
            sums[b][1] += error[i] * error[j]
    print("arc distance  pairs  correlation of the radial errors")
    for b, (count, total) in enumerate(sums):
        if count:
            print(f"{(b + 0.5) * a.bin:12.4f} {count:6d} {total / count / variance:8.3f}")
    if a.projected:
        with open(a.projected, "w") as f:
            for u in unit:
                f.write("v %.9g %.9g %.9g\n" % tuple(c[i] + a.radius * u[i] for i in range(3)))
            for face in faces:
                f.write("f " + " ".join(str(i + 1) for i in face) + "\n")
        print(f"wrote {a.projected}")


if __name__ == "__main__":
    main()
