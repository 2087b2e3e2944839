"""Thick glass (KHR_materials_volume): Cycles references for closed meshes filled with glass.

Run with Blender 3.4 from the repository root (outputs go to --out, not the repository):

    nice -n 15 blender -b --factory-startup -P bench/blender/thick_glass.py -- \
        [--out /tmp/glass-check/thick] [--depths 1,2,3] [--spp 32768] [--control-spp 4096] \
        [--portalview target/release/portalview]

(--preview SPP: only a 512 x 384 Cycles render of the scene at depth 3, preview.png, to look at.)

The scene `thick` (Blender Z up), built as an artist would and exported with Blender's glTF
exporter: glass.py's closed 4 x 3 x 2.5 m room of Lambertian grey 0.6 quads, black world, no
portals, and

- a pendant: an emissive sphere bulb (r 5 cm, --bulb W/(sr m^2)) inside a thick glass globe,
  ONE closed mesh (object "Globe") joined from two UV spheres, the outer r 0.10 m with normals
  out and the inner r 0.094 m with normals in, shaded smooth; material "Glass": Principled BSDF
  Transmission 1, Roughness 0, IOR 1.5, Base Color white, and the exporter's custom "glTF
  Material Output" node group (made with the add-on's own create_settings_group, as its Add >
  Output > glTF Material Output operator does) with Thickness 0.006: the exporter writes
  KHR_materials_transmission and KHR_materials_volume {thicknessFactor 0.006}, no attenuation;
- a solid glass ball (r 0.2 m, object "Ball") on the floor, material "AbsorbingGlass": the
  same Principled glass, Thickness 0.4 (its diameter) and a Volume Absorption node (Color =
  --attenuation-color, Density = 1 / --attenuation-distance) linked to the Material Output's
  Volume socket: the exporter writes attenuationColor = Color, attenuationDistance =
  1 / Density (gltf2_blender_gather_materials_volume.py);
- a bare emissive sphere (r 5 cm, --bare) in a corner under the ceiling (glass.py's, out of
  view), lighting the ball.

The camera sees the globe (~260 pixels at 128 x 96), the ball (~270) and floor and walls.

IOR 1.5 is glTF's default, so the exporter writes no KHR_materials_ior for the glass. Each
scene is exported as scene.glb, and without the globe shell and the ball as noglass.glb (the
control); main() checks the glass materials' JSON.

portalview's semantics and their Cycles rendition:

- Smooth thick glass is a perfect dielectric interface (exact Fresnel, total internal
  reflection), as Cycles 3.4's Principled BSDF with Transmission 1 and Roughness <= 0.05 (its
  single-scatter branch: a sharp reflection weighted by fresnel_dielectric_cos(N.I, eta) and a
  sharp refraction weighted by base colour x (1 - F)). The Principled node is kept as exported.
  Radiance x eta^2 across an interface cancels here: every light and the camera are in air.
- Absorption: glTF's Beer-Lambert coefficient is sigma = -ln(attenuationColor) /
  attenuationDistance per metre. Cycles 3.4's Volume Absorption has sigma = density x
  (1 - color): svm_node_closure_volume in intern/cycles/kernel/svm/closure.h (blender/cycles
  v3.4.0, src/kernel/svm/closure.h lines 976-987):
      density = mix_weight * fmaxf(density, 0.0f);
      Spectrum weight = sd->svm_closure_weight;            /* the node's Color */
      if (type == CLOSURE_VOLUME_ABSORPTION_ID) { weight = one_spectrum() - weight; }
      weight *= density;  ... volume_extinction_setup(sd, weight);   /* sigma_t */
  So the artist's node as exported (Color c, Density 1/d) renders in Cycles with sigma =
  (1 - c) / d, not glTF's -ln(c) / d. For the Cycles reference the node is set after export to
      Density D = max(1/d, max_i sigma_i),   Color_i = 1 - sigma_i / D   (in [0, 1)),
  so that Cycles' D (1 - Color_i) = sigma_i per channel (cycles_absorption). The material is
  also marked homogeneous (Beer-Lambert in closed form).
- Depth: portalview's --max-depth d counts diffuse (and rough) scattering vertices only; a
  smooth glass reflection or refraction is not a vertex, so a path may cross any number of
  them. Cycles counts a sharp glass reflection as a glossy bounce and a refraction as a
  transmission bounce, so every Lambertian material becomes Mix(Diffuse, black Diffuse) with
  factor [Diffuse Depth > d - 1] (glass.depth_limit(d, glossy=False)), and the bounce limits
  never bind (cycles_bounces: max 64, diffuse d + 1, glossy 32, transmission 32, volume 0,
  transparent 8), caustics reflective and refractive on, Filter Glossy 0,
  light_sampling_threshold 0, plus common.render_cycles' fair settings (box filter width 1,
  no clamping, no adaptive sampling, no denoising, Standard view, 32-bit EXR).
- Cycles' shadow rays stop at glass, as portalview's stop at thick glass: the bulb in the
  globe lights the room only along BSDF paths, and so does the bare bulb through the ball.
  Everything seen through the ball is lit so (the floor behind it is in its shadow): the ball
  region converges slowly (Cycles at 512 spp: 8% standard error; its noise is the globe's
  light, not the bare bulb's: a 3x larger bare bulb of equal power changed nothing).

Two seeds each; the standard error of a region's mean is sqrt(sum d_i^2) / (2 n) over its n
pixels, d = seed 1 - seed 2. Regions (16-spp transparent-film renders of stand-in spheres):
`globe` = pixels on the globe's outer sphere, `ball` = on the ball, `bulb` = the bare bulb
(if in view), `room` = the rest. The control without glass also renders depth 1 with plain
max_bounces 0 (no Light Path trick): its means must equal the trick's.

With --portalview (skipped if the binary is missing) each .glb is rendered by it at the same
size and depth, two seeds, and compared as glass.py does: ratio of means per region (and per
RGB channel on the ball and globe), glass/no-glass ratios, z-scores of 4 x 4 room blocks.
Its default 4096 spp (20-70 s a render on 2 threads) resolves the room to ~0.25%: at 256 spp
the room's light, all along BSDF paths through the globe, is a few rare paths per pixel.

Sensitivity found with it (portalview with 3ebcc08's thick glass): a ray that refracts must
start on its own line. Offsetting a refracted ray's origin along -Ng (by 2e-4 of the
coordinates, 0.37 mm at the globe) moves its line towards the sphere's centre at each crossing,
and through a 6 mm shell the bulb looked 0.8% larger in radius: its edge pixels +9%, the globe
region +1.7% (z ~100) and the room, lit mostly by the globe, +1.4-1.7% (z ~7), while the bulb's
interior pixels agreed to 0.15%. The same .glb translated so that the globe sits at the origin
(offsets 3x smaller) gave +0.6% and +0.4%. (A concentric shell keeps a ray's distance from the
centre, so the bulb's true apparent size is the same as without glass, as Cycles shows.)
"""

