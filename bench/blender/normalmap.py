"""Tangent-space normal maps: does portalview shade them as Cycles does?

Run with Blender 3.4 from the repository root (outputs go to --out, not the repository):

    blender -b --factory-startup -t 1 -P bench/blender/normalmap.py -- \
        --out /work/refs/normalmap [--portalview target/release/portalview] \
        [--mitsuba-python /work/mitsuba-venv/bin/python]

The scene (Blender Z up): a wall at y = 0 facing the camera (-Y), four 1 x 0.75 m panels, each UV
mapped 0..1 (u to the right, v up) with a Principled BSDF (Specular 0, Roughness 1: Lambertian in
glTF) whose Normal comes from a Normal Map node (tangent space, strength 1) fed by a generated
Non-Color PNG:

    mild   (top left)      cos x cos bumps, 3 periods, slopes up to 15 degrees
    steep  (top right)     the same, slopes up to 70 degrees
    tiltX  (bottom left)   a constant normal tilted 30 degrees toward image +X (right)
    tiltY  (bottom right)  a constant normal tilted 30 degrees toward image +Y (up)

lit by (i) a point lamp (upper left, in front) or (ii) an emissive 0.6 m square (upper right).
Each lighting is exported with Blender's glTF exporter twice, with TANGENT (`export_tangents`)
and without; the script checks the files hold normalTexture and (or not) TANGENT, and writes a
copy of each with the normal maps' green channel inverted (`*-ginv`). Cycles renders the Blender
scene after swapping each Principled BSDF for a Diffuse BSDF with the same colour and the same
Normal link (direct light only, box filter of width 1, two seeds). Cycles renders are kept and
reused; --force renders them again.

With --portalview, each glTF variant is rendered with it (same size, --max-depth 1) and compared
per panel: the ratio of the means (portalview / Cycles, luminance) and the RMS of the per-pixel
difference relative to Cycles' mean; `cy noise` is the RMS standard error of Cycles' two-seed mean
per pixel, the floor of that RMS. For the tilted panels under the point lamp the closed form
rho/pi * I/r^2 * max(0, n.l) (n the 8-bit map's normal) is compared with Cycles, with and without
Cycles' bump_shadowing_term; and for every panel under the point lamp a numerical model of Cycles
(supersampled pixels, the 8-bit map read bilinearly) at three levels: `model plain` (Lambert with
the mapped normal), `model shadowing` (times bump_shadowing_term(sd->N, N, L), closure/bsdf.h)
and `model cycles` (the normal also passed through ensure_valid_reflection(Ng, I, N),
closure/bsdf_util.h, as svm_node_closure_bsdf does). `model cycles` matches Cycles to 0.04% RMS.

With --mitsuba-python (a Python with Mitsuba 3.9, `pip install 'mitsuba==3.9.*'`), the scene is
also rendered with Mitsuba 3 (bench/blender/mitsuba_normalmap.py: each panel a world-space PLY
with Blender's uvs, a `twosided` `normalmap` BSDF around `diffuse`, the same PNG raw and bilinear;
the point lamp as a `point` emitter of P/(4 pi) W/sr, the emissive square as a one-sided `area`
emitter; the camera as in run.py; box filter; `direct`), once with normalmap's 3.9 defaults
(`Mitsuba default`: flip_invalid_normals and use_shadowing_function, Conty Estevez et al. 2019) and once
with both off (`Mitsuba plain`), two seeds each, and compared with Cycles per panel as portalview
is. Under the point lamp both are also compared with `model plain` and with `model mitsuba`
(normalmap.cpp's rule: a mapped normal facing away from the viewer mirrored about the geometric
normal, times Estevez's 2 / (1 + sqrt(1 + min(tan^2(theta_n) / 8, 1) tan^2(theta_l))), both
angles from the geometric normal); `mi noise` is the RMS standard error of Mitsuba's two-seed
mean per pixel. (Plain Mitsuba also zeroes where the mapped normal faces away from the viewer,
diffuse's cos_theta_i > 0; no pixel here has such a normal, so `model plain` is its rule.)
Mitsuba plain matches `model plain`, and Mitsuba default `model mitsuba`, to within its noise:
Mitsuba shades by the plain rule (or Estevez's term), not by Cycles' ensure_valid_reflection
and Chiang's bump_shadowing_term, hence its difference from Cycles on the steep bumps.
"""

