"""Re-renders a difftrans scene folder with Blender's Cycles path tracer.

Run inside Blender (Debian package `blender`, headless):

    blender -b --factory-startup --python-exit-code 1 -P scripts/blender_scene.py -- \
        --scene SCENE --out OUT [--spp 256] [--bounces 16] [--seed 0] [--split train,test] [--threads 0]

SCENE is a folder written by `difftrans synth` (gt/mesh.obj, gt/material.json,
gt/envmap.hdr, transforms_train.json, transforms_test.json, scene.json). OUT
becomes a scene folder of the same layout whose photographs and masks come
from Cycles instead of difftrans: images/NAME.exr (linear RGB), masks/NAME.png
(the ray through the pixel centre hits the object, cast by Blender's own BVH),
the transforms, scene.json and gt/ copied, and gt/cycles.json saying how the
images were made. `difftrans reconstruct OUT` then fits photographs that the
renderer fitting them did not make.

Conventions (docs/independent-renders.md; checked by scripts/blender_check.sh):
- the scene's frame is used as is (no axis conversion): the mesh's vertices
  and the cameras' camera-to-world matrices (OpenGL cameras: -z forward, +y up,
  as Blender's) go in unchanged;
- the environment: difftrans maps a direction d to u = 1/2 + atan2(d.x, -d.z)
  / 2 pi, v = acos(d.y) / pi with v = 0 the map's top row; Cycles' world
  texture reads a direction D with z up and u = 0 at -x. D = (-d.z, -d.x, d.y)
  makes the two read the same texel;
- the object is a smooth dielectric (Glass BSDF, sharp) with the scene's IoR,
  shaded with its vertex normals as difftrans defines them (the normalized sum
  of the unit normals of the triangles around a vertex, set as custom normals);
  a homogeneous absorption sigma becomes a Volume Absorption of density
  max(sigma) and colour 1 - sigma / max(sigma) (Cycles absorbs (1 - colour) x
  density per unit length);
- pixels: a box filter one pixel wide, no clamping, no denoising, no adaptive
  sampling; the bounce limits all `--bounces` (difftrans' depth counts
  surface interactions the same way).
Grid absorption has no counterpart here (the script stops with a message).
"""
import argparse
import json
import math
import os
import shutil
import struct
import sys
import time
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from obj_file import ObjError, read_obj  # noqa: E402 (after the path)

import bpy
from mathutils import Matrix, Vector


def fail(message):
    print(f"blender_scene: {message}", file=sys.stderr)
    sys.exit(1)


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except OSError as e:
        fail(f"{path}: {e.strerror}")
    except json.JSONDecodeError as e:
        fail(f"{path}:{e.lineno}: {e.msg}")


def vertex_normals(verts, tris):
    """difftrans' vertex normals: the normalized sum of the unit face normals around each vertex."""
    acc = [Vector((0.0, 0.0, 0.0)) for _ in verts]
    for a, b, c in tris:
        n = (Vector(verts[b]) - Vector(verts[a])).cross(Vector(verts[c]) - Vector(verts[a]))
        if n.length > 0.0:
            n.normalize()
            for i in (a, b, c):
                acc[i] += n
    return [n.normalized() if n.length > 0.0 else Vector((0.0, 0.0, 1.0)) for n in acc]


def write_png_gray(path, width, height, rows):
    """8-bit greyscale PNG; rows top to bottom, each a bytes of width values."""
    raw = b"".join(b"\x00" + r for r in rows)

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def build_object(scene_dir, material):
    try:
        verts, tris = read_obj(os.path.join(scene_dir, "gt", "mesh.obj"))
    except ObjError as e:
        fail(str(e))
    mesh = bpy.data.meshes.new("object")
    mesh.from_pydata(verts, [], tris)
    mesh.validate(clean_customdata=False)
    mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
    mesh.use_auto_smooth = True  # custom normals need it (Blender 3.x)
    mesh.normals_split_custom_set_from_vertices(vertex_normals(verts, tris))
    obj = bpy.data.objects.new("object", mesh)
    bpy.context.scene.collection.objects.link(obj)

    mat = bpy.data.materials.new("dielectric")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    glass = nodes.new("ShaderNodeBsdfGlass")
    glass.distribution = "SHARP"
    glass.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    glass.inputs["IOR"].default_value = float(material["ior"])
    links.new(glass.outputs["BSDF"], out.inputs["Surface"])
    absorption = material.get("absorption", {"type": "none"})
    kind = absorption.get("type", "none")
    if kind == "homogeneous":
        sigma = [float(s) for s in absorption["sigma"]]
        density = max(sigma)
        if density > 0.0:
            vol = nodes.new("ShaderNodeVolumeAbsorption")
            vol.inputs["Density"].default_value = density
            vol.inputs["Color"].default_value = tuple(1.0 - s / density for s in sigma) + (1.0,)
            links.new(vol.outputs["Volume"], out.inputs["Volume"])
            mat.cycles.homogeneous_volume = True
    elif kind != "none":
        fail(f"gt/material.json: absorption '{kind}' has no Cycles counterpart here (none or homogeneous only)")
    obj.data.materials.append(mat)
    return obj, len(verts), len(tris)