import argparse
import json
import math
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (  # noqa: E402
    alpha_mask, black_world, emission_material, export_gltf, gltf_json, load_exr,
    principled_to_diffuse, render_cycles, run_portalview, script_argv, set_resolution,
    write_json,
)
from glass import (  # noqa: E402
    BARE_AT, BULB_R, GLOBE_R, camera, compare_pv, depth_limit, mean_se, plain_control, render_args,
    room, sphere, summarize,
)

GLOBE_AT = (0.35, 0.1, 1.3)
GLOBE_THICKNESS = GLOBE_R[0] - GLOBE_R[1]  # 0.006
BALL_R = 0.2
BALL_AT = (-0.35, 0.45, BALL_R)  # on the floor
CAMERA_AT, CAMERA_TARGET, CAMERA_LENS = (1.05, -0.75, 1.15), (-0.1, 0.4, 0.78), 24.0
GLASS = ("Globe", "Ball")  # the glass objects
GLASS_MATERIALS = ("Glass", "AbsorbingGlass")


def cycles_bounces(depth):
    """scene.cycles settings for portalview's --max-depth `depth` with the Light Path trick on
    Diffuse Depth only: limits that never bind, caustics on, no glossy blur, no threshold."""
    return {
        "max_bounces": 64,
        "diffuse_bounces": depth + 1,
        "glossy_bounces": 32,
        "transmission_bounces": 32,
        "volume_bounces": 0,
        "transparent_max_bounces": 8,
        "caustics_reflective": True,
        "caustics_refractive": True,
        "blur_glossy": 0.0,
        "light_sampling_threshold": 0.0,
    }


