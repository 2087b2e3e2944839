"""Does portalview render a Blender scene as Cycles does?

Run with Blender 3.4 (Debian's `blender` package) from the repository root:

    blender -b --factory-startup -P bench/blender/run.py -- \
        --portalview target/release/portalview --out /tmp/cycles-fidelity

It builds an artist's scene in Blender (a flat-shaded Suzanne lit at grazing angles, a textured
floor, a lampshade with an emissive bulb and a portal on each opening, a point lamp), exports it
with Blender's own glTF exporter, renders it with Cycles (direct light only, box filter of width
1, no clamping or denoising) and with portalview, each twice with different seeds, and compares:

- the mean of the whole image and of chosen regions, with the standard error of the difference
  estimated from the two seeds of each renderer;
- per 8x8 block, the z-score of the difference; with no systematic difference about 0.3% of
  blocks exceed |z| > 3 by chance.

Cycles renders Principled BSDF's diffuse with a retro-reflection term, so before rendering the
script swaps each exported Principled BSDF (Specular 0: a Lambertian surface in glTF) for a
Diffuse BSDF with the same colour input, the material the glTF file describes.
"""

import argparse
import math
import os
import subprocess
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (  # noqa: E402
    HERE, black_world, emission_material, export_gltf, lambert_material, load_exr,
    look_rotation, luminance, mesh_triangles, mitsuba_camera, mitsuba_point,
    principled_to_diffuse, render_cycles, script_argv, set_resolution, write_json, write_ply,
)

WIDTH, HEIGHT = 192, 144
BLOCK = 8
TRIANGULATE = "--triangulate" in sys.argv
BULB = "disc" if "disc" in sys.argv else "sphere"
INTERPOLATION = "Linear" if "Linear" in sys.argv else "Closest"


def args():
    p = argparse.ArgumentParser()
    p.add_argument("--portalview", default="target/release/portalview")
    p.add_argument("--out", default="/tmp/cycles-fidelity")
    p.add_argument("--spp", type=int, default=1024, help="Cycles samples per pixel per seed")
    p.add_argument("--pv-spp", type=int, default=1024, help="portalview spp per seed")
    p.add_argument("--strategy", default="antishadow")
    p.add_argument(
        "--sampler",
        default="independent",
        help="portalview's sampler: the block test needs each renderer's variance from two seeds",
    )
    p.add_argument("--triangulate", action="store_true", help="Suzanne's quads as triangles")
    p.add_argument(
        "--mitsuba-python",
        help="a Python with Mitsuba 3.9 (e.g. bench/peers/.venv/bin/python): also render with it",
    )
    p.add_argument(
        "--interpolation",
        default="Closest",
        choices=["Closest", "Linear"],
        help="the floor texture's filter (Cycles interpolates 8-bit sRGB before decoding it)",
    )
    p.add_argument(
        "--bulb", default="sphere", choices=["sphere", "disc"], help="the emissive mesh's shape"
    )
    p.add_argument("--no-texture", action="store_true", help="plain floor colour")
    return p.parse_args(script_argv())


def material(name, color, image=None):
    """A Principled BSDF with Specular 0 (exported as a Lambertian glTF material), its Base
    Color from `image` (filtered as INTERPOLATION) if given."""
    m = lambert_material(name, color)
    if image is not None:
        nodes = m.node_tree.nodes
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = INTERPOLATION
        m.node_tree.links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    return m


