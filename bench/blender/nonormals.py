"""A glTF written by hand (no Blender export): a room and a box of 8 shared vertices, with NO
NORMAL attribute, lit by an equirectangular sky through a window. Cycles renders it as Blender's
importer reads it.

Run with Blender 3.4 from the repository root (outputs go to --out, not the repository):

    blender -b --factory-startup -t 1 -P bench/blender/nonormals.py -- \
        --out /work/refs/nonormals [--portalview target/release/portalview]

The file (`scene.gltf` + `scene.bin` + `sky.hdr`, glTF Y up, metres): the same 4 x 2.6 x 5 m room
as hdri_room.py (x in [-2, 2], y in [0, 2.6], z in [-2.5, 2.5]) with a 1.6 x 1.2 m window in the
z = -2.5 wall (sill 0.9 m), as indexed triangles wound counter-clockwise seen from inside; a
0.8 m box of 8 shared vertices and 12 outward triangles on the floor, turned 10 degrees about +Y
by its node; a window portal quad (winding: its face normal into the room, +Z) whose node's
extras say portal_target = "environment"; a camera. No primitive has NORMAL, so glTF 3.7.2.1
asks for flat normals (a loader that averages the box's shared vertices shades it round).
Materials are Lambertian (metallic 0, KHR_materials_specular specularColorFactor 0), double
sided. The scene's extras name the environment: `sky.hdr`, an RGBE image written here (a blue
gradient sky, a dim ground, a 4 degree sun at 45 degrees elevation shining through the window).

Blender imports the file (flat shading without NORMAL), the world is set to the same sky
(Environment Texture, Linear, no rotation), Principled BSDFs are swapped for Diffuse BSDFs, the
portal object is hidden and a Cycles light portal added in the window; Cycles renders with
max_bounces = depth - 1 (two seeds), and transparent-film renders give the `sky`, `room` and
`box` (the box's own pixels) masks. Renders are kept and reused; --force renders again. With
--portalview, the file is rendered with it and compared as in hdri_room.py.
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (  # noqa: E402
    alpha_mask, cycles_two_seeds, cycles_window_portal, principled_to_diffuse,
    print_region_table, region_stats, run_portalview, script_argv, set_resolution, write_json,
)

X, H, Z = 2.0, 2.6, 2.5  # the room: x in [-X, X], y in [0, H], z in [-Z, Z]
WINDOW = (-0.8, 0.8, 0.9, 2.1)  # x0, x1, y0, y1 in the z = -Z wall
BOX = {"centre": (-1.2, 0.4, -1.0), "half": 0.4, "turn_degrees": 10.0}
CAMERA_AT = (1.3, 1.1, 2.2)
CAMERA_TARGET = (-0.3, 1.45, -2.5)
YFOV = 2 * math.atan(math.tan(math.radians(45.0)) * 0.75)  # 90 degrees across at 4:3
SUN = {"elevation": 45.0, "azimuth": 15.0, "radius": 4.0, "radiance": 400.0}
SKY_SIZE = (512, 256)
BOUNCES = ("diffuse",)  # limited to depth - 1 as max_bounces (glossy, transmission: Blender's)


def args():
    p = argparse.ArgumentParser()
    p.add_argument("--out", default="/work/refs/nonormals")
    p.add_argument("--portalview")
    p.add_argument("--depth", type=int, default=1, help="path depth (1 = direct light only)")
    p.add_argument("--width", type=int, default=192)
    p.add_argument("--height", type=int, default=144)
    p.add_argument("--spp", type=int, default=1024, help="Cycles samples per pixel per seed")
    p.add_argument("--pv-spp", type=int, default=256)
    p.add_argument("--pv-threads", type=int, default=1)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--force", action="store_true")
    return p.parse_args(script_argv())


# --- the sky ----------------------------------------------------------------------------------


def sun_direction():
    el, az = math.radians(SUN["elevation"]), math.radians(SUN["azimuth"])
    # Out through the window (-Z), a little toward +X.
    return np.array([math.cos(el) * math.sin(az), math.sin(el), -math.cos(el) * math.cos(az)])


def sky_image(width, height):
    """Linear RGB (h, w, 3), top row first, in Blender's / portalview's mapping: for a direction d
    (glTF), u = 0.5 + atan2(d.z, d.x) / 2 pi and the row from the top is acos(d.y) / pi."""
    u = (np.arange(width) + 0.5) / width
    t = (np.arange(height) + 0.5) / height
    phi = (u - 0.5) * 2 * math.pi
    theta = t * math.pi
    d = np.stack(
        [
            np.sin(theta)[:, None] * np.cos(phi)[None, :],
            np.cos(theta)[:, None] * np.ones_like(phi)[None, :],
            np.sin(theta)[:, None] * np.sin(phi)[None, :],
        ],
        -1,
    )
    up = np.clip(d[..., 1], 0.0, 1.0)
    horizon = np.array([0.9, 0.95, 1.0])
    zenith = np.array([0.25, 0.45, 0.9])
    ground = np.array([0.18, 0.16, 0.14])
    sky = horizon + (zenith - horizon) * up[..., None] ** 0.5
    img = np.where(d[..., 1:2] >= 0.0, sky, ground)
    cos_sun = d @ sun_direction()
    img = img + np.where(cos_sun > math.cos(math.radians(SUN["radius"])), SUN["radiance"], 0.0)[
        ..., None
    ] * np.array([1.0, 0.95, 0.85])
    return img


def write_hdr(path, img):
    """Radiance RGBE, each scanline run-length encoded with literal runs only."""
    h, w, _ = img.shape
    m = img.max(axis=-1)
    e = np.zeros_like(m, dtype=np.int32)
    mant = np.zeros_like(m)
    nz = m > 1e-32
    mant[nz], e[nz] = np.frexp(m[nz])
    scale = np.where(nz, mant * 256.0 / np.where(nz, m, 1.0), 0.0)
    rgbe = np.zeros((h, w, 4), dtype=np.uint8)
    rgbe[..., :3] = np.clip(np.floor(img * scale[..., None]), 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(nz, e + 128, 0).astype(np.uint8)
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
        f.write(f"-Y {h} +X {w}\n".encode())
        for row in rgbe:
            f.write(bytes([2, 2, w >> 8, w & 0xFF]))
            for c in range(4):
                data = row[:, c].tobytes()
                for k in range(0, w, 128):
                    chunk = data[k : k + 128]
                    f.write(bytes([len(chunk)]) + chunk)


# --- the glTF ---------------------------------------------------------------------------------


def room_triangles():
    """Positions and CCW-from-inside triangles of the room (shared vertices per quad)."""
    wx0, wx1, wy0, wy1 = WINDOW
    quads = [
        # floor (normal +Y), ceiling (-Y)
        [(-X, 0, -Z), (-X, 0, Z), (X, 0, Z), (X, 0, -Z)],
        [(-X, H, -Z), (X, H, -Z), (X, H, Z), (-X, H, Z)],
        # south wall z = +Z (normal -Z), west x = -X (+X), east x = +X (-X)
        [(-X, 0, Z), (-X, H, Z), (X, H, Z), (X, 0, Z)],
        [(-X, 0, -Z), (-X, H, -Z), (-X, H, Z), (-X, 0, Z)],
        [(X, 0, -Z), (X, 0, Z), (X, H, Z), (X, H, -Z)],
    ]
    # The window wall z = -Z (normal +Z): below, above, left, right of the opening.
    for (x0, y0), (x1, y1) in [
        ((-X, 0), (X, wy0)),
        ((-X, wy1), (X, H)),
        ((-X, wy0), (wx0, wy1)),
        ((wx1, wy0), (X, wy1)),
    ]:
        quads.append([(x0, y0, -Z), (x1, y0, -Z), (x1, y1, -Z), (x0, y1, -Z)])
    return quads_to_mesh(quads)


def quads_to_mesh(quads):
    positions, triangles = [], []
    for q in quads:
        k = len(positions)
        positions.extend(q)
        triangles.extend([(k, k + 1, k + 2), (k, k + 2, k + 3)])
    return np.array(positions, dtype=np.float32), np.array(triangles, dtype=np.uint32)


def box_mesh():
    """A cube of 8 shared vertices (local, centred), 12 triangles wound outward."""
    s = BOX["half"]
    v = np.array(
        [[x, y, z] for x in (-s, s) for y in (-s, s) for z in (-s, s)], dtype=np.float32
    )  # index = 4 * (x > 0) + 2 * (y > 0) + (z > 0)
    faces = [
        (0, 1, 3, 2),  # -X
        (4, 6, 7, 5),  # +X
        (0, 4, 5, 1),  # -Y
        (2, 3, 7, 6),  # +Y
        (0, 2, 6, 4),  # -Z
        (1, 5, 7, 3),  # +Z
    ]
    tris = []
    for a, b, c, d in faces:
        tris += [(a, b, c), (a, c, d)]
    tris = np.array(tris, dtype=np.uint32)
    # Check the winding: each face's normal points away from the centre.
    for t in tris:
        n = np.cross(v[t[1]] - v[t[0]], v[t[2]] - v[t[0]])
        assert np.dot(n, v[t].mean(0)) > 0
    return v, tris


def portal_mesh():
    wx0, wx1, wy0, wy1 = WINDOW
    p, t = quads_to_mesh([[(wx0, wy0, -Z), (wx1, wy0, -Z), (wx1, wy1, -Z), (wx0, wy1, -Z)]])
    n = np.cross(p[t[0][1]] - p[t[0][0]], p[t[0][2]] - p[t[0][0]])
    assert n[2] > 0  # into the room
    return p, t


def look_at_quaternion(eye, target):
    """glTF camera node rotation (x, y, z, w): the camera looks along its -Z, +Y up."""
    f = np.array(target, float) - np.array(eye, float)
    f /= np.linalg.norm(f)
    right = np.cross(f, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    m = np.stack([right, up, -f], axis=1)  # columns: local X, Y, Z in world
    w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = (m[2, 1] - m[1, 2]) / (4 * w)
    y = (m[0, 2] - m[2, 0]) / (4 * w)
    z = (m[1, 0] - m[0, 1]) / (4 * w)
    return [x, y, z, w]


def write_gltf(out, width, height):
    blob = bytearray()
    views, accessors = [], []

    def add(array, target, kind):
        while len(blob) % 4:
            blob.append(0)
        data = np.ascontiguousarray(array).tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob.extend(data)
        acc = {
            "bufferView": len(views) - 1,
            "componentType": 5126 if array.dtype == np.float32 else 5125,
            "count": int(array.shape[0] if kind != "SCALAR" else array.size),
            "type": kind,
        }
        if kind == "VEC3":
            acc["min"] = array.min(0).tolist()
            acc["max"] = array.max(0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    meshes = []
    for name, (pos, tri), material in [
        ("Room", room_triangles(), 0),
        ("Box", box_mesh(), 1),
        ("Window", portal_mesh(), 2),
    ]:
        p = add(pos, 34962, "VEC3")
        i = add(tri.ravel(), 34963, "SCALAR")
        meshes.append(
            {"name": name, "primitives": [{"attributes": {"POSITION": p}, "indices": i, "material": material}]}
        )

    def lambert(name, color):
        return {
            "name": name,
            "doubleSided": True,
            "pbrMetallicRoughness": {
                "baseColorFactor": [*color, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            },
            "extensions": {"KHR_materials_specular": {"specularColorFactor": [0.0, 0.0, 0.0]}},
        }

    turn = math.radians(BOX["turn_degrees"])
    gltf = {
        "asset": {"version": "2.0", "generator": "portalview bench/blender/nonormals.py"},
        "extensionsUsed": ["KHR_materials_specular"],
        "scene": 0,
        "scenes": [
            {
                "name": "Scene",
                "nodes": [0, 1, 2, 3],
                "extras": {
                    "environment": "sky.hdr",
                    "environment_strength": 1.0,
                    "environment_rotation": 0.0,
                    "environment_interpolation": "linear",
                },
            }
        ],
        "nodes": [
            {"name": "Room", "mesh": 0},
            {
                "name": "Box",
                "mesh": 1,
                "translation": list(BOX["centre"]),
                "rotation": [0.0, math.sin(turn / 2), 0.0, math.cos(turn / 2)],
            },
            {"name": "Window", "mesh": 2, "extras": {"portal_target": "environment"}},
            {
                "name": "Camera",
                "camera": 0,
                "translation": list(CAMERA_AT),
                "rotation": look_at_quaternion(CAMERA_AT, CAMERA_TARGET),
            },
        ],
        "cameras": [
            {
                "type": "perspective",
                "perspective": {"yfov": YFOV, "aspectRatio": width / height, "znear": 0.01},
            }
        ],
        "meshes": meshes,
        "materials": [
            lambert("Walls", (0.8, 0.78, 0.72)),
            lambert("Box", (0.7, 0.25, 0.15)),
            lambert("Portal", (0.0, 0.0, 0.0)),
        ],
        "buffers": [{"uri": "scene.bin", "byteLength": len(blob)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    with open(os.path.join(out, "scene.bin"), "wb") as f:
        f.write(blob)
    path = os.path.join(out, "scene.gltf")
    with open(path, "w") as f:
        json.dump(gltf, f, indent=1)
    return path


# --- Blender and Cycles -----------------------------------------------------------------------


def blender_scene(gltf, hdr, width, height):
    import bpy

    import numpy

    if not hasattr(numpy, "bool"):
        numpy.bool = bool  # the 3.4 importer uses numpy.bool, gone in numpy 2
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=gltf)
    scene = bpy.context.scene
    for obj in scene.objects:
        if "portal_target" in obj:
            obj.hide_render = True
        if obj.type == "CAMERA":
            scene.camera = obj
        if obj.type == "MESH":
            smooth = sum(p.use_smooth for p in obj.data.polygons)
            print(f"imported {obj.name}: {len(obj.data.vertices)} vertices, "
                  f"{len(obj.data.polygons)} faces, {smooth} smooth-shaded")
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdr)
    env.interpolation = "Linear"
    links.new(env.outputs["Color"], nodes["Background"].inputs["Color"])
    nodes["Background"].inputs["Strength"].default_value = 1.0
    principled_to_diffuse()
    # A Cycles light portal in the window (Blender Z up: the window is at y = +Z, facing -Y).
    wx0, wx1, wy0, wy1 = WINDOW
    cycles_window_portal(wx0, wx1, wy0, wy1, Z)
    set_resolution(scene, width, height)


def main():
    a = args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    hdr = os.path.join(out, "sky.hdr")
    write_hdr(hdr, sky_image(*SKY_SIZE))
    gltf = write_gltf(out, a.width, a.height)
    print(f"wrote {gltf} and {hdr}")
    blender_scene(gltf, hdr, a.width, a.height)
    alpha = alpha_mask(os.path.join(out, "mask.exr"), a.force, threads=a.threads, limit=BOUNCES)
    box = alpha_mask(os.path.join(out, "mask-box.exr"), a.force, only="Box", threads=a.threads,
                     limit=BOUNCES)
    masks = {"room": alpha > 0.999, "sky": alpha < 0.001, "box": box > 0.999}
    cycles = cycles_two_seeds(os.path.join(out, f"cycles-d{a.depth}"), a.spp, a.force,
                              threads=a.threads, depth=a.depth, limit=BOUNCES)
    pv = None
    if a.portalview:
        pv = run_portalview(a.portalview, gltf, os.path.join(out, "portalview", f"d{a.depth}.exr"),
                            a, depth=a.depth)
    rows = region_stats(cycles, pv, masks)
    print_region_table(rows)
    write_json(os.path.join(out, f"table-d{a.depth}.json"), rows)


main()
