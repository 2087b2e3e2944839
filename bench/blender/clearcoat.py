"""Does portalview render Blender's Principled *Clearcoat* as Cycles 3.4 does?

Run with Blender 3.4 from the repository root (outputs go to --out, not the repository):

    blender -b --factory-startup -t 2 -P bench/blender/clearcoat.py -- \
        --out /tmp/clearcoat --portalview target/release/portalview

The scene (Blender Z up, metres): a grey Lambertian floor and three smooth spheres of a dark red
Lambertian base (Principled Specular 0, Roughness 1) under a full clear coat of roughness 0.05,
0.25 and 0.6, lit by two point lamps of radius 0 and nothing else. Blender's exporter writes the
coat as KHR_materials_clearcoat (`clearcoatFactor`, `clearcoatRoughnessFactor`); the script
checks the file says so. Point lamps are sampled by light sampling alone in both renderers, so
the comparison is of the coat's value (its weight, Fresnel, GTR1 distribution and masking, and
the roughness the exporter writes), not of how it is sampled (which the unit tests check, and
where Cycles 3.4 draws GGX normals for a GTR1 lobe).

For Cycles each Principled BSDF becomes Add(Diffuse BSDF(base colour), Principled BSDF(black,
Specular 0, its clear coat)): the Lambertian base the file describes (Principled diffuse has a
retro-reflection term) and Cycles' own coat closure. Cycles renders direct light only (two
seeds), portalview --max-depth 1 (two seeds), and the spheres and the floor are compared as
regions (transparent-film masks). The negative control: the same file without its coat
(`--coat 0` in Blender, exported again) against the same Cycles images, which the table must
tell apart.
"""

import argparse
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from common import (  # noqa: E402
    alpha_mask, black_world, cycles_two_seeds, diffuse_like, export_gltf, gltf_json,
    lambert_material, look_rotation, material_output, print_region_table, region_stats,
    run_portalview, script_argv, set_resolution, write_json,
)

ROUGHNESS = (0.05, 0.25, 0.6)
BASE = (0.3, 0.04, 0.04)


def args():
    p = argparse.ArgumentParser()
    p.add_argument("--out", default="/tmp/clearcoat")
    p.add_argument("--portalview")
    p.add_argument("--width", type=int, default=192)
    p.add_argument("--height", type=int, default=108)
    p.add_argument("--spp", type=int, default=256, help="Cycles samples per pixel per seed")
    p.add_argument("--pv-spp", type=int, default=256)
    p.add_argument("--pv-threads", type=int, default=2)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--force", action="store_true", help="render Cycles again")
    return p.parse_args(script_argv())


def coated_material(name, roughness, coat):
    m = lambert_material(name, BASE)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Clearcoat"].default_value = coat
    p.inputs["Clearcoat Roughness"].default_value = roughness
    return m


def build_scene(a, coat):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, 0))
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(lambert_material("Floor", (0.5, 0.5, 0.5)))
    for k, r in enumerate(ROUGHNESS):
        bpy.ops.mesh.primitive_uv_sphere_add(
            segments=96, ring_count=48, radius=0.5, location=(1.25 * (k - 1), 0, 0.5)
        )
        sphere = bpy.context.object
        sphere.name = f"Sphere{k}"
        bpy.ops.object.shade_smooth()
        sphere.data.materials.append(coated_material(f"Coat{k}", r, coat))
    for name, at, watts in (("Key", (1.5, -2.5, 2.5), 400.0), ("Fill", (-3.0, -1.0, 1.2), 150.0)):
        bpy.ops.object.light_add(type="POINT", location=at)
        lamp = bpy.context.object
        lamp.name = name
        lamp.data.energy = watts
        lamp.data.shadow_soft_size = 0.0
    bpy.ops.object.camera_add(location=(0.0, -4.6, 1.6))
    cam = bpy.context.object
    cam.name = "Camera"
    cam.rotation_euler = look_rotation(cam.location, (0.0, 0.0, 0.45))
    cam.data.lens = 40
    scene.camera = cam
    black_world(scene)
    set_resolution(scene, a.width, a.height)


def coat_as_cycles_closures():
    """Each Principled BSDF as Add(Diffuse(base colour), Principled(black, Specular 0, coat))."""
    for m in bpy.data.materials:
        if not m.use_nodes or "Principled BSDF" not in m.node_tree.nodes:
            continue
        nodes, links = m.node_tree.nodes, m.node_tree.links
        p = nodes["Principled BSDF"]
        d = diffuse_like(m, p)
        p.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        p.inputs["Specular"].default_value = 0.0
        add = nodes.new("ShaderNodeAddShader")
        links.new(d.outputs["BSDF"], add.inputs[0])
        links.new(p.outputs["BSDF"], add.inputs[1])
        links.new(add.outputs["Shader"], material_output(m).inputs["Surface"])


def main():
    a = args()
    os.makedirs(a.out, exist_ok=True)
    files = {}
    for coat in (0.0, 1.0):
        build_scene(a, coat)
        files[coat] = os.path.join(a.out, f"coat{coat:g}.glb")
        export_gltf(files[coat], glb=True)
    doc = gltf_json(files[1.0])
    written = [m.get("extensions", {}).get("KHR_materials_clearcoat") for m in doc["materials"]]
    print("exported:", json.dumps(written))
    assert "KHR_materials_clearcoat" in doc.get("extensionsUsed", []), "no clear coat exported"

    build_scene(a, 1.0)
    coat_as_cycles_closures()
    settings = dict(threads=a.threads, depth=1)
    cycles = cycles_two_seeds(os.path.join(a.out, "cycles"), a.spp, force=a.force, **settings)
    masks = {}
    for k in range(len(ROUGHNESS)):
        path = os.path.join(a.out, f"mask-sphere{k}.exr")
        masks[f"r{ROUGHNESS[k]:g}"] = alpha_mask(path, force=a.force, only=f"Sphere{k}",
                                                 threads=a.threads) > 0.999
    floor = alpha_mask(os.path.join(a.out, "mask-floor.exr"), force=a.force, only="Floor",
                       threads=a.threads) > 0.999
    masks["floor"] = floor & ~np.any(list(masks.values()), axis=0)
    if not a.portalview:
        return
    results = {}
    for coat, gltf in files.items():
        images = [
            run_portalview(a.portalview, gltf, os.path.join(a.out, f"pv-coat{coat:g}-{seed}.exr"),
                           a, seed=seed, depth=1)
            for seed in (1, 2)
        ]
        if any(i is None for i in images):
            sys.exit(1)
        mean = (images[0] + images[1]) / 2
        rows = region_stats(cycles, mean, masks)
        print_region_table([(f"coat {coat:g}", *r) for r in rows], lead="file")
        # The standard error of the ratio from both renderers' two seeds.
        for region, m in masks.items():
            cy = [c[m].mean() for c in cycles]
            pv = [i[m].mean() for i in images]
            c, p = sum(cy) / 2, sum(pv) / 2
            se = math.hypot(abs(cy[0] - cy[1]) / 2 / c, abs(pv[0] - pv[1]) / 2 / p) * p / c
            results[f"coat{coat:g}/{region}"] = {"ratio": p / c, "se": se}
            print(f"  {region}: portalview / Cycles {p / c:.4f} ± {se:.4f}")
    write_json(os.path.join(a.out, "clearcoat.json"), results)


main()
