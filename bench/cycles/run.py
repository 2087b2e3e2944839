"""Does portalview render a Blender scene as Cycles does?

Run with Blender 3.4 (Debian's `blender` package) from the repository root:

    blender -b --factory-startup -P bench/cycles/run.py -- \
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

WIDTH, HEIGHT = 192, 144
BLOCK = 8
TRIANGULATE = "--triangulate" in sys.argv


def args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--portalview", default="target/release/portalview")
    p.add_argument("--out", default="/tmp/cycles-fidelity")
    p.add_argument("--spp", type=int, default=1024, help="Cycles samples per pixel per seed")
    p.add_argument("--pv-spp", type=int, default=1024, help="portalview spp per seed")
    p.add_argument("--strategy", default="antishadow")
    p.add_argument("--triangulate", action="store_true", help="Suzanne's quads as triangles")
    p.add_argument("--no-texture", action="store_true", help="plain floor colour")
    return p.parse_args(argv)


def material(name, color, image=None):
    """A Principled BSDF with Specular 0 (exported as a Lambertian glTF material)."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Specular"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    if image is not None:
        tex = m.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = "Linear"
        m.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return m


def emission(name, color, strength):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    e = nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*color, 1.0)
    e.inputs["Strength"].default_value = strength
    m.node_tree.links.new(e.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
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

    # The lampshade: an open 12-sided cylinder, a double-sided emissive disc inside, and a
    # portal on each opening naming the disc.
    shade_at = (1.3, 0.6, 1.5)
    bpy.ops.mesh.primitive_cylinder_add(
        vertices=12, radius=0.35, depth=0.5, end_fill_type="NOTHING", location=shade_at
    )
    shade = bpy.context.object
    shade.name = "Shade"
    shade.data.materials.append(material("Shade", (0.9, 0.9, 0.85)))

    bpy.ops.mesh.primitive_circle_add(vertices=12, radius=0.15, fill_type="NGON", location=shade_at)
    bulb = bpy.context.object
    bulb.name = "Bulb"
    bulb.data.materials.append(emission("Bulb", (1.0, 0.9, 0.7), 40.0))

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
    direction = (np.array([0.3, 0.0, 0.6]) - np.array(cam.location))
    cam.rotation_euler = _look_rotation(direction)
    cam.data.lens = 35
    scene.camera = cam

    scene.world = bpy.data.worlds.new("Black")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.render.resolution_x = WIDTH
    scene.render.resolution_y = HEIGHT
    scene.render.resolution_percentage = 100


def _look_rotation(d):
    from mathutils import Vector

    return Vector(d).to_track_quat("-Z", "Y").to_euler()


def export(path):
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLTF_SEPARATE",
        export_extras=True,
        export_lights=True,
        export_cameras=True,
        export_yup=True,
        export_apply=True,
    )


