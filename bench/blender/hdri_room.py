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
import math
import os
import shutil
import subprocess
import sys
import time

import bpy
import numpy as np

HDRI_DIR = "/usr/share/blender/datafiles/studiolights/world"
ROOM = (4.0, 5.0, 2.6)  # x, y, z extent; the room spans x in [-2, 2], y in [-2.5, 2.5]
WINDOW = (-0.8, 0.8, 0.9, 2.1)  # x0, x1, z0, z1 in the north wall (y = 2.5)
ALBEDO = (0.8, 0.78, 0.72)
FLOOR_ALBEDO = (0.6, 0.55, 0.5)
CAMERA_AT = (1.3, -2.2, 1.1)
CAMERA_TARGET = (-0.3, 2.5, 1.45)
LENS = 18.0


def args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
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
    return p.parse_args(argv)


def lambert(name, color):
    """A Principled BSDF with Specular 0 (exported as a Lambertian glTF material)."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Specular"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    return m


def quad_facing(corners, inward):
    """The quad's corners ordered so that its face normal points along `inward`."""
    c = [np.array(p, dtype=float) for p in corners]
    n = np.cross(c[1] - c[0], c[2] - c[0])
    return corners if np.dot(n, inward) > 0 else corners[::-1]


def mesh_object(name, quads, material):
    verts, faces = [], []
    for q in quads:
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts.extend(q)
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    obj.data.materials.append(material)
    return obj


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


def look_rotation(frm, to, track="-Z"):
    from mathutils import Vector

    return (Vector(to) - Vector(frm)).to_track_quat(track, "Y").to_euler()


def build_scene(a, interpolation, hdri_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    floor, walls = room_quads()
    mesh_object("Floor", floor, lambert("Floor", FLOOR_ALBEDO))
    mesh_object("Walls", walls, lambert("Walls", ALBEDO))

    # The window portal: the opening, its face normal into the room (-Y).
    wx0, wx1, wz0, wz1 = WINDOW
    Y = ROOM[1] / 2
    portal = mesh_object(
        "Window",
        [quad_facing([(wx0, Y, wz0), (wx1, Y, wz0), (wx1, Y, wz1), (wx0, Y, wz1)], (0, -1, 0))],
        lambert("Portal", (0.0, 0.0, 0.0)),
    )
    portal["portal_target"] = "environment"
    portal.hide_render = True  # invisible to Cycles; portalview never renders portals

    bpy.ops.object.camera_add(location=CAMERA_AT)
    cam = bpy.context.object
    cam.name = "Camera"
    cam.rotation_euler = look_rotation(CAMERA_AT, CAMERA_TARGET)
    cam.data.lens = LENS
    scene.camera = cam

    world = bpy.data.worlds.new("HDRI")
    scene.world = world
    world.use_nodes = True
    # Cycles' importance map of the world (its cells evaluated at their centres): with Closest and
    # cells not aligned to the image's pixels, a cell partly on the sun records a dim neighbour,
    # and the sun's light comes in rare huge samples (per-pixel noise 10x that of Linear at the
    # default rotation -136). A rotation by whole pixels (387 of 1024) and a 4096-wide map keep
    # the cells inside pixels.
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = a.map_resolution
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes["Background"]
    bg.inputs["Strength"].default_value = a.strength
    coord = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(a.rotation))
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri_path)
    env.interpolation = interpolation
    env.projection = "EQUIRECTANGULAR"
    links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    links.new(env.outputs["Color"], bg.inputs["Color"])

    # What portalview reads from the scene's extras.
    scene["environment"] = os.path.basename(hdri_path)
    scene["environment_strength"] = a.strength
    scene["environment_rotation"] = a.rotation
    scene["environment_interpolation"] = interpolation.lower()  # "linear" or "closest"

    scene.render.resolution_x = a.width
    scene.render.resolution_y = a.height
    scene.render.resolution_percentage = 100


def export(path):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLTF_SEPARATE",
        export_extras=True,
        export_lights=True,
        export_cameras=True,
        export_yup=True,
        export_apply=True,
    )


def add_cycles_portal():
    """A Cycles light portal in the window (after export: glTF has no such thing)."""
    wx0, wx1, wz0, wz1 = WINDOW
    Y = ROOM[1] / 2
    at = ((wx0 + wx1) / 2, Y, (wz0 + wz1) / 2)
    bpy.ops.object.light_add(type="AREA", location=at)
    light = bpy.context.object
    light.name = "CyclesPortal"
    light.data.shape = "RECTANGLE"
    light.data.size = wx1 - wx0
    light.data.size_y = wz1 - wz0
    light.data.cycles.is_portal = True
    # An area light shines along its local -Z: into the room (-Y); local Y up (+Z).
    light.rotation_euler = (-math.pi / 2, 0.0, 0.0)


