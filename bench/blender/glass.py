"""Glass as artists model it (issue 38): Cycles references for thin-walled glTF glass.

Run with Blender 3.4 from the repository root (outputs go to --out, not the repository):

    nice -n 15 blender -b --factory-startup -P bench/blender/glass.py -- \
        --scene pane_room|globe [--out /tmp/glass-check/<scene>] [--depths 1,2] \
        [--portalview target/release/portalview]

Scenes (Blender Z up, 4 x 3 x 2.5 m closed rooms of Lambertian grey 0.6 quads, exported as
Principled Specular 0 and swapped for a Diffuse BSDF before Cycles renders):

- pane_room: two window openings in the north wall (y = 1.5), each filled by a 6 mm glass box
  (Principled BSDF: Transmission 1, Roughness 0, IOR 1.5, Base Color white; the exporter writes
  KHR_materials_transmission and no KHR_materials_volume: thin-walled), a window portal per
  window 1 cm inside the pane (room side; 2 cm larger than the opening on each side; extras
  portal_target = "environment", invisible to Cycles), Blender's forest.exr as the world (copied
  beside the .glb and named in the scene's extras, as hdri_room.py does).
- globe: a pendant lamp, an emissive sphere (r 5 cm) inside a clear glass globe of two
  concentric UV spheres (outer r 0.10 m normals out, inner r 0.094 m normals in, shaded
  smooth, the same glass), and a bare emissive sphere in a corner. Black world, no portals.

Each is exported as scene.glb, and without its glass as noglass.glb (the control).

Cycles' shadow rays stop at glass, so light crosses it only along BSDF paths; a bounce limit
counts a pane crossing, portalview's --max-depth does not. To render portalview's --max-depth d
(path vertices after the camera, crossings of glass not counted), every Lambertian material
becomes Mix(Diffuse, black Diffuse) with factor [Diffuse Depth + Glossy Depth > d - 1] (Light
Path node): a wall hit after d diffuse or glossy bounces absorbs everything and shades nothing,
while a ray that leaves the d-th vertex may still cross any number of glass surfaces to reach the
sky or a bulb. The bounce limits are then set so as never to bind: CYCLES_BOUNCES below
(max 16, diffuse d + 1, glossy 8, transmission 8, transparent 8), caustics reflective and
refractive on, Filter Glossy 0 (its default 1 blurs the sharp glass behind a diffuse bounce),
light_sampling_threshold 0, plus common.render_cycles' fair settings (box filter width 1, no
clamping, no adaptive sampling, no denoising, Standard view, 32-bit EXR). The same settings
render the control without glass. Two seeds each; the standard error of a region's mean is
sqrt(sum d_i^2) / (2 n) over its n pixels, d = seed 1 - seed 2.

Masks (16-spp transparent-film renders of the geometry): pane_room: `room` = pixels that see
only the room with the windows open, `window` = pixels seeing the sky through an opening;
globe: `globe` = pixels on the globe, `bulb` = the bare bulb, `room` = the rest.

With --portalview (skipped if the binary is missing), each .glb is rendered by it at the same
size and depth, two seeds, and compared: ratio of means per region, glass/no-glass ratios, and
z-scores of the 4 x 4 blocks of room pixels.
"""

import argparse
import math
import os
import shutil
import sys

import bmesh
import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (  # noqa: E402
    alpha_mask, cycles_window_portal, emission_material, export_gltf, gltf_json,
    lambert_material, load_exr, look_rotation, luminance, mesh_object, principled_to_diffuse,
    quad_facing, render_cycles, run_portalview, script_argv, set_resolution, write_json,
    black_world,
)
from common import hdri_world as common_hdri_world  # noqa: E402
import json  # noqa: E402

HDRI_DIR = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
ROOM = (4.0, 3.0, 2.5)  # x in [-2, 2], y in [-1.5, 1.5], z in [0, 2.5]
ALBEDO = (0.6, 0.6, 0.6)
WINDOWS = [(-1.5, -0.5, 0.9, 2.0), (0.4, 1.4, 1.0, 2.0)]  # x0, x1, z0, z1 in the wall y = 1.5
PANE = 0.006  # glass thickness, centred on the wall plane
PORTAL_GAP = 0.01  # the portal's distance from the pane's room side
PORTAL_MARGIN = 0.02  # the portal is this much larger than the opening on each side
GLOBE_AT = (0.0, 0.2, 1.7)
GLOBE_R = (0.10, 0.094)
BULB_R = 0.05
BARE_AT = (-1.7, -1.2, 2.2)