def build_world(scene_dir):
    path = os.path.join(scene_dir, "gt", "envmap.hdr")
    if not os.path.isfile(path):
        fail(f"{path}: no such file (a distant environment map is needed)")
    world = bpy.data.worlds.new("environment")
    bpy.context.scene.world = world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    coords = nodes.new("ShaderNodeTexCoord")
    split = nodes.new("ShaderNodeSeparateXYZ")
    join = nodes.new("ShaderNodeCombineXYZ")
    neg_x, neg_z = nodes.new("ShaderNodeMath"), nodes.new("ShaderNodeMath")
    for n in (neg_x, neg_z):
        n.operation = "MULTIPLY"
        n.inputs[1].default_value = -1.0
    links.new(coords.outputs["Generated"], split.inputs["Vector"])
    # D = (-d.z, -d.x, d.y): difftrans' (u, v) of d is Cycles' (u, v) of D
    links.new(split.outputs["Z"], neg_z.inputs[0])
    links.new(split.outputs["X"], neg_x.inputs[0])
    links.new(neg_z.outputs["Value"], join.inputs["X"])
    links.new(neg_x.outputs["Value"], join.inputs["Y"])
    links.new(split.outputs["Y"], join.inputs["Z"])
    tex = nodes.new("ShaderNodeTexEnvironment")
    tex.projection = "EQUIRECTANGULAR"
    tex.interpolation = "Linear"
    try:
        tex.image = bpy.data.images.load(path)
    except RuntimeError as e:
        fail(f"{path}: {e}")
    tex.image.colorspace_settings.name = "Linear"
    links.new(join.outputs["Vector"], tex.inputs["Vector"])
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = 1.0
    links.new(tex.outputs["Color"], background.inputs["Color"])
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(background.outputs["Background"], out.inputs["Surface"])


def configure(scene, width, height, a):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = a.spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = a.seed
    c.max_bounces = c.transmission_bounces = c.glossy_bounces = c.transparent_max_bounces = a.bounces
    c.diffuse_bounces = 0
    c.volume_bounces = 0
    c.caustics_reflective = c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.use_compositing = scene.render.use_sequencer = False
    if a.threads > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = a.threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    s = scene.render.image_settings
    s.file_format = "OPEN_EXR"
    s.color_mode = "RGB"
    s.color_depth = "32"
    s.exr_codec = "ZIP"