def checker(path, n=8, size=64):
    """An sRGB checkerboard PNG of n x n squares, saved next to the scene."""
    img = bpy.data.images.new("checker", size, size)
    px = np.zeros((size, size, 4), dtype=np.float32)
    cell = size // n
    for y in range(size):
        for x in range(size):
            light = ((x // cell) + (y // cell)) % 2 == 0
            px[y, x] = (0.8, 0.75, 0.6, 1.0) if light else (0.15, 0.25, 0.5, 1.0)
    img.pixels = px.ravel()
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    return img


def build_scene(out, textured):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    image = checker(os.path.join(out, "checker.png")) if textured else None
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 0))
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(material("Floor", (0.6, 0.6, 0.6), image))

    bpy.ops.mesh.primitive_monkey_add(size=1.2, location=(0, 0, 0.6), rotation=(0.35, 0, 0.4))
    suzanne = bpy.context.object
    suzanne.name = "Suzanne"
    suzanne.data.materials.append(material("Suzanne", (0.8, 0.3, 0.2)))
    if TRIANGULATE:
        suzanne.modifiers.new("Triangulate", "TRIANGULATE")

    # The lampshade: an open 12-sided cylinder, an emissive bulb (a sphere or a disc), and a
    # portal on each opening naming the bulb.
    shade_at = (1.3, 0.6, 1.5)
    bpy.ops.mesh.primitive_cylinder_add(
        vertices=12, radius=0.35, depth=0.5, end_fill_type="NOTHING", location=shade_at
    )
    shade = bpy.context.object
    shade.name = "Shade"
    shade.data.materials.append(material("Shade", (0.9, 0.9, 0.85)))

    if BULB == "sphere":
        bpy.ops.mesh.primitive_uv_sphere_add(
            segments=12, ring_count=6, radius=0.12, location=shade_at
        )
    else:
        bpy.ops.mesh.primitive_circle_add(
            vertices=12, radius=0.15, fill_type="NGON", location=shade_at
        )
    bulb = bpy.context.object
    bulb.name = "Bulb"
    bulb.data.materials.append(emission_material("Bulb", (1.0, 0.9, 0.7), 40.0))

    for name, dz in (("PortalBottom", -0.25), ("PortalTop", 0.25)):
        bpy.ops.mesh.primitive_circle_add(
            vertices=12,
            radius=0.35,
            fill_type="NGON",
            location=(shade_at[0], shade_at[1], shade_at[2] + dz),
        )
        portal = bpy.context.object
        portal.name = name
        portal["portal_target"] = "Bulb"
        portal.hide_render = True  # invisible to Cycles; portalview never renders portals

    # A point lamp level with Suzanne's head: its top and sides are lit at grazing angles.
    bpy.ops.object.light_add(type="POINT", location=(-1.8, -0.6, 1.25))
    lamp = bpy.context.object
    lamp.name = "Lamp"
    lamp.data.energy = 60.0
    lamp.data.shadow_soft_size = 0.0
    lamp.data.color = (0.8, 0.9, 1.0)

    bpy.ops.object.camera_add(location=(0.6, -3.6, 2.0))
    cam = bpy.context.object
    cam.name = "Camera"
    cam.rotation_euler = look_rotation(cam.location, (0.3, 0.0, 0.6))
    cam.data.lens = 35
    scene.camera = cam

    black_world(scene)
    set_resolution(scene, WIDTH, HEIGHT)


def mitsuba_scene(out):
    """The Blender scene as Mitsuba 3 sees it (for mitsuba_render.py): world-space PLYs,
    Lambertian `diffuse` colours or bitmaps, one-sided area emitters (a double-sided bulb is two,
    back to back), point lamps of P/(4π) W/sr, and the camera (Mitsuba looks down +Z with +X to
    the left: to_world = camera matrix x diag(-1, 1, -1, 1))."""
    shapes, points = [], []
    for obj in bpy.context.scene.objects:
        if obj.type == "LIGHT":
            points.append(mitsuba_point(obj))
        if obj.type != "MESH" or "portal_target" in obj:
            continue
        tris, uvs = mesh_triangles(obj)
        ply = os.path.join(out, f"mitsuba-{obj.name}.ply")
        write_ply(ply, tris, uvs)
        nodes = obj.active_material.node_tree.nodes
        shape = {"ply": ply, "color": [0.0, 0.0, 0.0]}
        if "Emission" in nodes:
            e = nodes["Emission"].inputs
            shape["radiance"] = [e["Strength"].default_value * c for c in e["Color"].default_value[:3]]
            n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            if np.all(n @ n[0] > 0.9999):
                # A flat emitter is seen from both sides, but Mitsuba's area emitters are
                # one-sided: a flipped copy 0.1 mm behind emits the other way, and rays from
                # the back meet it first. (A closed bulb's inside is never seen.)
                back = os.path.join(out, f"mitsuba-{obj.name}-back.ply")
                write_ply(back, tris - 1e-4 * n[0], uvs)
                shapes.append(dict(shape, ply=back, flip=True))
        else:
            p = nodes["Principled BSDF"].inputs["Base Color"]
            shape["color"] = list(p.default_value[:3])
            if p.links:
                tex = p.links[0].from_node
                shape["texture"] = bpy.path.abspath(tex.image.filepath_raw)
                shape["filter"] = "bilinear" if tex.interpolation == "Linear" else "nearest"
        shapes.append(shape)
    desc = {"camera": mitsuba_camera(WIDTH, HEIGHT), "shapes": shapes, "points": points}
    return write_json(os.path.join(out, "mitsuba.json"), desc)