import argparse
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import time
import zlib

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (  # noqa: E402
    HERE, black_world, cycles_two_seeds, emission_material, export_gltf, lambert_material,
    look_rotation, luminance, mesh_triangles, mitsuba_camera, mitsuba_point,
    principled_to_diffuse, region_compare, run_portalview, script_argv, set_resolution,
    two_seed_mean, write_json, write_ply,
)

ALBEDO = 0.8
POINT_POWER = 120.0  # W
POINT_AT = (-1.2, -1.6, 1.2)
AREA_AT = (1.1, -1.5, 1.1)
AREA_SIZE = 0.6
AREA_STRENGTH = 20.0
PANEL_W, PANEL_H, GAP = 1.0, 0.75, 0.1
MAP_SIZE = 256
PERIODS = 3
TILT = 30.0
PANELS = {
    # name: (centre x, centre z, kind, parameter)
    "mild": (-(PANEL_W + GAP) / 2, (PANEL_H + GAP) / 2, "bumps", 15.0),
    "steep": ((PANEL_W + GAP) / 2, (PANEL_H + GAP) / 2, "bumps", 70.0),
    "tiltX": (-(PANEL_W + GAP) / 2, -(PANEL_H + GAP) / 2, "tilt", (1.0, 0.0)),
    "tiltY": ((PANEL_W + GAP) / 2, -(PANEL_H + GAP) / 2, "tilt", (0.0, 1.0)),
}
CAMERA_AT = (0.0, -3.0, 0.0)
LENS = 45.0


def args():
    p = argparse.ArgumentParser()
    p.add_argument("--out", default="/work/refs/normalmap")
    p.add_argument("--portalview", help="render every glTF variant with it and compare")
    p.add_argument("--width", type=int, default=192)
    p.add_argument("--height", type=int, default=144)
    p.add_argument("--spp", type=int, default=256, help="Cycles samples per pixel per seed")
    p.add_argument("--pv-spp", type=int, default=256, help="portalview samples per pixel")
    p.add_argument("--pv-threads", type=int, default=1, help="RAYON_NUM_THREADS for portalview")
    p.add_argument("--threads", type=int, default=1, help="Cycles threads")
    p.add_argument("--lights", default="point,area")
    p.add_argument("--force", action="store_true", help="render Cycles again")
    p.add_argument(
        "--mitsuba-python",
        help="a Python with Mitsuba 3.9 (e.g. /work/mitsuba-venv/bin/python): also render with it",
    )
    p.add_argument("--mi-spp", type=int, default=256, help="Mitsuba samples per pixel")
    p.add_argument("--mi-threads", type=int, default=1, help="Mitsuba's worker threads")
    p.add_argument(
        "--probe-diffuse-export",
        action="store_true",
        help="also export a Diffuse BSDF version and print what glTF material it becomes",
    )
    return p.parse_args(script_argv())


# --- images -----------------------------------------------------------------------------------