def make_camera(scene, transforms, path):
    w, h = int(transforms["w"]), int(transforms["h"])
    fx, fy = float(transforms["fl_x"]), float(transforms["fl_y"])
    cx, cy = float(transforms.get("cx", w / 2)), float(transforms.get("cy", h / 2))
    if abs(fx - fy) > 1e-3 * fx:
        fail(f"{path}: fl_x {fx} and fl_y {fy} differ (square pixels only)")
    if abs(cx - w / 2) > 1e-3 or abs(cy - h / 2) > 1e-3:
        fail(f"{path}: principal point ({cx}, {cy}) is not the image centre ({w / 2}, {h / 2})")
    data = bpy.data.cameras.new("camera")
    data.type = "PERSP"
    data.sensor_fit = "HORIZONTAL"
    data.angle_x = 2.0 * math.atan(0.5 * w / fx)
    data.clip_start, data.clip_end = 1e-3, 1e4
    cam = bpy.data.objects.new("camera", data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam, w, h, fx, cx, cy


def render_mask(scene, obj, matrix, w, h, f, cx, cy):
    """Rows (top to bottom) of 0/255: the ray through each pixel centre hits the object."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    rot = matrix.to_3x3()
    origin = matrix.translation
    rows = []
    for j in range(h):
        row = bytearray(w)
        for i in range(w):
            d = rot @ Vector(((i + 0.5 - cx) / f, -(j + 0.5 - cy) / f, -1.0))
            hit, _, _, _, hit_obj, _ = scene.ray_cast(depsgraph, origin, d.normalized())
            row[i] = 255 if hit and hit_obj.name == obj.name else 0
        rows.append(bytes(row))
    return rows


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="blender_scene.py", description="Re-render a difftrans scene with Cycles")
    ap.add_argument("--scene", required=True, help="scene folder written by difftrans synth")
    ap.add_argument("--out", required=True, help="scene folder to write (must not exist or be empty)")
    ap.add_argument("--spp", type=int, default=256, help="Cycles samples per pixel")
    ap.add_argument("--bounces", type=int, default=16, help="bounce limit (difftrans' depth)")
    ap.add_argument("--seed", type=int, default=0, help="Cycles' seed")
    ap.add_argument("--split", default="train,test", help="which transforms_SPLIT.json to render")
    ap.add_argument("--views", type=int, default=0, help="render only the first N views of each split (0: all)")
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    a = ap.parse_args(argv)
    if a.spp < 1 or a.bounces < 1:
        fail("--spp and --bounces must be positive")
    if os.path.isdir(a.out) and os.listdir(a.out):
        fail(f"{a.out}: exists and is not empty")

    material = read_json(os.path.join(a.scene, "gt", "material.json"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    obj, nv, nt = build_object(a.scene, material)
    build_world(a.scene)

    splits = [s for s in a.split.split(",") if s]
    jobs = []
    size = None
    for split in splits:
        path = os.path.join(a.scene, f"transforms_{split}.json")
        t = read_json(path)
        frames = t.get("frames", [])
        if a.views > 0:
            frames = frames[: a.views]
        jobs.append((split, path, t, frames))
        size = size or (int(t["w"]), int(t["h"]))

    # the folder: copies of what does not change, then the renders
    os.makedirs(os.path.join(a.out, "gt"), exist_ok=True)
    for name in os.listdir(os.path.join(a.scene, "gt")):
        src = os.path.join(a.scene, "gt", name)
        if os.path.isfile(src):
            shutil.copy2(src, os.path.join(a.out, "gt", name))
    if os.path.isfile(os.path.join(a.scene, "scene.json")):
        shutil.copy2(os.path.join(a.scene, "scene.json"), os.path.join(a.out, "scene.json"))

    total = sum(len(f) for _, _, _, f in jobs)
    done, t0 = 0, time.time()
    for split, path, t, frames in jobs:
        cam, w, h, f, cx, cy = make_camera(scene, t, path)
        configure(scene, w, h, a)
        out_t = dict(t)
        out_t["frames"] = frames
        with open(os.path.join(a.out, f"transforms_{split}.json"), "w") as fo:
            json.dump(out_t, fo, indent=2)
        for frame in frames:
            image = os.path.join(a.out, frame["file_path"])
            mask = os.path.join(a.out, frame.get("mask_path", frame["file_path"].replace("images/", "masks/")))
            os.makedirs(os.path.dirname(image), exist_ok=True)
            os.makedirs(os.path.dirname(mask), exist_ok=True)
            cam.matrix_world = Matrix(frame["transform_matrix"])
            bpy.context.view_layer.update()
            scene.render.filepath = image
            bpy.ops.render.render(write_still=True)
            write_png_gray(mask, w, h, render_mask(scene, obj, cam.matrix_world, w, h, f, cx, cy))
            done += 1
            print(f"blender_scene: {done}/{total} {frame['file_path']} ({time.time() - t0:.0f} s)", file=sys.stderr)

    with open(os.path.join(a.out, "gt", "cycles.json"), "w") as fo:
        json.dump({"renderer": f"Blender {bpy.app.version_string} Cycles (CPU)", "source": os.path.abspath(a.scene),
                   "samples_per_pixel": a.spp, "bounces": a.bounces, "seed": a.seed, "pixel_filter": "box, 1 pixel",
                   "mesh": {"vertices": nv, "triangles": nt}, "views": total, "seconds": round(time.time() - t0, 1)},
                  fo, indent=2)


if __name__ == "__main__":
    main()