def parser():
    p = argparse.ArgumentParser()
    p.add_argument("--out", default="/tmp/glass-check/thick")
    render_args(p, spp=4096, pv_spp=4096)
    p.add_argument("--bare-radius", type=float, default=BULB_R, help="bare bulb radius, m")
    p.add_argument("--attenuation-color", default="0.6,0.8,0.9",
                   help="the ball's Volume Absorption Color (glTF attenuationColor)")
    p.add_argument("--attenuation-distance", type=float, default=0.2,
                   help="1 / the ball's Volume Absorption Density (glTF attenuationDistance), m")
    p.add_argument("--preview", type=int, metavar="SPP",
                   help="only a 4x-size Cycles render (depth 3) of the glass scene, preview.png")
    return p


def args():
    return parser().parse_args(script_argv())


def attenuation(a):
    return tuple(float(c) for c in a.attenuation_color.split(","))


# --- building ---------------------------------------------------------------------------------


def gltf_output_node(m, thickness):
    """The exporter's custom "glTF Material Output" group node in material m with Thickness
    `thickness`, the group made by the add-on's own helper if the file has none yet."""
    from io_scene_gltf2.blender.com.gltf2_blender_material_helpers import (
        create_settings_group, get_gltf_node_name,
    )

    name = get_gltf_node_name()  # "glTF Material Output" (older files: "glTF Settings")
    group = bpy.data.node_groups.get(name) or create_settings_group(name)
    node = m.node_tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.location = (0, -500)
    node.inputs["Thickness"].default_value = thickness
    return node


def thick_glass_material(name, thickness, absorb=None):
    """Clear glass as an artist sets it (Principled BSDF, Transmission 1, Roughness 0, IOR 1.5,
    white), Thickness in the glTF Material Output node; absorb = (color, distance): a Volume
    Absorption node (Color, Density 1 / distance) on the Material Output's Volume socket."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes = m.node_tree.nodes
    p = nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    p.inputs["Transmission"].default_value = 1.0
    p.inputs["Roughness"].default_value = 0.0
    p.inputs["IOR"].default_value = 1.5
    gltf_output_node(m, thickness)
    if absorb is not None:
        color, distance = absorb
        v = nodes.new("ShaderNodeVolumeAbsorption")
        v.inputs["Color"].default_value = (*color, 1.0)
        v.inputs["Density"].default_value = 1.0 / distance
        m.node_tree.links.new(v.outputs["Volume"], nodes["Material Output"].inputs["Volume"])
    return m


def globe_shell(material):
    """The globe: outer and inner UV spheres joined into one object "Globe" (Ctrl J)."""
    outer = sphere("Globe", GLOBE_AT, GLOBE_R[0], material)
    inner = sphere("GlobeInner", GLOBE_AT, GLOBE_R[1], material, inward=True)
    bpy.ops.object.select_all(action="DESELECT")
    outer.select_set(True)
    inner.select_set(True)
    bpy.context.view_layer.objects.active = outer
    bpy.ops.object.join()
    assert len(outer.data.materials) == 1, list(outer.data.materials)
    return outer


def build(a):
    """The scene built afresh at a.width x a.height."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    room([])
    globe_shell(thick_glass_material("Glass", GLOBE_THICKNESS))
    sphere("Bulb", GLOBE_AT, BULB_R, emission_material("Bulb", (1.0, 0.9, 0.75), a.bulb))
    sphere("Ball", BALL_AT, BALL_R, thick_glass_material(
        "AbsorbingGlass", 2 * BALL_R, (attenuation(a), a.attenuation_distance)))
    sphere("BareBulb", BARE_AT, a.bare_radius,
           emission_material("Bare", (1.0, 0.9, 0.75), a.bare))
    camera(CAMERA_AT, CAMERA_TARGET, CAMERA_LENS)
    black_world(bpy.context.scene)
    set_resolution(bpy.context.scene, a.width, a.height)