def cycles_bounces(depth, transparent=8):
    """scene.cycles settings for portalview's --max-depth `depth` with the Light Path trick:
    limits that never bind, caustics on, no glossy blur, no light threshold."""
    return {
        "max_bounces": 16,
        "diffuse_bounces": depth + 1,
        "glossy_bounces": 8,
        "transmission_bounces": 8,
        "volume_bounces": 0,
        "transparent_max_bounces": transparent,
        "caustics_reflective": True,
        "caustics_refractive": True,
        "blur_glossy": 0.0,
        "light_sampling_threshold": 0.0,
    }


def parser():
    """glass.py's arguments (glass_time.py adds its own)."""
    p = argparse.ArgumentParser()
    p.add_argument("--scene", choices=["pane_room", "globe"], required=True)
    p.add_argument("--out", help="default /tmp/glass-check/<scene>")
    p.add_argument("--hdri", default="forest.exr")
    p.add_argument("--strength", type=float, default=1.0)
    p.add_argument("--rotation", type=float, default=0.0, help="Mapping Z rotation, degrees")
    render_args(p, spp=2048, pv_spp=256)
    return p


def render_args(p, spp, pv_spp):
    """The bulbs', the renders' and the comparison's arguments, shared with thick_glass.py;
    `spp` and `pv_spp` are the Cycles and portalview samples per pixel per seed."""
    p.add_argument("--portalview", help="render each .glb with it and compare")
    p.add_argument("--bulb", type=float, default=400.0, help="globe bulb radiance W/(sr m^2)")
    p.add_argument("--bare", type=float, default=200.0, help="bare bulb radiance")
    p.add_argument("--depths", default="1,2", help="portalview --max-depth values to render")
    p.add_argument("--width", type=int, default=128)
    p.add_argument("--height", type=int, default=96)
    p.add_argument("--spp", type=int, default=spp, help="Cycles samples per pixel per seed")
    p.add_argument("--control-spp", type=int, default=1024, help="the same without glass")
    p.add_argument("--threads", type=int, default=2, help="Cycles threads")
    p.add_argument("--pv-spp", type=int, default=pv_spp)
    p.add_argument("--pv-threads", type=int, default=2, help="RAYON_NUM_THREADS for portalview")
    p.add_argument("--pv-args", default="", help="extra portalview render arguments")
    p.add_argument("--force", action="store_true", help="render Cycles again")


def args():
    return parser().parse_args(script_argv())


# --- building ---------------------------------------------------------------------------------




def room(windows):
    """The closed room's quads facing in; `windows` are openings in the north wall y = Y."""
    X, Y, Z = ROOM[0] / 2, ROOM[1] / 2, ROOM[2]
    quads = [
        quad_facing([(-X, -Y, 0), (X, -Y, 0), (X, Y, 0), (-X, Y, 0)], (0, 0, 1)),
        quad_facing([(-X, -Y, Z), (X, -Y, Z), (X, Y, Z), (-X, Y, Z)], (0, 0, -1)),
        quad_facing([(-X, -Y, 0), (X, -Y, 0), (X, -Y, Z), (-X, -Y, Z)], (0, 1, 0)),
        quad_facing([(-X, -Y, 0), (-X, Y, 0), (-X, Y, Z), (-X, -Y, Z)], (1, 0, 0)),
        quad_facing([(X, -Y, 0), (X, Y, 0), (X, Y, Z), (X, -Y, Z)], (-1, 0, 0)),
    ]
    # The north wall: the cells of a grid through the windows' edges, minus the openings.
    xs = sorted({-X, X, *[w[0] for w in windows], *[w[1] for w in windows]})
    zs = sorted({0.0, Z, *[w[2] for w in windows], *[w[3] for w in windows]})
    for x0, x1 in zip(xs, xs[1:]):
        for z0, z1 in zip(zs, zs[1:]):
            xm, zm = (x0 + x1) / 2, (z0 + z1) / 2
            if any(w[0] < xm < w[1] and w[2] < zm < w[3] for w in windows):
                continue
            quads.append(
                quad_facing([(x0, Y, z0), (x1, Y, z0), (x1, Y, z1), (x0, Y, z1)], (0, -1, 0))
            )
    mesh_object("Room", quads, lambert_material("Walls", ALBEDO))