def swap_to_diffuse():
    for m in bpy.data.materials:
        if not m.use_nodes or "Principled BSDF" not in m.node_tree.nodes:
            continue
        nodes, links = m.node_tree.nodes, m.node_tree.links
        p = nodes["Principled BSDF"]
        d = nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = p.inputs["Base Color"].default_value
        for link in list(p.inputs["Base Color"].links):
            links.new(link.from_socket, d.inputs["Color"])
        for link in list(p.inputs["Normal"].links):
            links.new(link.from_socket, d.inputs["Normal"])
        links.new(d.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
        nodes.remove(p)


def render_cycles(path, spp, seed, threads, depth, transparent=False):
    s = bpy.context.scene
    s.render.engine = "CYCLES"
    s.cycles.device = "CPU"
    s.render.threads_mode = "FIXED"
    s.render.threads = threads
    s.cycles.samples = spp
    s.cycles.use_adaptive_sampling = False
    s.cycles.use_denoising = False
    b = max(depth - 1, 0)
    s.cycles.max_bounces = b
    s.cycles.diffuse_bounces = b
    s.cycles.glossy_bounces = b
    s.cycles.transmission_bounces = b
    s.cycles.transparent_max_bounces = 8
    s.cycles.sample_clamp_direct = 0.0
    s.cycles.sample_clamp_indirect = 0.0
    s.cycles.pixel_filter_type = "BOX"
    s.cycles.filter_width = 1.0
    s.cycles.seed = seed
    s.render.film_transparent = transparent
    s.view_settings.view_transform = "Standard"
    s.render.image_settings.file_format = "OPEN_EXR"
    s.render.image_settings.color_mode = "RGBA"
    s.render.image_settings.color_depth = "32"
    s.render.filepath = path
    bpy.ops.render.render(write_still=True)


def load_exr(path, alpha=False):
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    px = px[::-1]  # top row first
    return px if alpha else px[..., :3]


def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def run_portalview(exe, gltf, path, a, extra=()):
    env = dict(os.environ, RAYON_NUM_THREADS=str(a.pv_threads))
    cmd = [
        exe, "render", "--scene", gltf, "--width", str(a.width), "--height", str(a.height),
        "--spp", str(a.pv_spp), "--seed", "1", "--max-depth", str(a.depth), "--out", path,
        *a.pv_args.split(), *extra,
    ]
    t0 = time.time()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        print(f"portalview failed on {gltf}:\n{r.stderr.strip()}")
        return None
    print(f"  portalview {path}: {time.time() - t0:.0f} s")
    return load_exr(path)


def stats(cycles, other, masks):
    cy = (cycles[0] + cycles[1]) / 2
    noise = np.abs(cycles[0] - cycles[1]) / 2
    rows = []
    for region, m in masks.items():
        c = cy[m].mean()
        ratio = other[m].mean() / c if other is not None else float("nan")
        rms = math.sqrt(np.mean((other[m] - cy[m]) ** 2)) / c if other is not None else float("nan")
        rows.append((region, int(m.sum()), c, ratio, rms, math.sqrt(np.mean(noise[m] ** 2)) / c))
    return rows


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
        export(gltf)
        with open(gltf) as f:
            g = json.load(f)
        print(f"{tag}: scene extras {g['scenes'][0].get('extras')}; portal node extras "
              f"{[n.get('extras') for n in g['nodes'] if n.get('name') == 'Window']}")
        swap_to_diffuse()
        add_cycles_portal()
        mask_path = os.path.join(out, "mask.exr")
        if a.force or not os.path.exists(mask_path):
            render_cycles(mask_path, 16, 1, a.threads, 1, transparent=True)
        alpha = load_exr(mask_path, alpha=True)[..., 3]
        masks = {"room": alpha > 0.999, "sky": alpha < 0.001}
        cycles = []
        for seed in (1, 2):
            path = os.path.join(out, f"cycles-{tag}-d{a.depth}-{seed}.exr")
            if a.force or not os.path.exists(path):
                t0 = time.time()
                render_cycles(path, a.spp, seed, a.threads, a.depth)
                print(f"  Cycles {path}: {time.time() - t0:.0f} s")
            cycles.append(luminance(load_exr(path)))
        pv = None
        if a.portalview:
            path = os.path.join(out, "portalview", f"{tag}-d{a.depth}.exr")
            os.makedirs(os.path.dirname(path), exist_ok=True)
            pv = run_portalview(a.portalview, gltf, path, a)
            pv = luminance(pv) if pv is not None else None
        for row in stats(cycles, pv, masks):
            table.append((tag, *row))
    print(f"\n{'interp':<8} {'region':<6} {'pixels':>6} {'Cycles mean':>11} {'ratio':>7} "
          f"{'RMS diff':>9} {'cy noise':>9}")
    for tag, region, n, c, ratio, rms, nz in table:
        print(f"{tag:<8} {region:<6} {n:6d} {c:11.5f} {ratio:7.3f} {100 * rms:8.1f}% {100 * nz:8.1f}%")
    with open(os.path.join(out, f"table-d{a.depth}.json"), "w") as f:
        json.dump(table, f, indent=1)


main()