def write_png(path, rgb8):
    """An 8-bit RGB PNG from (h, w, 3) uint8, top row first (no colour management involved)."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return (
            struct.pack(">I", len(data)) + tag + data
            + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
        )

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def normal_field(kind, param, size=MAP_SIZE):
    """Unit tangent-space normals (h, w, 3), top row first; +Y is up the image (+v in Blender,
    -v in glTF), the OpenGL convention of Blender's Normal Map node and of glTF."""
    c = (np.arange(size) + 0.5) / size
    u = c[None, :].repeat(size, 0)
    v = (1.0 - c)[:, None].repeat(size, 1)  # row 0 is the top: v = 1
    if kind == "bumps":
        # h = A cos(2 pi k u) cos(2 pi k v) with 2 pi k A = tan(max slope)
        g = math.tan(math.radians(param))
        a, b = 2 * math.pi * PERIODS * u, 2 * math.pi * PERIODS * v
        n = np.stack([g * np.sin(a) * np.cos(b), g * np.cos(a) * np.sin(b), np.ones_like(u)], -1)
    else:
        t = math.radians(TILT)
        n = np.zeros((size, size, 3))
        n[..., 0] = param[0] * math.sin(t)
        n[..., 1] = param[1] * math.sin(t)
        n[..., 2] = math.cos(t)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def encode(n, invert_green=False):
    rgb = np.clip(np.round((n * 0.5 + 0.5) * 255.0), 0, 255).astype(np.uint8)
    if invert_green:
        rgb[..., 1] = 255 - rgb[..., 1]
    return rgb


def make_maps(out):
    """The four normal maps as PNGs (and their green-inverted twins) in out/maps."""
    d = os.path.join(out, "maps")
    os.makedirs(d, exist_ok=True)
    paths = {}
    for name, (_, _, kind, param) in PANELS.items():
        n = normal_field(kind, param)
        paths[name] = os.path.join(d, f"{name}.png")
        write_png(paths[name], encode(n))
        write_png(os.path.join(d, f"{name}-ginv.png"), encode(n, True))
    return paths


# --- the scene --------------------------------------------------------------------------------


def panel_material(name, image_path):
    """A Lambertian Principled BSDF of albedo ALBEDO whose Normal comes from a tangent-space
    Normal Map node (strength 1) fed by the Non-Color PNG at image_path, read bilinearly."""
    m = lambert_material(name, (ALBEDO, ALBEDO, ALBEDO))
    nodes, links = m.node_tree.nodes, m.node_tree.links
    bsdf = nodes["Principled BSDF"]
    img = bpy.data.images.load(image_path)
    img.colorspace_settings.name = "Non-Color"
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Linear"
    nm = nodes.new("ShaderNodeNormalMap")
    nm.space = "TANGENT"
    nm.inputs["Strength"].default_value = 1.0
    links.new(tex.outputs["Color"], nm.inputs["Color"])
    links.new(nm.outputs["Normal"], bsdf.inputs["Normal"])
    return m


def build_scene(maps, light, width, height):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for name, (x, z, _, _) in PANELS.items():
        # A plane in XY (u along +X, v along +Y, normal +Z) turned to face -Y: v runs up.
        bpy.ops.mesh.primitive_plane_add(size=1.0, location=(x, 0.0, z), rotation=(math.pi / 2, 0, 0))
        obj = bpy.context.object
        obj.name = name
        obj.scale = (PANEL_W, PANEL_H, 1.0)
        bpy.ops.object.transform_apply(location=False, rotation=True, scale=True)
        obj.data.materials.append(panel_material(name, maps[name]))

    if light == "point":
        bpy.ops.object.light_add(type="POINT", location=POINT_AT)
        lamp = bpy.context.object
        lamp.name = "Lamp"
        lamp.data.energy = POINT_POWER
        lamp.data.shadow_soft_size = 0.0
    else:
        bpy.ops.mesh.primitive_plane_add(size=AREA_SIZE, location=AREA_AT)
        panel = bpy.context.object
        panel.name = "Emitter"
        # The face normal (+Z) toward the wall's centre.
        panel.rotation_euler = look_rotation(AREA_AT, (0.0, 0.0, 0.0), track="Z")
        panel.data.materials.append(emission_material("Emitter", (1.0, 1.0, 1.0), AREA_STRENGTH))

    bpy.ops.object.camera_add(location=CAMERA_AT, rotation=(math.pi / 2, 0.0, 0.0))
    cam = bpy.context.object
    cam.name = "Camera"
    cam.data.lens = LENS
    scene.camera = cam

    black_world(scene)
    set_resolution(scene, width, height)


