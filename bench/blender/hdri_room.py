"""A room lit by a real HDRI (Blender's city.exr) through one window: Cycles references.

Run with Blender 3.4 from the repository root (outputs go to --out, not the repository):

    blender -b --factory-startup -t 1 -P bench/blender/hdri_room.py -- \
        --out /work/refs/hdri_room [--portalview target/release/portalview]

The scene (Blender Z up): a closed 4 x 5 x 2.6 m room of Lambertian white-ish quads (Principled
BSDF, Specular 0, exported as such and swapped for a Diffuse BSDF before Cycles renders), one
1.6 x 1.2 m window opening in the north wall (y = 2.5, sill 0.9 m), a window portal plane in the
opening (face normal into the room, custom property portal_target = "environment", invisible to
Cycles), and a camera inside that sees the walls, the floor's sun patch and, through the window,
the sky. World: Texture Coordinate (Generated) -> Mapping (Point, Z rotation) -> Environment
Texture (city.exr, Linear or Closest) -> Background (strength). The scene's custom properties
carry the same environment for portalview (`environment` = "city.exr" beside the .gltf,
`environment_strength`, `environment_rotation` in degrees, `environment_interpolation` =
"linear" or "closest") and are exported with
export_extras. One glTF per interpolation (`linear/scene.gltf`, `closest/scene.gltf`).

Cycles renders with max_bounces = depth - 1 (portalview's --max-depth counts path vertices after
the camera; depth 1 = direct light only), box filter of width 1, no clamping, two seeds, and a
Cycles light portal (an area light with is_portal, added after export) in the window to cut its
noise (portals change Cycles' sampling, not its expectation). A separate transparent-film render
gives the masks: `sky` = pixels whose camera rays all leave through the window, `room` = pixels
that see only the room. Renders are kept and reused; --force renders Cycles again.

With --portalview, each glTF is rendered with it at the same size and depth and compared: mean over
room pixels and over sky pixels (portalview / Cycles, luminance) and the RMS per-pixel difference
relative to Cycles' mean (`cy noise`: the RMS standard error of Cycles' two-seed mean per pixel).
"""

import argparse
import json
import os
import shutil
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (  # noqa: E402
    alpha_mask, cycles_two_seeds, cycles_window_portal, export_gltf, lambert_material,
    hdri_world, look_rotation, mesh_object, principled_to_diffuse, print_region_table,
    quad_facing,
    region_stats,
    run_portalview, script_argv, set_resolution, write_json,
)

HDRI_DIR = "/usr/share/blender/datafiles/studiolights/world"
ROOM = (4.0, 5.0, 2.6)  # x, y, z extent; the room spans x in [-2, 2], y in [-2.5, 2.5]
WINDOW = (-0.8, 0.8, 0.9, 2.1)  # x0, x1, z0, z1 in the north wall (y = 2.5)
ALBEDO = (0.8, 0.78, 0.72)
FLOOR_ALBEDO = (0.6, 0.55, 0.5)
CAMERA_AT = (1.3, -2.2, 1.1)
CAMERA_TARGET = (-0.3, 2.5, 1.45)
LENS = 18.0
BOUNCES = ("diffuse", "glossy", "transmission")  # each limited to depth - 1 as max_bounces


def args():
    p = argparse.ArgumentParser()
    p.add_argument("--out", default="/work/refs/hdri_room")
    p.add_argument("--portalview", help="render each glTF with it and compare")
    p.add_argument("--hdri", default="city.exr")
    p.add_argument("--strength", type=float, default=1.0)
    p.add_argument(
        "--rotation",
        type=float,
        default=-387 * 360 / 1024,
        help="Mapping node Z rotation in degrees (the default, -136.05 = 387 of city.exr's 1024 "
        "columns, puts its sun through the window)",
    )
    p.add_argument("--depth", type=int, default=1, help="path depth (1 = direct light only)")
    p.add_argument("--width", type=int, default=192)
    p.add_argument("--height", type=int, default=144)
    p.add_argument("--spp", type=int, default=1024, help="Cycles samples per pixel per seed")
    p.add_argument("--pv-spp", type=int, default=256)
    p.add_argument("--pv-threads", type=int, default=1, help="RAYON_NUM_THREADS for portalview")
    p.add_argument("--pv-args", default="", help="extra portalview render arguments")
    p.add_argument("--threads", type=int, default=1, help="Cycles threads")
    p.add_argument("--interpolations", default="Linear,Closest")
    p.add_argument("--force", action="store_true", help="render Cycles again")
    p.add_argument("--map-resolution", type=int, default=4096, help="Cycles' world sampling map")
    return p.parse_args(script_argv())