def principled_to_diffuse():
    """The glTF file describes Lambertian surfaces; Cycles' Diffuse BSDF is one."""
    for m in bpy.data.materials:
        if not m.use_nodes or "Principled BSDF" not in m.node_tree.nodes:
            continue
        nodes, links = m.node_tree.nodes, m.node_tree.links
        p = nodes["Principled BSDF"]
        d = nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = p.inputs["Base Color"].default_value
        for link in list(p.inputs["Base Color"].links):
            links.new(link.from_socket, d.inputs["Color"])
        links.new(d.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
        nodes.remove(p)


def render_cycles(path, spp, seed):
    s = bpy.context.scene
    s.render.engine = "CYCLES"
    s.cycles.device = "CPU"
    s.cycles.samples = spp
    s.cycles.use_adaptive_sampling = False
    s.cycles.use_denoising = False
    s.cycles.max_bounces = 0  # direct light only, as portalview's --max-depth 1
    s.cycles.sample_clamp_direct = 0.0
    s.cycles.sample_clamp_indirect = 0.0
    s.cycles.pixel_filter_type = "BOX"
    s.cycles.filter_width = 1.0
    s.cycles.seed = seed
    s.view_settings.view_transform = "Standard"
    s.render.image_settings.file_format = "OPEN_EXR"
    s.render.image_settings.color_depth = "32"
    s.render.filepath = path
    bpy.ops.render.render(write_still=True)


def load_exr(path):
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[::-1, :, :3]  # top row first


def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def compare(cy, pv, label):
    """Mean ratio with its standard error, and per-block z-scores of the difference."""
    a = np.mean(cy, axis=0)
    b = np.mean(pv, axis=0)
    # Each renderer's per-pixel variance of the two-seed mean, from the seeds' difference.
    var = ((cy[0] - cy[1]) ** 2 + (pv[0] - pv[1]) ** 2) / 4.0
    la, lb = luminance(a), luminance(b)
    lvar = luminance(np.sqrt(var)) ** 2
    h, w = la.shape
    rows = []
    diff = lb.mean() - la.mean()
    se = math.sqrt(lvar.sum()) / la.size
    rows.append((label, la.mean(), lb.mean(), diff / la.mean(), se / la.mean()))
    z = []
    for y in range(0, h - BLOCK + 1, BLOCK):
        for x in range(0, w - BLOCK + 1, BLOCK):
            sa, sb = la[y : y + BLOCK, x : x + BLOCK], lb[y : y + BLOCK, x : x + BLOCK]
            sv = lvar[y : y + BLOCK, x : x + BLOCK].sum()
            if sa.mean() < 1e-4 and sb.mean() < 1e-4:
                continue
            z.append((sb.mean() - sa.mean()) / (math.sqrt(sv) / sa.size + 1e-12))
    return rows[0], np.array(z)


def main():
    a = args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    build_scene(out, not a.no_texture)
    gltf = os.path.join(out, "scene.gltf")
    export(gltf)
    principled_to_diffuse()
    cy, pv = [], []
    for seed in (1, 2):
        path = os.path.join(out, f"cycles-{seed}.exr")
        render_cycles(path, a.spp, seed)
        cy.append(load_exr(path))
        path = os.path.join(out, f"portalview-{seed}.exr")
        subprocess.run(
            [
                a.portalview, "render", "--scene", gltf, "--width", str(WIDTH),
                "--height", str(HEIGHT), "--spp", str(a.pv_spp), "--seed", str(seed),
                "--strategy", a.strategy, "--out", path,
            ],
            check=True,
        )
        pv.append(load_exr(path))
    cy, pv = np.array(cy), np.array(pv)
    (label, ma, mb, rel, se), z = compare(cy, pv, "whole image")
    print(f"\n{'region':<14} {'Cycles':>9} {'portalview':>11} {'difference':>11} {'std. error':>11}")
    print(f"{label:<14} {ma:9.5f} {mb:11.5f} {100 * rel:+10.3f}% {100 * se:10.3f}%")
    print(
        f"{len(z)} blocks of {BLOCK}x{BLOCK}: |z| > 3 in {np.mean(np.abs(z) > 3) * 100:.1f}%,"
        f" |z| > 5 in {np.mean(np.abs(z) > 5) * 100:.1f}%, mean z {z.mean():+.2f}, "
        f"largest |z| {np.abs(z).max():.1f}"
    )
    save_png(os.path.join(out, "comparison.png"), cy.mean(axis=0), pv.mean(axis=0), cy, pv)


def save_png(path, a, b, cy, pv):
    """Cycles | portalview | per-pixel z of the difference (red: portalview brighter)."""
    var = ((cy[0] - cy[1]) ** 2 + (pv[0] - pv[1]) ** 2) / 4.0
    # One seed pair's variance estimate per pixel is too noisy to divide by: average it over
    # the pixel's 5x5 neighbourhood.
    lvar = luminance(np.sqrt(var)) ** 2
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