def check_gltf(path):
    """What the exported file holds: per material its normalTexture, per mesh TANGENT."""
    with open(path) as f:
        g = json.load(f)
    mats = {}
    for m in g.get("materials", []):
        nt = m.get("normalTexture")
        uri = None
        if nt is not None:
            src = g["textures"][nt["index"]]["source"]
            uri = g["images"][src].get("uri")
        mats[m["name"]] = {
            "normalTexture": nt,
            "uri": uri,
            "extensions": sorted(m.get("extensions", {})),
            "pbr": m.get("pbrMetallicRoughness"),
        }
    tangent = [
        "TANGENT" in p["attributes"] for mesh in g.get("meshes", []) for p in mesh["primitives"]
    ]
    return g, mats, tangent


def green_inverted_copy(src_dir, dst_dir, mats, out):
    """The exported directory again, with each normal map's green channel inverted."""
    if os.path.isdir(dst_dir):
        shutil.rmtree(dst_dir)
    shutil.copytree(src_dir, dst_dir)
    for name, m in mats.items():
        if m["uri"] and name in PANELS:
            shutil.copyfile(
                os.path.join(out, "maps", f"{name}-ginv.png"), os.path.join(dst_dir, m["uri"])
            )


# --- regions and the closed form --------------------------------------------------------------