def check_export(glb, a):
    """The exported glass materials as intended; returns them (name: JSON)."""
    g = gltf_json(glb)
    print("extensionsUsed:", g.get("extensionsUsed"))
    for m in g["materials"]:
        print("material", json.dumps(m))
    mats = {m["name"]: m for m in g["materials"]}
    for name, thickness in (("Glass", GLOBE_THICKNESS), ("AbsorbingGlass", 2 * BALL_R)):
        m = mats[name]
        ext = m.get("extensions", {})
        assert ext["KHR_materials_transmission"]["transmissionFactor"] == 1, m
        vol = ext["KHR_materials_volume"]
        assert abs(vol["thicknessFactor"] - thickness) < 1e-6, m
        assert ext.get("KHR_materials_ior", {"ior": 1.5})["ior"] == 1.5, m
        pbr = m.get("pbrMetallicRoughness", {})
        assert pbr.get("roughnessFactor", 1) == 0 and pbr.get("metallicFactor", 1) == 0, m
        assert pbr.get("baseColorFactor", [1, 1, 1, 1]) == [1, 1, 1, 1], m
        if name == "Glass":
            assert "attenuationColor" not in vol and "attenuationDistance" not in vol, m
        else:
            assert np.allclose(vol["attenuationColor"], attenuation(a), atol=1e-6), m
            assert abs(vol["attenuationDistance"] - a.attenuation_distance) < 1e-6, m
    nodes = {n["name"]: n for n in g["nodes"]}
    prims = g["meshes"][nodes["Globe"]["mesh"]]["primitives"]
    assert len(prims) == 1, prims  # one closed mesh
    print("Globe: one mesh, one primitive of", g["accessors"][prims[0]["indices"]]["count"] // 3,
          "triangles")
    return {n: mats[n] for n in GLASS_MATERIALS}


def region_masks(a, out):
    """{globe, ball, bulb (if in view), room} boolean masks (h, w) from 16-spp transparent-film
    renders of stand-in spheres (reused from out unless a.force). Builds the scene afresh."""
    build(a)
    for n in GLASS:
        bpy.data.objects.remove(bpy.data.objects[n])
    walls = bpy.data.materials["Walls"]
    masks = {}
    for region, at, r, name in (("globe", GLOBE_AT, GLOBE_R[0], "StandGlobe"),
                                ("ball", BALL_AT, BALL_R, "StandBall"),
                                ("bulb", BARE_AT, a.bare_radius, "BareBulb")):
        stand = sphere(name, at, r, walls) if name.startswith("Stand") else None
        alpha = alpha_mask(os.path.join(out, f"mask-{region}.exr"), a.force, threads=a.threads,
                           only=name)
        if stand is not None:
            bpy.data.objects.remove(stand)
        if (alpha > 0.001).any():
            masks[region] = alpha > 0.001
    masks["room"] = ~np.any(list(masks.values()), axis=0)
    return masks


# --- Cycles -----------------------------------------------------------------------------------


def cycles_absorption(color, distance):
    """The Cycles Volume Absorption (Color, Density) whose sigma = Density (1 - Color) equals
    glTF's sigma = -ln(attenuationColor) / attenuationDistance per channel."""
    sigma = [-math.log(c) / distance for c in color]
    density = max(1.0 / distance, *sigma)
    return [1.0 - s / density for s in sigma], density, sigma


