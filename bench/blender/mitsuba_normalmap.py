"""Render the normal-mapped wall that bench/blender/normalmap.py wrote (JSON + PLYs) with Mitsuba 3.

    VENV/bin/python bench/blender/mitsuba_normalmap.py SCENE.json OUT_PREFIX SPP SEED [THREADS]

Each panel is a `twosided` `normalmap` BSDF wrapping a Lambertian `diffuse`; the normal map is a
`bitmap` of the same 8-bit PNG, `raw` (no sRGB decoding) and `bilinear`. Mitsuba's bitmap puts
uv (0, 0) at the image's top-left texel (v runs down the image; its OBJ loader flips v by
default for that reason, its PLY loader does not), while the PLYs hold Blender's uvs (v up), so
the lookup flips v (`to_uv`). The normal map's axes are the shading frame's s (dp/du made
orthogonal to n: +u, image right) and t = n x s: +v, image up, as in Blender.

Two renders per scene, written as float64 arrays (rows top first, RGB):

    OUT_PREFIX-default.npy   normalmap's defaults in 3.9: flip_invalid_normals (a mapped normal
                             facing away from the viewer mirrored about the geometric normal)
                             and use_shadowing_function (Estevez et al. 2019's terminator term)
    OUT_PREFIX-plain.npy     both off: the nested diffuse with the mapped normal, nothing more

Direct illumination only (`direct`: an emitter and a BSDF sample, MIS), box pixel filter, the
`scalar_rgb` variant with THREADS worker threads (default 1).
"""

import json
import os
import sys

import drjit as dr
import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import mitsuba_flip_v, mitsuba_points, mitsuba_sensor  # noqa: E402

CONFIGS = {
    "default": {"flip_invalid_normals": True, "use_shadowing_function": True},
    "plain": {"flip_invalid_normals": False, "use_shadowing_function": False},
}


def panel(s, config):
    diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": s["color"]}}
    normalmap = {
        "type": "normalmap",
        "normalmap": {
            "type": "bitmap",
            "filename": s["normalmap"],
            "raw": True,
            "filter_type": "bilinear",
            "to_uv": mitsuba_flip_v(),
        },
        "bsdf": diffuse,
        **CONFIGS[config],
    }
    return {
        "type": "ply",
        "filename": s["ply"],
        "face_normals": True,
        "bsdf": {"type": "twosided", "bsdf": normalmap},
    }


def scene(desc, config):
    d = {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": mitsuba_sensor(desc["camera"]),
    }
    for i, s in enumerate(desc["panels"]):
        d[f"panel{i}"] = panel(s, config)
    for i, e in enumerate(desc.get("areas", [])):
        # One-sided: it emits on its face normal's side (toward the wall), as the PLY winds it.
        d[f"area{i}"] = {
            "type": "ply",
            "filename": e["ply"],
            "face_normals": True,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": e["radiance"]}},
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
        }
    d.update(mitsuba_points(desc.get("points", [])))
    return d


def main():
    path, prefix, spp, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    dr.set_thread_count(int(sys.argv[5]) if len(sys.argv) > 5 else 1)
    with open(path) as f:
        desc = json.load(f)
    for config in CONFIGS:
        img = mi.render(mi.load_dict(scene(desc, config)), spp=spp, seed=seed)
        np.save(f"{prefix}-{config}.npy", np.array(img, dtype=np.float64)[:, :, :3])


main()