def camera_rays(width, height):
    """Per pixel centre (top row first): the camera's position and unit ray directions."""
    cam = bpy.context.scene.camera
    frame = [np.array(v) for v in cam.data.view_frame(scene=bpy.context.scene)]
    # view_frame: top right, bottom right, bottom left, top left (camera space, z = -d)
    tr, br, bl, tl = frame
    m = np.array(cam.matrix_world)
    xs = (np.arange(width) + 0.5) / width
    ys = (np.arange(height) + 0.5) / height
    top = tl[None, :] + xs[:, None] * (tr - tl)[None, :]
    bottom = bl[None, :] + xs[:, None] * (br - bl)[None, :]
    local = top[None, :, :] + ys[:, None, None] * (bottom - top)[None, :, :]
    d = local @ m[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return m[:3, 3], d


def panel_masks(width, height, margin=0.02):
    """Per panel, the pixels whose centre ray meets the panel at least `margin` m inside it."""
    o, d = camera_rays(width, height)
    t = -o[1] / d[..., 1]
    p = o + t[..., None] * d
    masks = {}
    for name, (x, z, _, _) in PANELS.items():
        masks[name] = (np.abs(p[..., 0] - x) < PANEL_W / 2 - margin) & (
            np.abs(p[..., 2] - z) < PANEL_H / 2 - margin
        )
    return masks, p


def closed_form_point(width, height):
    """Radiance (luminance = value: white light, grey albedo) of the tilted panels under the
    point lamp: rho/pi * P/(4 pi) / r^2 * max(0, n.l), n decoded from the 8-bit map."""
    _, p = panel_masks(width, height)
    out = {}
    for name in ("tiltX", "tiltY"):
        _, _, kind, param = PANELS[name]
        n_ts = normal_field(kind, param, size=1)[0, 0]
        n_ts = encode(n_ts).astype(np.float64) / 255.0 * 2.0 - 1.0
        n_ts /= np.linalg.norm(n_ts)
        # tangent +X, bitangent +Z (v up), normal -Y
        n = n_ts[0] * np.array([1.0, 0, 0]) + n_ts[1] * np.array([0, 0, 1.0]) + n_ts[2] * np.array([0, -1.0, 0])
        l = np.array(POINT_AT) - p
        r2 = np.sum(l * l, axis=-1)
        l /= np.sqrt(r2)[..., None]
        cos = np.maximum(l @ n, 0.0)
        plain = ALBEDO / math.pi * POINT_POWER / (4 * math.pi) / r2 * cos
        out[name] = plain * bump_shadowing(np.array([0, -1.0, 0]), n, l), plain
    return out


def bump_shadowing(ns, n, l):
    """Cycles 3.4's bump_shadowing_term(sd->N, sc->N, omega_in) (closure/bsdf.h), which
    bsdf_eval multiplies into a diffuse closure's value wherever its normal differs from the
    interpolated shading normal sd->N (Chiang, Li and Burley 2019, "Taming the Shadow
    Terminator"). ns: sd->N, n: the mapped normal, l: (..., 3) unit directions to the light."""
    n = np.broadcast_to(n, l.shape)
    cos_nl = np.sum(l * n, -1)
    sign = np.where(cos_nl < 0.0, -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = (sign * (l @ ns)) / (cos_nl * sign * (n @ ns))
    g = np.where(np.isfinite(g), g, 0.0)
    smooth = -(g ** 3) + g ** 2 + g
    return np.where(g >= 1.0, 1.0, np.where(g < 0.0, 0.0, smooth))


def ensure_valid_reflection(ng, i, n):
    """Cycles 3.4's ensure_valid_reflection(Ng, I, N) (closure/bsdf_util.h), vectorised: ng (3,),
    i and n (..., 3). svm_node_closure_bsdf applies it to every closure's normal."""
    dot = lambda a, b: np.sum(a * b, axis=-1)
    r = 2 * dot(n, i)[..., None] * n - i
    threshold = np.minimum(0.9 * (i @ ng), 0.01)
    keep = (r @ ng) >= threshold
    x = n - (n @ ng)[..., None] * ng
    x /= np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-30)
    ix, iz = dot(i, x), i @ ng
    ix2, iz2 = ix * ix, iz * iz
    a = ix2 + iz2
    b = np.sqrt(np.maximum(ix2 * (a - threshold * threshold), 0.0))
    c = iz * threshold + a
    fac = 0.5 / a
    n1z2, n2z2 = fac * (b + c), fac * (-b + c)
    valid1 = (n1z2 > 1e-5) & (n1z2 <= 1 + 1e-5)
    valid2 = (n2z2 > 1e-5) & (n2z2 <= 1 + 1e-5)
    n1 = np.stack([np.sqrt(np.maximum(1 - n1z2, 0)), np.sqrt(np.maximum(n1z2, 0))], -1)
    n2 = np.stack([np.sqrt(np.maximum(1 - n2z2, 0)), np.sqrt(np.maximum(n2z2, 0))], -1)
    r1 = 2 * (n1[..., 0] * ix + n1[..., 1] * iz) * n1[..., 1] - iz
    r2 = 2 * (n2[..., 0] * ix + n2[..., 1] * iz) * n2[..., 1] - iz
    both_ok = (r1 >= 1e-5) & (r2 >= 1e-5)
    pick1_both = np.where(both_ok, r1 < r2, r1 > r2)
    pick1 = np.where(valid1 & valid2, pick1_both, valid1)
    new = np.where(pick1[..., None], n1, n2)
    out = new[..., :1] * x + new[..., 1:] * ng
    out = np.where((~valid1 & ~valid2)[..., None], ng, out)
    return np.where(keep[..., None], n, out)


def mitsuba_flip(ng, i, n):
    """Mitsuba 3.9's normalmap.cpp with flip_invalid_normals: where cos_theta(wi) * dot(wi, n) <= 0
    (n the mapped normal in the shading frame), n = (-n.x, -n.y, n.z), the mirror image of n about
    the shading normal (here ng). i: (..., 3) unit directions to the viewer."""
    flip = ((i @ ng) * np.sum(i * n, -1)) <= 0.0
    mirrored = 2.0 * (n @ ng)[..., None] * ng - n
    return np.where(flip[..., None], mirrored, n)


def estevez_shadowing(ng, n, l):
    """Mitsuba 3.9's eval_shadow_terminator (bsdfs/normalmap_helpers.h; Conty Estevez, Lecocq
    and Stein, Ray Tracing Gems 2019): 2 / (1 + sqrt(1 + alpha2 tan^2(theta_l))), alpha2 =
    min(tan^2(theta_n) / 8, 1), both angles from the unperturbed shading normal ng."""
    cn2 = np.minimum((n @ ng) ** 2, 1.0)
    cl2 = np.minimum((l @ ng) ** 2, 1.0)
    alpha2 = np.minimum(0.125 * (1.0 - cn2) / cn2, 1.0)
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * (1.0 - cl2) / cl2))