def cycles_variant(a, variant):
    """The scene built afresh for Cycles: "glass" (the Principled glass kept as exported, the
    ball's Volume Absorption set to glTF's sigma) or "noglass" (globe shell and ball removed);
    Lambertian materials as Diffuse BSDFs (depth_limit still to be applied). Returns the
    absorption set (or None)."""
    build(a)
    for name in GLASS_MATERIALS:  # principled_to_diffuse leaves the glass alone
        bpy.data.materials[name].node_tree.nodes["Principled BSDF"].name = "Glass BSDF"
    principled_to_diffuse()
    if variant == "noglass":
        for n in GLASS:
            bpy.data.objects.remove(bpy.data.objects[n])
        return None
    m = bpy.data.materials["AbsorbingGlass"]
    m.cycles.homogeneous_volume = True
    v = [n for n in m.node_tree.nodes if n.type == "VOLUME_ABSORPTION"][0]
    color, density, sigma = cycles_absorption(attenuation(a), a.attenuation_distance)
    v.inputs["Color"].default_value = (*color, 1.0)
    v.inputs["Density"].default_value = density
    return {"color": color, "density": density, "sigma_per_m": sigma,
            "cycles_sigma_of_artist_node": [(1 - c) / a.attenuation_distance
                                            for c in attenuation(a)]}


def two_seeds(prefix, spp, depth, a, timings):
    """Cycles renders with seeds 1 and 2 (reused if present) as RGB arrays; new renders timed
    into timings[path]."""
    imgs = []
    for seed in (1, 2):
        path = f"{prefix}-{seed}.exr"
        if a.force or not os.path.exists(path):
            t0 = time.time()
            render_cycles(path, spp, seed, threads=a.threads, overrides=cycles_bounces(depth))
            timings[os.path.basename(path)] = time.time() - t0
            print(f"  Cycles {path}: {timings[os.path.basename(path)]:.0f} s", flush=True)
        imgs.append(load_exr(path))
    return imgs


def region_rgb(imgs, masks):
    """{region: [(mean, se) per channel]} of two seeds' RGB images."""
    a, b = imgs
    return {r: [mean_se(a[..., c], b[..., c], m) for c in range(3)] for r, m in masks.items()}


def print_rgb(name, rgb):
    for r, ch in rgb.items():
        print(f"  {name} {r:<6} RGB " + ", ".join(f"{m:.5g}±{e:.2g}" for m, e in ch))


# --- main -------------------------------------------------------------------------------------