def room_quads():
    """Floor, ceiling and walls as quads facing into the room; the north wall has the window."""
    X, Y, Z = ROOM[0] / 2, ROOM[1] / 2, ROOM[2]
    wx0, wx1, wz0, wz1 = WINDOW
    floor = [quad_facing([(-X, -Y, 0), (X, -Y, 0), (X, Y, 0), (-X, Y, 0)], (0, 0, 1))]
    walls = [
        quad_facing([(-X, -Y, Z), (X, -Y, Z), (X, Y, Z), (-X, Y, Z)], (0, 0, -1)),
        quad_facing([(-X, -Y, 0), (X, -Y, 0), (X, -Y, Z), (-X, -Y, Z)], (0, 1, 0)),
        quad_facing([(-X, -Y, 0), (-X, Y, 0), (-X, Y, Z), (-X, -Y, Z)], (1, 0, 0)),
        quad_facing([(X, -Y, 0), (X, Y, 0), (X, Y, Z), (X, -Y, Z)], (-1, 0, 0)),
    ]
    north = [
        ((-X, 0), (X, wz0)),  # below the sill
        ((-X, wz1), (X, Z)),  # above the lintel
        ((-X, wz0), (wx0, wz1)),  # left of the window
        ((wx1, wz0), (X, wz1)),  # right of the window
    ]
    for (x0, z0), (x1, z1) in north:
        walls.append(quad_facing([(x0, Y, z0), (x1, Y, z0), (x1, Y, z1), (x0, Y, z1)], (0, -1, 0)))
    return floor, walls


def build_scene(a, interpolation, hdri_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    floor, walls = room_quads()
    mesh_object("Floor", floor, lambert_material("Floor", FLOOR_ALBEDO))
    mesh_object("Walls", walls, lambert_material("Walls", ALBEDO))

    # The window portal: the opening, its face normal into the room (-Y).
    wx0, wx1, wz0, wz1 = WINDOW
    Y = ROOM[1] / 2
    portal = mesh_object(
        "Window",
        [quad_facing([(wx0, Y, wz0), (wx1, Y, wz0), (wx1, Y, wz1), (wx0, Y, wz1)], (0, -1, 0))],
        lambert_material("Portal", (0.0, 0.0, 0.0)),
    )
    portal["portal_target"] = "environment"
    portal.hide_render = True  # invisible to Cycles; portalview never renders portals

    bpy.ops.object.camera_add(location=CAMERA_AT)
    cam = bpy.context.object
    cam.name = "Camera"
    cam.rotation_euler = look_rotation(CAMERA_AT, CAMERA_TARGET)
    cam.data.lens = LENS
    scene.camera = cam

    # Cycles' importance map of the world (its cells evaluated at their centres): with Closest and
    # cells not aligned to the image's pixels, a cell partly on the sun records a dim neighbour,
    # and the sun's light comes in rare huge samples (per-pixel noise 10x that of Linear at the
    # default rotation -136). A rotation by whole pixels (387 of 1024) and a 4096-wide map keep
    # the cells inside pixels.
    hdri_world(scene, hdri_path, a.strength, a.rotation, interpolation, a.map_resolution)

    set_resolution(scene, a.width, a.height)


def main():
    a = args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    src = os.path.join(HDRI_DIR, a.hdri)
    table = []
    for interpolation in a.interpolations.split(","):
        tag = interpolation.lower()
        gltf = os.path.join(out, tag, "scene.gltf")
        os.makedirs(os.path.dirname(gltf), exist_ok=True)
        hdri = os.path.join(os.path.dirname(gltf), a.hdri)
        shutil.copyfile(src, hdri)
        build_scene(a, interpolation, hdri)
        export_gltf(gltf)
        with open(gltf) as f:
            g = json.load(f)
        print(f"{tag}: scene extras {g['scenes'][0].get('extras')}; portal node extras "
              f"{[n.get('extras') for n in g['nodes'] if n.get('name') == 'Window']}")
        principled_to_diffuse()
        # A Cycles light portal in the window (after export: glTF has no such thing).
        wx0, wx1, wz0, wz1 = WINDOW
        cycles_window_portal(wx0, wx1, wz0, wz1, ROOM[1] / 2, name="CyclesPortal")
        alpha = alpha_mask(os.path.join(out, "mask.exr"), a.force, threads=a.threads, limit=BOUNCES)
        masks = {"room": alpha > 0.999, "sky": alpha < 0.001}
        cycles = cycles_two_seeds(os.path.join(out, f"cycles-{tag}-d{a.depth}"), a.spp, a.force,
                                  threads=a.threads, depth=a.depth, limit=BOUNCES)
        pv = None
        if a.portalview:
            path = os.path.join(out, "portalview", f"{tag}-d{a.depth}.exr")
            pv = run_portalview(a.portalview, gltf, path, a, depth=a.depth, extra=a.pv_args.split())
        for row in region_stats(cycles, pv, masks):
            table.append((tag, *row))
    print_region_table(table, lead="interp")
    write_json(os.path.join(out, f"table-d{a.depth}.json"), table)


main()