def cycles_model(width, height, light_at, ss=6):
    """Per panel, a numerical model of Cycles 3.4 shading the panels under the point lamp, at
    three levels: plain Lambert with the mapped normal; with bump_shadowing_term; and with
    ensure_valid_reflection too (Cycles); and, for Mitsuba 3.9's normalmap, the plain level with
    mitsuba_flip and estevez_shadowing instead. ss x ss samples per pixel (box filter), the 8-bit
    map read bilinearly with wrapping as Cycles' Linear image texture (and Mitsuba's bilinear
    bitmap: texel centres at (i + 0.5) / size) does."""
    cam = bpy.context.scene.camera
    o = np.array(cam.matrix_world)[:3, 3]
    frame = [np.array(v) for v in cam.data.view_frame(scene=bpy.context.scene)]
    tr, br, bl, tl = frame
    m3 = np.array(cam.matrix_world)[:3, :3]
    offs = (np.arange(ss) + 0.5) / ss
    xs = ((np.arange(width)[:, None] + offs[None, :]) / width).ravel()
    ys = ((np.arange(height)[:, None] + offs[None, :]) / height).ravel()
    top = tl + xs[:, None] * (tr - tl)
    bottom = bl + xs[:, None] * (br - bl)
    local = top[None] + ys[:, None, None] * (bottom - top)[None]
    d = local @ m3.T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    t = -o[1] / d[..., 1]
    p = o + t[..., None] * d
    i = -d
    ng = np.array([0.0, -1.0, 0.0])
    T, B = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    l = np.array(light_at) - p
    r2 = np.sum(l * l, -1)
    l /= np.sqrt(r2)[..., None]
    scale = ALBEDO / math.pi * POINT_POWER / (4 * math.pi) / r2
    levels = {
        k: np.zeros((height, width))
        for k in ("plain", "shadowing", "cycles", "mitsuba")
    }
    for name, (cx, cz, kind, param) in PANELS.items():
        u = (p[..., 0] - (cx - PANEL_W / 2)) / PANEL_W
        v = (p[..., 2] - (cz - PANEL_H / 2)) / PANEL_H
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        tex = encode(normal_field(kind, param))[::-1].astype(np.float64) / 255.0  # bottom row 0
        h, w, _ = tex.shape
        fx, fy = u * w - 0.5, v * h - 0.5
        ix, iy = np.floor(fx).astype(int), np.floor(fy).astype(int)
        ax, ay = (fx - ix)[..., None], (fy - iy)[..., None]
        ix0, ix1, iy0, iy1 = ix % w, (ix + 1) % w, iy % h, (iy + 1) % h
        col = (1 - ay) * ((1 - ax) * tex[iy0, ix0] + ax * tex[iy0, ix1]) + ay * (
            (1 - ax) * tex[iy1, ix0] + ax * tex[iy1, ix1]
        )
        c = col * 2 - 1
        n = c[..., :1] * T + c[..., 1:2] * B + c[..., 2:3] * ng
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        for level in levels:
            nn = n
            if level == "cycles":
                nn = ensure_valid_reflection(ng, i, n)
            elif level == "mitsuba":
                nn = mitsuba_flip(ng, i, n)
            val = np.maximum(np.sum(nn * l, -1), 0.0)
            if level in ("shadowing", "cycles"):
                val = val * bump_shadowing(ng, nn, l)
            if level == "mitsuba":
                # diffuse.cpp: zero unless cos_theta_i > 0 in the perturbed frame (after the
                # flip always so); normalmap.cpp: Estevez's term
                val = np.where(np.sum(nn * i, -1) > 0.0, val, 0.0)
                val = val * estevez_shadowing(ng, nn, l)
            val = np.where(inside, scale * val, 0.0)
            levels[level] += val.reshape(height, ss, width, ss).mean(axis=(1, 3))
    return levels