def main():
    a = args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    depths = [int(d) for d in a.depths.split(",")]
    report = {"scene": "thick", "args": vars(a), "cycles_settings": {}, "cycles": {},
              "cycles_seconds": {}}
    glbs = {"glass": os.path.join(out, "scene.glb"), "noglass": os.path.join(out, "noglass.glb")}
    try:  # the times of renders reused from an earlier run
        with open(os.path.join(out, "report.json")) as f:
            report["cycles_seconds"] = json.load(f).get("cycles_seconds", {})
    except (OSError, ValueError):
        pass

    if a.preview:
        report["absorption"] = cycles_variant(a, "glass")
        depth_limit(3, glossy=False)
        set_resolution(bpy.context.scene, 4 * a.width, 4 * a.height)
        t0 = time.time()
        render_cycles(os.path.join(out, "preview.exr"), a.preview, 1, threads=a.threads,
                      overrides=cycles_bounces(3))
        print(f"preview: {time.time() - t0:.0f} s")
        px = load_exr(os.path.join(out, "preview.exr"))
        px = np.clip(px / (px + 1.0) * 2.0, 0.0, 1.0) ** (1 / 2.2)  # a soft tone map to view
        h, w = px.shape[:2]
        img = bpy.data.images.new("preview", w, h)
        img.pixels[:] = np.concatenate([px[::-1], np.ones((h, w, 1))], axis=2).ravel()
        img.filepath_raw = os.path.join(out, "preview.png")
        img.file_format = "PNG"
        img.save()
        return

    # Export with and without glass (the scene built afresh each time).
    build(a)
    export_gltf(glbs["glass"], glb=True)
    for n in GLASS:
        bpy.data.objects.remove(bpy.data.objects[n])
    export_gltf(glbs["noglass"], glb=True)
    report["glass_materials"] = check_export(glbs["glass"], a)
    report["extensionsUsed"] = gltf_json(glbs["glass"]).get("extensionsUsed")

    masks = region_masks(a, out)
    print("region pixels:", {k: int(v.sum()) for k, v in masks.items()})

    results = {}
    for variant in ("glass", "noglass"):
        absorption = cycles_variant(a, variant)
        if absorption:
            report["absorption"] = absorption
            print("absorption: glTF sigma per m", [f"{s:.4f}" for s in absorption["sigma_per_m"]],
                  "-> Cycles Volume Absorption Color",
                  [f"{c:.4f}" for c in absorption["color"]], f"Density {absorption['density']:.4f}"
                  " (the artist's node as exported renders sigma",
                  [f"{s:.4f}" for s in absorption["cycles_sigma_of_artist_node"]], ")")
        spp = a.spp if variant == "glass" else a.control_spp
        for d in depths:
            depth_limit(d, glossy=False)
            key = f"{variant}-d{d}"
            report["cycles_settings"][key] = cycles_bounces(d)
            imgs = two_seeds(os.path.join(out, f"cycles-{key}"), spp, d, a,
                             report["cycles_seconds"])
            results[(variant, d)] = imgs
            report["cycles"][key] = summarize(f"Cycles {variant} d{d} {spp} spp", imgs, masks)
            report["cycles"][key]["region_rgb"] = rgb = region_rgb(imgs, masks)
            print_rgb("", {r: v for r, v in rgb.items() if r in ("globe", "ball")})
        if variant == "noglass" and 1 in depths:
            report["cycles"]["noglass-plain-d1"] = plain_control(a, out, masks, glossy=False)
    for d in depths:
        rg = report["cycles"][f"glass-d{d}"]["regions"]
        rn = report["cycles"][f"noglass-d{d}"]["regions"]
        ratios = {r: [rg[r][0] / rn[r][0], math.hypot(rg[r][1] / rg[r][0], rn[r][1] / rn[r][0])
                      * rg[r][0] / rn[r][0]] for r in rg if rn[r][0] > 0}
        report.setdefault("glass_over_noglass", {})[f"d{d}"] = ratios
        print(f"\nCycles glass / no glass, d{d}: " +
              ", ".join(f"{r} {v:.4f}±{e:.4f}" for r, (v, e) in ratios.items()))

    if a.portalview and os.path.exists(a.portalview):
        report["portalview"] = {}
        warned = False
        for variant, glb in glbs.items():
            for d in depths:
                pv, pv_rgb = [], []
                for seed in (1, 2):
                    path = os.path.join(out, "portalview", f"{variant}-d{d}-{seed}.exr")
                    info = {}
                    lum = run_portalview(a.portalview, glb, path, a, seed=seed, depth=d,
                                         extra=a.pv_args.split(), info=info)
                    if lum is not None and not warned and variant == "glass":
                        print("portalview's output on scene.glb:\n" + info["stdout"].strip())
                        warned = True
                    pv.append(lum)
                    pv_rgb.append(load_exr(path) if lum is not None else None)
                if any(p is None for p in pv):
                    continue
                key = f"{variant}-d{d}"
                res = compare_pv(f"portalview {variant} d{d} vs Cycles {variant}",
                                 results[(variant, d)], pv, masks)
                prgb, crgb = region_rgb(pv_rgb, masks), region_rgb(results[(variant, d)], masks)
                res["rgb_ratio"] = {r: [p[0] / c[0] if c[0] else float("nan")
                                        for p, c in zip(prgb[r], crgb[r])] for r in masks}
                for r in ("globe", "ball"):
                    if r in masks:
                        print(f"  {r:<7} RGB ratios " +
                              ", ".join(f"{x:.4f}" for x in res["rgb_ratio"][r]))
                report["portalview"][key] = res
        for d in depths:
            r = report["portalview"]
            if f"glass-d{d}" in r and f"noglass-d{d}" in r:
                for reg in masks:
                    pr = r[f"glass-d{d}"][reg]["portalview"] / r[f"noglass-d{d}"][reg]["portalview"]
                    cg = report["glass_over_noglass"][f"d{d}"].get(reg, [float("nan")])[0]
                    print(f"portalview glass / no glass d{d} {reg}: {pr:.4f} (Cycles {cg:.4f})")
    elif a.portalview:
        print(f"no {a.portalview}: portalview skipped")
    print("Cycles seconds:", {k: round(v) for k, v in report["cycles_seconds"].items()})
    write_json(os.path.join(out, "report.json"), report)
    print("wrote", os.path.join(out, "report.json"))


if __name__ == "__main__":
    main()
