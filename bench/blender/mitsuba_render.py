"""Render the Mitsuba scene that bench/blender/run.py wrote (JSON + PLY) with Mitsuba 3.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \
        VENV/bin/python bench/blender/mitsuba_render.py SCENE.json OUT.npy SPP SEED

Writes the image as a float64 array (rows top first, RGB) for run.py to compare.
"""

import json
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("llvm_ad_rgb")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import mitsuba_flip_v, mitsuba_points, mitsuba_sensor  # noqa: E402


def shape(s):
    bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": s["color"]}}
    if "texture" in s:
        # The PLY's v is Blender's (origin at the image's bottom row); Mitsuba's bitmap puts
        # v = 0 at the top row, so the lookup flips v.
        bsdf["reflectance"] = {
            "type": "bitmap",
            "filename": s["texture"],
            "filter_type": s["filter"],
            "to_uv": mitsuba_flip_v(),
        }
    d = {
        "type": "ply",
        "filename": s["ply"],
        "face_normals": True,
        "flip_normals": s.get("flip", False),
        "bsdf": {"type": "twosided", "bsdf": bsdf},
    }
    if "radiance" in s:
        d["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": s["radiance"]}}
        d["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}}
    return d


def main():
    path, out, spp, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    desc = json.load(open(path))
    scene = {"type": "scene", "integrator": {"type": "direct"}}
    scene["sensor"] = mitsuba_sensor(desc["camera"])
    for i, s in enumerate(desc["shapes"]):
        scene[f"shape{i}"] = shape(s)
    scene.update(mitsuba_points(desc["points"]))
    img = mi.render(mi.load_dict(scene), spp=spp, seed=seed)
    np.save(out, np.array(img, dtype=np.float64)[:, :, :3])


main()