# --- Mitsuba 3 -------------------------------------------------------------------------------


def mitsuba_scene(out, maps, light, width, height):
    """The Blender scene as mitsuba_normalmap.py reads it: a PLY per panel with its normal map's
    PNG, the point lamp (P/(4 pi) W/sr) or the emissive square (radiance = Strength x Color, one
    side), and the camera (Mitsuba looks down +Z with +X to the left: to_world = camera matrix
    x diag(-1, 1, -1, 1)), as run.py's mitsuba_scene does."""
    d = os.path.join(out, "mitsuba")
    os.makedirs(d, exist_ok=True)
    desc = {"panels": [], "areas": [], "points": []}
    for obj in bpy.context.scene.objects:
        if obj.type == "LIGHT":
            desc["points"].append(mitsuba_point(obj))
        if obj.type != "MESH":
            continue
        tris, uvs = mesh_triangles(obj)
        ply = os.path.join(d, f"{light}-{obj.name}.ply")
        write_ply(ply, tris, uvs)
        if obj.name in PANELS:
            desc["panels"].append({"name": obj.name, "ply": ply, "normalmap": maps[obj.name],
                                   "color": [ALBEDO] * 3})
        else:
            e = obj.active_material.node_tree.nodes["Emission"].inputs
            desc["areas"].append({
                "ply": ply,
                "radiance": [e["Strength"].default_value * c for c in e["Color"].default_value[:3]],
            })
    desc["camera"] = mitsuba_camera(width, height)
    return write_json(os.path.join(d, f"{light}.json"), desc)


def run_mitsuba(python, scene_json, a):
    """Mitsuba's renders (normalmap's defaults, and plain), seeds 1 and 2, as luminance images:
    {config: (seed 1, seed 2)}."""
    images = {"default": [], "plain": []}
    for seed in (1, 2):
        prefix = f"{os.path.splitext(scene_json)[0]}-{seed}"
        t0 = time.time()
        r = subprocess.run(
            [python, os.path.join(HERE, "mitsuba_normalmap.py"), scene_json, prefix,
             str(a.mi_spp), str(seed), str(a.mi_threads)],
            capture_output=True, text=True,
        )
        if r.returncode != 0:
            print(f"Mitsuba failed on {scene_json}:\n{r.stderr.strip()}")
            return {}
        print(f"  Mitsuba {prefix}-*.npy: {time.time() - t0:.0f} s")
        for c in images:
            images[c].append(luminance(np.load(f"{prefix}-{c}.npy")))
    return images


# --- main -------------------------------------------------------------------------------------