def glass_material():
    """Clear glass as an artist sets it: Principled BSDF, Transmission 1, Roughness 0,
    IOR 1.5, white. Its node is renamed "Glass BSDF" after export so that
    principled_to_diffuse leaves it alone."""
    m = bpy.data.materials.new("Glass")
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    p.inputs["Transmission"].default_value = 1.0
    p.inputs["Roughness"].default_value = 0.0
    p.inputs["IOR"].default_value = 1.5
    return m


def camera(at, target, lens):
    bpy.ops.object.camera_add(location=at)
    cam = bpy.context.object
    cam.name = "Camera"
    cam.rotation_euler = look_rotation(at, target)
    cam.data.lens = lens
    bpy.context.scene.camera = cam


def hdri_world(a, hdri_path):
    """The world as hdri_room.py builds it, and the scene extras portalview reads."""
    common_hdri_world(bpy.context.scene, hdri_path, a.strength, a.rotation)


def build_pane_room(a, hdri_path):
    """Returns the glass objects' names."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    room(WINDOWS)
    glass = glass_material()
    portal_material = lambert_material("Portal", (0.0, 0.0, 0.0))
    Y = ROOM[1] / 2
    names = []
    for i, (x0, x1, z0, z1) in enumerate(WINDOWS):
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=((x0 + x1) / 2, Y, (z0 + z1) / 2))
        pane = bpy.context.object
        pane.name = f"Pane{i}"
        pane.scale = (x1 - x0, PANE, z1 - z0)
        bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
        pane.data.materials.append(glass)
        names.append(pane.name)
        m = PORTAL_MARGIN
        y = Y - PANE / 2 - PORTAL_GAP
        portal = mesh_object(
            f"Window{i}",
            [quad_facing([(x0 - m, y, z0 - m), (x1 + m, y, z0 - m), (x1 + m, y, z1 + m),
                          (x0 - m, y, z1 + m)], (0, -1, 0))],
            portal_material,
        )
        portal["portal_target"] = "environment"
        portal.hide_render = True
    camera((1.8, 1.2, 2.0), (-0.6, -0.9, 0.4), 16.0)
    hdri_world(a, hdri_path)
    return names


def sphere(name, at, r, material, inward=False):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=r, location=at)
    obj = bpy.context.object
    obj.name = name
    bpy.ops.object.shade_smooth()
    if inward:
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
        bm.to_mesh(obj.data)
        bm.free()
        obj.data.update()
    obj.data.materials.append(material)
    return obj


def build_globe(a):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    room([])
    glass = glass_material()
    sphere("GlobeOuter", GLOBE_AT, GLOBE_R[0], glass)
    sphere("GlobeInner", GLOBE_AT, GLOBE_R[1], glass, inward=True)
    sphere("Bulb", GLOBE_AT, BULB_R, emission_material("Bulb", (1.0, 0.9, 0.75), a.bulb))
    sphere("BareBulb", BARE_AT, BULB_R, emission_material("Bare", (1.0, 0.9, 0.75), a.bare))
    # A cord from the ceiling would shadow nothing measurable: left out.
    camera((1.5, -1.35, 1.4), (-0.2, 0.6, 1.1), 16.0)
    black_world(bpy.context.scene)
    return ["GlobeOuter", "GlobeInner"]


def build(a, out):
    """The scene a.scene built afresh at a.width x a.height (pane_room's HDRI copied to out);
    returns the glass objects' names."""
    if a.scene == "pane_room":
        hdri = os.path.join(out, a.hdri)
        shutil.copyfile(os.path.join(HDRI_DIR, a.hdri), hdri)
        names = build_pane_room(a, hdri)
    else:
        names = build_globe(a)
    set_resolution(bpy.context.scene, a.width, a.height)
    return names


def region_masks(a, out):
    """The regions' boolean masks (h, w) from 16-spp renders of the current scene's geometry
    (built by build, glass removed), reused from out unless a.force. Changes the scene (the
    globe's world strength): build afresh afterwards."""
    if a.scene == "pane_room":
        alpha = alpha_mask(os.path.join(out, "mask.exr"), a.force, threads=a.threads)
        return {"room": alpha > 0.999, "window": alpha < 0.001}
    s = bpy.context.scene
    s.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    # The globe: a render with only a stand-in sphere of the globe's radius.
    stand = sphere("Stand", GLOBE_AT, GLOBE_R[0], bpy.data.materials["Walls"])
    ga = alpha_mask(os.path.join(out, "mask-globe.exr"), a.force, threads=a.threads,
                    only="Stand")
    bpy.data.objects.remove(stand)
    ba = alpha_mask(os.path.join(out, "mask-bare.exr"), a.force, threads=a.threads,
                    only="BareBulb")
    masks = {"globe": ga > 0.001, "bulb": ba > 0.001}
    masks["room"] = ~(masks["globe"] | masks["bulb"])
    return masks


# --- Cycles -----------------------------------------------------------------------------------


def cycles_variant(a, out, variant):
    """The scene built afresh for Cycles as `variant`: "glass" (the Principled glass as
    exported), "thin" (gltf_thin_glass, Cycles portals in the windows) or "noglass" (glass
    removed, Cycles portals); Lambertian materials as Diffuse BSDFs. Returns the
    transparent_max_bounces to render it with (depth_limit is still to be applied)."""
    names = build(a, out)
    principled_to_diffuse_keep_glass()
    transparent = 8
    if variant == "thin":
        gltf_thin_glass()
        transparent = 32
    if variant == "noglass":
        for n in names:
            bpy.data.objects.remove(bpy.data.objects[n])
    if variant != "glass":
        if a.scene == "pane_room":  # Cycles portals cut the noise where shadow rays pass
            for i, (x0, x1, z0, z1) in enumerate(WINDOWS):
                cycles_window_portal(x0, x1, z0, z1, ROOM[1] / 2, name=f"CyclesPortal{i}")
    return transparent



def depth_limit(depth, glossy=True):
    """Each Diffuse BSDF output (after principled_to_diffuse) becomes Mix(it, black Diffuse)
    with factor [Diffuse Depth + Glossy Depth > depth - 1]: portalview's --max-depth without
    counting crossings of glass. glossy False: [Diffuse Depth > depth - 1], sharp glass
    reflections not counted either (thick_glass.py)."""
    for m in bpy.data.materials:
        if not m.use_nodes:
            continue
        nodes, links = m.node_tree.nodes, m.node_tree.links
        out = [n for n in nodes if n.type == "OUTPUT_MATERIAL"][0]
        if not out.inputs["Surface"].links:
            continue
        src = out.inputs["Surface"].links[0].from_node
        if "DepthMix" in nodes:  # already wrapped: only the threshold changes
            nodes["DepthGreater"].inputs[1].default_value = depth - 0.5
            continue
        if src.type != "BSDF_DIFFUSE":
            continue
        mix = black_past_depth(nodes, links, src.outputs["BSDF"], depth, glossy)
        links.new(mix.outputs["Shader"], out.inputs["Surface"])


def black_past_depth(nodes, links, shader, depth, glossy=True):
    """Mix(`shader`, black Diffuse) with factor [Diffuse Depth + Glossy Depth > depth - 1]
    (nodes "DepthGreater" and "DepthMix", so depth_limit can change the threshold later);
    glossy False: [Diffuse Depth > depth - 1]."""
    lp = nodes.new("ShaderNodeLightPath")
    add = nodes.new("ShaderNodeMath")
    add.operation = "ADD"
    gt = nodes.new("ShaderNodeMath")
    gt.name = "DepthGreater"
    gt.operation = "GREATER_THAN"
    gt.inputs[1].default_value = depth - 0.5
    black = nodes.new("ShaderNodeBsdfDiffuse")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    mix = nodes.new("ShaderNodeMixShader")
    mix.name = "DepthMix"
    links.new(lp.outputs["Diffuse Depth"], add.inputs[0])
    if glossy:
        links.new(lp.outputs["Glossy Depth"], add.inputs[1])
    else:
        add.inputs[1].default_value = 0.0
    links.new(add.outputs["Value"], gt.inputs[0])
    links.new(gt.outputs["Value"], mix.inputs["Fac"])
    links.new(shader, mix.inputs[1])
    links.new(black.outputs["BSDF"], mix.inputs[2])
    return mix


def two_seeds(prefix, spp, depth, force, threads, transparent=8):
    """Cycles renders with seeds 1 and 2 (reused if present) as RGB arrays."""
    import time

    imgs = []
    for seed in (1, 2):
        path = f"{prefix}-{seed}.exr"
        if force or not os.path.exists(path):
            t0 = time.time()
            render_cycles(path, spp, seed, threads=threads, overrides=cycles_bounces(depth, transparent))
            print(f"  Cycles {path}: {time.time() - t0:.0f} s", flush=True)
        imgs.append(load_exr(path))
    return imgs


# --- statistics -------------------------------------------------------------------------------


def mean_se(a, b, m):
    """Mean of (a + b) / 2 over mask m and its standard error from d = a - b."""
    d = (a - b)[m]
    return float(((a + b)[m]).mean() / 2), float(math.sqrt((d**2).sum()) / (2 * d.size))


def blocks(a, b, m, n=4):
    """Per block of an n x n grid: (mean, se) over its pixels in mask m."""
    h, w = m.shape
    out = []
    for i in range(n):
        row = []
        for j in range(n):
            bm = np.zeros_like(m)
            bm[i * h // n : (i + 1) * h // n, j * w // n : (j + 1) * w // n] = True
            bm &= m
            row.append(mean_se(a, b, bm) if bm.sum() > 20 else (float("nan"), float("nan")))
        out.append(row)
    return out


def plain_control(a, out, masks, glossy=True):
    """A check of the Light Path trick at depth 1: the control without glass rendered with plain
    max_bounces = 0, no trick (cycles-noglass-plain-d1-{seed}.exr, reused unless --force),
    whose means must equal the trick's. `glossy` as for depth_limit."""
    depth_limit(1000, glossy=glossy)
    plain = []
    for seed in (1, 2):
        path = os.path.join(out, f"cycles-noglass-plain-d1-{seed}.exr")
        if a.force or not os.path.exists(path):
            render_cycles(path, a.control_spp, seed, threads=a.threads, depth=1,
                          overrides={"light_sampling_threshold": 0.0, "blur_glossy": 0.0})
        plain.append(load_exr(path))
    return summarize("Cycles no glass, max_bounces 0, no trick", plain, masks)


def summarize(name, imgs, masks):
    a, b = imgs
    la, lb = luminance(a), luminance(b)
    everything = np.ones(la.shape, bool)
    s = {
        "rgb_mean": [mean_se(a[..., c], b[..., c], everything) for c in range(3)],
        "regions": {r: mean_se(la, lb, m) for r, m in {"all": everything, **masks}.items()},
        "room_blocks": blocks(la, lb, masks["room"]),
    }
    print(f"\n{name}: RGB mean " + ", ".join(f"{m:.5g}±{e:.2g}" for m, e in s["rgb_mean"]))
    for r, (m, e) in s["regions"].items():
        print(f"  {r:<7} luminance {m:.5g} ± {e:.2g} ({100 * e / m if m else 0:.2f}%)")
    print("  room blocks (4 x 4, luminance, se %):")
    for row in s["room_blocks"]:
        print("   " + " ".join(f"{m:8.4g}({100 * e / m if m else 0:4.1f})" if m == m else "     nan      "
                               for m, e in row))
    return s


def compare_pv(name, cy, pv, masks):
    """portalview (two seeds, luminance) against Cycles (two seeds, RGB): ratios and z."""
    ca, cb = luminance(cy[0]), luminance(cy[1])
    pa, pb = pv
    res = {}
    print(f"\n{name}: portalview / Cycles")
    for r, m in masks.items():
        c, ce = mean_se(ca, cb, m)
        p, pe = mean_se(pa, pb, m)
        z = (p - c) / math.hypot(ce, pe) if ce or pe else float("nan")
        res[r] = {"cycles": c, "portalview": p, "ratio": p / c, "z": z}
        print(f"  {r:<7} {p:.5g} / {c:.5g} = {p / c:.4f}  (z {z:+.1f})")
    cbk, pbk = blocks(ca, cb, masks["room"]), blocks(pa, pb, masks["room"])
    zs = [[(p[0] - c[0]) / math.hypot(c[1], p[1]) for c, p in zip(cr, pr)]
          for cr, pr in zip(cbk, pbk)]
    print("  room block z-scores: " + " | ".join(" ".join(f"{z:+5.1f}" for z in row)
                                                 for row in zs))
    res["room_block_z"] = zs
    return res


# --- main -------------------------------------------------------------------------------------


def main():
    a = args()
    out = os.path.abspath(a.out or f"/tmp/glass-check/{a.scene}")
    os.makedirs(out, exist_ok=True)
    depths = [int(d) for d in a.depths.split(",")]
    report = {"scene": a.scene, "args": vars(a), "cycles_settings": {}, "cycles": {}}
    glbs = {"glass": os.path.join(out, "scene.glb"), "noglass": os.path.join(out, "noglass.glb")}

    # Export with and without glass (the scene built afresh each time).
    glass_names = build(a, out)
    export_gltf(glbs["glass"], glb=True)
    for n in glass_names:
        bpy.data.objects.remove(bpy.data.objects[n])
    export_gltf(glbs["noglass"], glb=True)
    g = gltf_json(glbs["glass"])
    print("extensionsUsed:", g.get("extensionsUsed"))
    for m in g["materials"]:
        print("material", json.dumps(m))
    print("scene extras:", g["scenes"][0].get("extras"))
    print("portal extras:", [(n["name"], n.get("extras")) for n in g["nodes"] if n.get("extras")])
    glass_json = [m for m in g["materials"] if m["name"] == "Glass"]
    assert glass_json and "KHR_materials_transmission" in glass_json[0].get("extensions", {})
    assert "KHR_materials_volume" not in glass_json[0].get("extensions", {})
    report["glass_material"] = glass_json[0]
    report["extensionsUsed"] = g.get("extensionsUsed")

    # Masks from the geometry without glass.
    masks = region_masks(a, out)
    print({k: int(v.sum()) for k, v in masks.items()})

    # Cycles: the scene with glass, then without (rebuilt, glass removed).
    results = {}
    for variant in ("glass", "thin", "noglass"):
        transparent = cycles_variant(a, out, variant)
        for d in depths:
            depth_limit(d)
            report["cycles_settings"][f"{variant}-d{d}"] = cycles_bounces(d, transparent)
            spp = a.spp if variant == "glass" else a.control_spp
            imgs = two_seeds(os.path.join(out, f"cycles-{variant}-d{d}"), spp, d, a.force,
                             a.threads, transparent)
            results[(variant, d)] = imgs
            report["cycles"][f"{variant}-d{d}"] = summarize(f"Cycles {variant} d{d} {spp} spp",
                                                            imgs, masks)
        if variant == "noglass" and 1 in depths:
            report["cycles"]["noglass-plain-d1"] = plain_control(a, out, masks)
    for d in depths:
        rn = report["cycles"][f"noglass-d{d}"]["regions"]
        for variant in ("glass", "thin"):
            rg = report["cycles"][f"{variant}-d{d}"]["regions"]
            ratios = {r: [rg[r][0] / rn[r][0], math.hypot(rg[r][1] / rg[r][0],
                                                          rn[r][1] / rn[r][0]) * rg[r][0] / rn[r][0]]
                      for r in rg if rn[r][0] > 0}
            report.setdefault(f"{variant}_over_noglass", {})[f"d{d}"] = ratios
            print(f"\nCycles {variant} / no glass, d{d}: " +
                  ", ".join(f"{r} {v:.4f}±{e:.4f}" for r, (v, e) in ratios.items()))

    if a.portalview and os.path.exists(a.portalview):
        report["portalview"] = {}
        for variant, glb in glbs.items():
            for d in depths:
                pv = []
                for seed in (1, 2):
                    path = os.path.join(out, "portalview", f"{variant}-d{d}-{seed}.exr")
                    lum = run_portalview(a.portalview, glb, path, a, seed=seed, depth=d,
                                         extra=a.pv_args.split())
                    pv.append(lum)
                if any(p is None for p in pv):
                    continue
                for ref in (("glass", "thin") if variant == "glass" else (variant,)):
                    report["portalview"][f"{variant}-d{d}-vs-{ref}"] = compare_pv(
                        f"portalview {variant} d{d} vs Cycles {ref}", results[(ref, d)], pv,
                        masks)
        for d in depths:
            r = report["portalview"]
            if f"glass-d{d}-vs-glass" in r and f"noglass-d{d}-vs-noglass" in r:
                for reg in masks:
                    pr = (r[f"glass-d{d}-vs-glass"][reg]["portalview"]
                          / r[f"noglass-d{d}-vs-noglass"][reg]["portalview"])
                    cg = report["glass_over_noglass"][f"d{d}"].get(reg, [float("nan")])[0]
                    ct = report["thin_over_noglass"][f"d{d}"].get(reg, [float("nan")])[0]
                    print(f"portalview glass / no glass d{d} {reg}: {pr:.4f} (Cycles glass "
                          f"{cg:.4f}, Cycles glTF-thin {ct:.4f})")
    elif a.portalview:
        print(f"no {a.portalview}: portalview skipped")
    write_json(os.path.join(out, "report.json"), report)
    print("wrote", os.path.join(out, "report.json"))


def gltf_thin_glass():
    """The glass material replaced by Cycles' rendition of glTF's thin-walled smooth
    transmission (what portalview implements): Mix(Transparent white, Glossy Sharp white) with
    factor F = 0.04 + 0.96 (1 - |N.I|)^5 (Schlick, F0 of IOR 1.5 and the default specular
    layer; Layer Weight Facing at blend 0.5 is 1 - |N.I|). A Transparent BSDF lets Cycles'
    shadow rays through, and crossing it is not a bounce. The reflection is a path vertex in
    portalview, so depth_limit's factor kills it too (a "DepthMix" with black): otherwise
    reflections between a pane's two faces reach the sky beyond --max-depth (at 80 degrees
    they add 28% to the light through the pane)."""
    m = bpy.data.materials["Glass"]
    nodes, links = m.node_tree.nodes, m.node_tree.links
    for n in list(nodes):
        if n.type != "OUTPUT_MATERIAL":
            nodes.remove(n)
    out = [n for n in nodes if n.type == "OUTPUT_MATERIAL"][0]
    lw = nodes.new("ShaderNodeLayerWeight")
    lw.inputs["Blend"].default_value = 0.5
    pw = nodes.new("ShaderNodeMath")
    pw.operation = "POWER"
    pw.inputs[1].default_value = 5.0
    ma = nodes.new("ShaderNodeMath")
    ma.operation = "MULTIPLY_ADD"
    ma.inputs[1].default_value = 0.96
    ma.inputs[2].default_value = 0.04
    tr = nodes.new("ShaderNodeBsdfTransparent")
    tr.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    gl = nodes.new("ShaderNodeBsdfGlossy")
    gl.distribution = "SHARP"
    gl.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    mix = nodes.new("ShaderNodeMixShader")
    kill = black_past_depth(nodes, links, gl.outputs["BSDF"], 1)
    links.new(lw.outputs["Facing"], pw.inputs[0])
    links.new(pw.outputs["Value"], ma.inputs[0])
    links.new(ma.outputs["Value"], mix.inputs["Fac"])
    links.new(tr.outputs["BSDF"], mix.inputs[1])
    links.new(kill.outputs["Shader"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])


def principled_to_diffuse_keep_glass():
    """principled_to_diffuse for every material but the glass (its node renamed first)."""
    g = bpy.data.materials.get("Glass")
    if g is not None:
        g.node_tree.nodes["Principled BSDF"].name = "Glass BSDF"
    principled_to_diffuse()


if __name__ == "__main__":
    main()