def compare(ref, other):
    """Relative difference of the image means with its standard error, and per-block z-scores.

    Each renderer made two renders with different seeds; the variance of a pixel's two-seed
    mean is estimated from their difference, d^2 / 4, for both renderers."""
    lr, lo = luminance(ref), luminance(other)
    a, b = lr.mean(axis=0), lo.mean(axis=0)
    var = ((lr[0] - lr[1]) ** 2 + (lo[0] - lo[1]) ** 2) / 4.0
    rel = (b.mean() - a.mean()) / a.mean()
    se = math.sqrt(var.sum()) / a.size / a.mean()
    h, w = a.shape
    z = []
    for y in range(0, h - BLOCK + 1, BLOCK):
        for x in range(0, w - BLOCK + 1, BLOCK):
            sa, sb = a[y : y + BLOCK, x : x + BLOCK], b[y : y + BLOCK, x : x + BLOCK]
            if sa.mean() < 1e-4 and sb.mean() < 1e-4:
                continue  # black in both: nothing to compare
            sv = var[y : y + BLOCK, x : x + BLOCK].sum()
            z.append((sb.mean() - sa.mean()) / (math.sqrt(sv) / sa.size + 1e-12))
    return (a.mean(), b.mean(), rel, se), np.array(z)


def main():
    a = args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    build_scene(out, not a.no_texture)
    gltf = os.path.join(out, "scene.gltf")
    export_gltf(gltf)
    mitsuba_json = mitsuba_scene(out) if a.mitsuba_python else None
    principled_to_diffuse()
    images = {"Cycles": [], "portalview": []}
    if mitsuba_json:
        images["Mitsuba"] = []
    for seed in (1, 2):
        path = os.path.join(out, f"cycles-{seed}.exr")
        render_cycles(path, a.spp, seed)
        images["Cycles"].append(load_exr(path))
        path = os.path.join(out, f"portalview-{seed}.exr")
        subprocess.run(
            [
                a.portalview, "render", "--scene", gltf, "--width", str(WIDTH),
                "--height", str(HEIGHT), "--spp", str(a.pv_spp), "--seed", str(seed),
                "--strategy", a.strategy, "--sampler", a.sampler, "--out", path,
            ],
            check=True,
        )
        images["portalview"].append(load_exr(path))
        if mitsuba_json:
            path = os.path.join(out, f"mitsuba-{seed}.npy")
            subprocess.run(
                [a.mitsuba_python, os.path.join(HERE, "mitsuba_render.py"), mitsuba_json, path,
                 str(a.spp), str(seed)],
                check=True,
            )
            images["Mitsuba"].append(np.load(path))
    images = {k: np.array(v) for k, v in images.items()}
    print(f"\n{'reference':<10} {'renderer':<11} {'ref. mean':>10} {'mean':>9} {'difference':>11} "
          f"{'std. error':>11}   8x8 blocks: |z|>3  |z|>5  max |z|")
    pairs = [("Cycles", "portalview"), ("Cycles", "Mitsuba"), ("Mitsuba", "portalview")]
    for ref, other in pairs:
        if ref not in images or other not in images:
            continue
        (ma, mb, rel, se), z = compare(images[ref], images[other])
        print(
            f"{ref:<10} {other:<11} {ma:10.5f} {mb:9.5f} {100 * rel:+10.3f}% {100 * se:10.3f}%"
            f"   {len(z):4d} blocks {np.mean(np.abs(z) > 3) * 100:5.1f}% {np.mean(np.abs(z) > 5) * 100:5.1f}%"
            f" {np.abs(z).max():6.1f}"
        )
        save_png(os.path.join(out, f"{ref}-vs-{other}.png"), images[ref], images[other])


def save_png(path, cy, pv):
    """Reference | other | per-pixel z of the difference (red: the other brighter)."""
    a, b = cy.mean(axis=0), pv.mean(axis=0)
    lc, lp = luminance(cy), luminance(pv)
    # One seed pair's variance estimate per pixel is too noisy to divide by: average it over
    # the pixel's 5x5 neighbourhood.
    lvar = ((lc[0] - lc[1]) ** 2 + (lp[0] - lp[1]) ** 2) / 4.0
    pad = np.pad(lvar, 2, mode="edge")
    smooth = sum(
        pad[dy : dy + lvar.shape[0], dx : dx + lvar.shape[1]] for dy in range(5) for dx in range(5)
    ) / 25.0
    z = luminance(b - a) / np.sqrt(smooth + 1e-12)
    zmap = np.zeros(a.shape)
    zmap[..., 0] = np.clip(z / 4, 0, 1)
    zmap[..., 2] = np.clip(-z / 4, 0, 1)

    def srgb(c):
        c = np.clip(c, 0, 1)
        return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)

    tiles = np.concatenate([srgb(a), srgb(b), zmap], axis=1)[::-1]
    tiles = tiles.repeat(3, axis=0).repeat(3, axis=1)
    h, w, _ = tiles.shape
    img = bpy.data.images.new("comparison", w, h)
    img.pixels = np.concatenate([tiles, np.ones((h, w, 1))], axis=2).ravel()
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()


main()