def main():
    a = args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    maps = make_maps(out)
    lights = a.lights.split(",")
    report = {}
    for light in lights:
        build_scene(maps, light, a.width, a.height)
        variants = {}
        for tangents in (True, False):
            tag = f"{light}-{'tangents' if tangents else 'notangents'}"
            path = os.path.join(out, tag, "scene.gltf")
            export_gltf(path, tangents)
            g, mats, has_tangent = check_gltf(path)
            print(f"{tag}: TANGENT in {sum(has_tangent)}/{len(has_tangent)} primitives; "
                  + ", ".join(f"{k}: normalTexture {'yes' if v['normalTexture'] else 'NO'}"
                              for k, v in mats.items() if k in PANELS))
            variants[tag] = path
            ginv = os.path.join(out, tag + "-ginv")
            green_inverted_copy(os.path.dirname(path), ginv, mats, out)
            variants[tag + "-ginv"] = os.path.join(ginv, "scene.gltf")
        if a.probe_diffuse_export and light == lights[0]:
            probe_diffuse_export(out)
            build_scene(maps, light, a.width, a.height)
        mitsuba_json = (
            mitsuba_scene(out, maps, light, a.width, a.height) if a.mitsuba_python else None
        )
        principled_to_diffuse()
        masks, _ = panel_masks(a.width, a.height)
        cycles = cycles_two_seeds(os.path.join(out, f"cycles-{light}"), a.spp, a.force,
                                  threads=a.threads)
        report[light] = (variants, masks, cycles, mitsuba_json)

    rows, mi_rows = [], []
    for light, (variants, masks, cycles, mitsuba_json) in report.items():
        cy, noise = two_seed_mean(*cycles)
        if light == "point":
            cf = closed_form_point(a.width, a.height)
            for name, images in cf.items():
                m = masks[name]
                for label, img in zip(("closed form", "c.f. w/o shadowing"), images):
                    rows.append((light, label, name, *region_compare(cy, noise, img, m)))
            model = cycles_model(a.width, a.height, POINT_AT)
            for label, img in model.items():
                for name, m in masks.items():
                    rows.append((light, f"model {label}", name, *region_compare(cy, noise, img, m)))
        if mitsuba_json:
            for config, (mi1, mi2) in run_mitsuba(a.mitsuba_python, mitsuba_json, a).items():
                img, mi_noise = two_seed_mean(mi1, mi2)
                for name, m in masks.items():
                    rows.append((light, f"Mitsuba {config}", name,
                                 *region_compare(cy, noise, img, m)))
                    if light != "point":
                        continue
                    for level in ("plain", "mitsuba"):
                        mi_rows.append((light, f"Mitsuba {config}", f"model {level}", name,
                                        *region_compare(model[level], mi_noise, img, m)))
        if not a.portalview:
            for name, m in masks.items():
                rows.append((light, "Cycles only", name, *region_compare(cy, noise, None, m)))
            continue
        for tag, gltf in variants.items():
            pv_path = os.path.join(out, "portalview", tag + ".exr")
            pv = run_portalview(a.portalview, gltf, pv_path, a, show=os.path.relpath(pv_path))
            if pv is None:
                continue
            variant = tag.split("-", 1)[1]
            for name, m in masks.items():
                rows.append((light, variant, name, *region_compare(cy, noise, pv, m)))
    print(f"\n{'light':<6} {'variant':<20} {'panel':<6} {'Cycles mean':>11} {'ratio':>7} "
          f"{'RMS diff':>9} {'cy noise':>9}")
    for light, variant, name, c, ratio, rms, nz in rows:
        print(f"{light:<6} {variant:<20} {name:<6} {c:11.5f} {ratio:7.3f} {100 * rms:8.2f}% "
              f"{100 * nz:8.2f}%")
    if mi_rows:
        print(f"\n{'light':<6} {'renderer':<16} {'against':<14} {'panel':<6} {'model mean':>11} "
              f"{'ratio':>7} {'RMS diff':>9} {'mi noise':>9}")
        for light, renderer, against, name, r, ratio, rms, nz in mi_rows:
            print(f"{light:<6} {renderer:<16} {against:<14} {name:<6} {r:11.5f} {ratio:7.3f} "
                  f"{100 * rms:8.2f}% {100 * nz:8.2f}%")
    table = "table.json" if a.portalview else "mitsuba-table.json" if a.mitsuba_python else (
        "cycles-table.json")
    write_json(os.path.join(out, table), rows + mi_rows)


def probe_diffuse_export(out):
    """Exports the panels with a Diffuse BSDF (Normal Map linked) and prints the glTF material."""
    principled_to_diffuse()
    path = os.path.join(out, "probe-diffuse", "scene.gltf")
    export_gltf(path, True)
    _, mats, has_tangent = check_gltf(path)
    print(f"probe: a Diffuse BSDF exports as (TANGENT in {sum(has_tangent)} primitives):")
    for k, v in mats.items():
        print(f"  {k}: {json.dumps(v)}")


main()
