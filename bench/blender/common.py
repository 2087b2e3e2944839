"""Helpers shared by the scripts in bench/blender (run.py, normalmap.py, hdri_room.py,
nonormals.py under Blender; mitsuba_render.py and mitsuba_normalmap.py under Mitsuba's Python).

Each script puts its own folder first on sys.path and imports from here. bpy is imported only
where it exists: under Mitsuba's Python the Blender helpers are unusable, the Mitsuba ones work.
"""

import json
import math
import os
import subprocess
import sys
import time

import numpy as np

try:
    import bpy
except ImportError:  # not in Blender: only the Mitsuba and plain numpy helpers are usable
    bpy = None

HERE = os.path.dirname(os.path.abspath(__file__))


def script_argv():
    """The script's own arguments: those after Blender's `--`."""
    return sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []


def write_json(path, data):
    """data as JSON (indent 1) at path; returns path."""
    with open(path, "w") as f:
        json.dump(data, f, indent=1)
    return path


# --- building the scene -----------------------------------------------------------------------


def lambert_material(name, color):
    """A Principled BSDF with Specular 0 and Roughness 1 (exported as a Lambertian glTF
    material); color is linear RGB."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Specular"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    return m


def emission_material(name, color, strength):
    """An Emission shader alone (radiance = strength x color)."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    e = nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*color, 1.0)
    e.inputs["Strength"].default_value = strength
    m.node_tree.links.new(e.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
    return m


def look_rotation(frm, to, track="-Z"):
    """The Euler rotation that turns an object at `frm` to point its `track` axis at `to`, its
    local Y up (a camera looks down its -Z)."""
    from mathutils import Vector

    return (Vector(to) - Vector(frm)).to_track_quat(track, "Y").to_euler()


def black_world(scene):
    """A world of strength 0: no light but the scene's own."""
    scene.world = bpy.data.worlds.new("Black")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0


def set_resolution(scene, width, height):
    """The render's size: width x height pixels at 100%."""
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100


def cycles_window_portal(x0, x1, z0, z1, y, name=None):
    """A Cycles light portal (an area light with is_portal) filling the opening x in [x0, x1],
    z in [z0, z1] of the wall y = `y` (Blender Z up), shining into the room along -Y; named
    `name` (None: Blender's default). glTF has no such thing: add it after export."""
    bpy.ops.object.light_add(type="AREA", location=((x0 + x1) / 2, y, (z0 + z1) / 2))
    light = bpy.context.object
    if name is not None:
        light.name = name
    light.data.shape = "RECTANGLE"
    light.data.size = x1 - x0
    light.data.size_y = z1 - z0
    light.data.cycles.is_portal = True
    # An area light shines along its local -Z: into the room (-Y); local Y up (+Z).
    light.rotation_euler = (-math.pi / 2, 0.0, 0.0)
    return light


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


def hdri_world(scene, hdri_path, strength, rotation, interpolation="Linear",
               map_resolution=2048):
    """The world lit by the equirectangular image `hdri_path` (Mapping's Z rotation in
    degrees, Environment Texture's `interpolation`), and the scene extras portalview reads
    for the same sky (the image is named relative to the exported file)."""
    world = bpy.data.worlds.new("HDRI")
    scene.world = world
    world.use_nodes = True
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = map_resolution
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes["Background"]
    bg.inputs["Strength"].default_value = strength
    coord = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(rotation))
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri_path)
    env.interpolation = interpolation
    env.projection = "EQUIRECTANGULAR"
    links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    links.new(env.outputs["Color"], bg.inputs["Color"])
    scene["environment"] = os.path.basename(hdri_path)
    scene["environment_strength"] = strength
    scene["environment_rotation"] = rotation
    scene["environment_interpolation"] = interpolation.lower()  # "linear" or "closest"


def export_gltf(path, tangents=False, glb=False):
    """The scene as glTF (.gltf + .bin + textures, or one .glb if `glb`) with Blender's
    exporter: custom properties as extras, lights, cameras, Y up, modifiers applied, TANGENT if
    `tangents`."""
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLB" if glb else "GLTF_SEPARATE",
        export_extras=True,
        export_lights=True,
        export_cameras=True,
        export_yup=True,
        export_apply=True,
        export_tangents=tangents,
    )


def principled_to_diffuse():
    """The glTF file describes Lambertian surfaces; Cycles' Diffuse BSDF is one (Principled
    BSDF's diffuse has a retro-reflection term). Each Principled BSDF is swapped for a Diffuse
    BSDF with the same colour (value and link) and the same Normal link (e.g. from a Normal Map
    node)."""
    for m in bpy.data.materials:
        if not m.use_nodes or "Principled BSDF" not in m.node_tree.nodes:
            continue
        nodes, links = m.node_tree.nodes, m.node_tree.links
        p = nodes["Principled BSDF"]
        d = diffuse_like(m, p)
        links.new(d.outputs["BSDF"], material_output(m).inputs["Surface"])
        nodes.remove(p)


def diffuse_like(m, p):
    """A new Diffuse BSDF in material m with Principled BSDF p's colour (value and link) and
    Normal link."""
    nodes, links = m.node_tree.nodes, m.node_tree.links
    d = nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = p.inputs["Base Color"].default_value
    for link in list(p.inputs["Base Color"].links):
        links.new(link.from_socket, d.inputs["Color"])
    for link in list(p.inputs["Normal"].links):
        links.new(link.from_socket, d.inputs["Normal"])
    return d


def material_output(m):
    """Material m's output node, by type: an imported material's may have another name."""
    return [n for n in m.node_tree.nodes if n.type == "OUTPUT_MATERIAL"][0]


# --- rendering and reading images -------------------------------------------------------------


def render_cycles(path, spp, seed, threads=None, depth=1, limit=(), transparent=False,
                  overrides=None):
    """A Cycles render on the CPU to a 32-bit RGBA OpenEXR: spp samples, no adaptive sampling,
    denoising or clamping, box filter of width 1, the Standard view transform.

    threads: a fixed thread count (None: Blender's, e.g. from -t). depth: portalview's
    --max-depth (path vertices after the camera; 1 = direct light only): max_bounces = depth - 1,
    and the same limit on each kind of bounce in `limit` ("diffuse", "glossy", "transmission").
    transparent: transparent film (alpha 0 where camera rays leave the scene). overrides: other
    scene.cycles settings ({name: value}, e.g. bounce limits or caustics), set last."""
    s = bpy.context.scene
    s.render.engine = "CYCLES"
    s.cycles.device = "CPU"
    if threads is not None:
        s.render.threads_mode = "FIXED"
        s.render.threads = threads
    s.cycles.samples = spp
    s.cycles.use_adaptive_sampling = False
    s.cycles.use_denoising = False
    b = max(depth - 1, 0)
    s.cycles.max_bounces = b  # depth 1: direct light only, as portalview's --max-depth 1
    for kind in limit:
        setattr(s.cycles, f"{kind}_bounces", b)
    s.cycles.transparent_max_bounces = 8  # Blender's default
    s.cycles.sample_clamp_direct = 0.0
    s.cycles.sample_clamp_indirect = 0.0
    s.cycles.pixel_filter_type = "BOX"
    s.cycles.filter_width = 1.0
    s.cycles.seed = seed
    s.render.film_transparent = transparent
    for name, value in (overrides or {}).items():
        setattr(s.cycles, name, value)
    s.view_settings.view_transform = "Standard"
    s.render.image_settings.file_format = "OPEN_EXR"
    s.render.image_settings.color_mode = "RGBA"  # Blender's default
    s.render.image_settings.color_depth = "32"
    s.render.filepath = path
    bpy.ops.render.render(write_still=True)


def cycles_two_seeds(prefix, spp, force=False, **settings):
    """Cycles' renders with seeds 1 and 2, `prefix`-1.exr and `prefix`-2.exr, as luminance
    images. An existing render is reused unless `force`; a new one is timed. settings: the rest
    of render_cycles' arguments."""
    images = []
    for seed in (1, 2):
        path = f"{prefix}-{seed}.exr"
        if force or not os.path.exists(path):
            t0 = time.time()
            render_cycles(path, spp, seed, **settings)
            print(f"  Cycles {path}: {time.time() - t0:.0f} s")
        images.append(luminance(load_exr(path)))
    return images


def alpha_mask(path, force=False, only=None, **settings):
    """The alpha (h, w) of a 16-sample transparent-film render at `path` (reused unless
    `force`): 1 where every camera ray of the pixel meets the scene, 0 where all leave it. With
    `only` (a mesh object's name) the other mesh objects are hidden for the render. settings:
    render_cycles' threads and limit."""
    if force or not os.path.exists(path):
        objects = bpy.context.scene.objects
        hidden = [o for o in objects if o.type == "MESH" and o.name != only] if only else []
        was = [o.hide_render for o in hidden]
        for o in hidden:
            o.hide_render = True
        render_cycles(path, 16, 1, transparent=True, **settings)
        for o, w in zip(hidden, was):
            o.hide_render = w
    return load_exr(path, alpha=True)[..., 3]


def gltf_json(path):
    """The JSON of a .gltf, or of a .glb's first (JSON) chunk, as a dict."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"glTF":
        return json.loads(data)
    length = int.from_bytes(data[12:16], "little")
    return json.loads(data[20 : 20 + length])


def load_exr(path, alpha=False):
    """An OpenEXR as float64 (h, w, 3), or (h, w, 4) with alpha, top row first."""
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    px = px[::-1]  # top row first
    return px if alpha else px[..., :3]


def luminance(rgb):
    """Rec. 709 luminance of linear RGB (..., 3)."""
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def run_portalview(exe, gltf, path, a, seed=1, depth=1, extra=(), show=None, seconds=None,
                   info=None):
    """`exe render` of gltf to the OpenEXR `path` (its folder made if need be) at a.width x
    a.height, a.pv_spp samples per pixel (or `seconds` of passes, --seconds), --max-depth depth,
    RAYON_NUM_THREADS = a.pv_threads, then `extra` arguments. Prints the time (naming the output
    `show`, by default path) and returns the image's luminance, or None (with portalview's stderr
    printed) if it failed. info (a dict): gets "wall" (seconds) and "stdout"."""
    os.makedirs(os.path.dirname(path), exist_ok=True)
    env = dict(os.environ, RAYON_NUM_THREADS=str(a.pv_threads))
    budget = ["--spp", str(a.pv_spp)] if seconds is None else ["--seconds", f"{seconds:.6g}"]
    cmd = [
        exe, "render", "--scene", gltf, "--width", str(a.width), "--height", str(a.height),
        *budget, "--seed", str(seed), "--max-depth", str(depth), "--out", path, *extra,
    ]
    t0 = time.time()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        print(f"portalview failed on {gltf}:\n{r.stderr.strip()}")
        return None
    if info is not None:
        info.update(wall=time.time() - t0, stdout=r.stdout)
    print(f"  portalview {path if show is None else show}: {time.time() - t0:.0f} s")
    return luminance(load_exr(path))


# --- comparing --------------------------------------------------------------------------------


def two_seed_mean(first, second):
    """The mean of two renders with different seeds and, per pixel, the standard error of that
    mean, roughly: |first - second| / 2."""
    return (first + second) / 2, np.abs(first - second) / 2


def region_compare(ref, noise, other, m):
    """Over the pixels of mask m: the reference's mean c, other's mean / c, the RMS of
    other - ref relative to c, and the RMS of `noise` (the reference's per-pixel standard error)
    relative to c. With other None the ratio and the RMS difference are nan."""
    c = ref[m].mean()
    ratio = other[m].mean() / c if other is not None else float("nan")
    rms = math.sqrt(np.mean((other[m] - ref[m]) ** 2)) / c if other is not None else float("nan")
    return c, ratio, rms, math.sqrt(np.mean(noise[m] ** 2)) / c


def region_stats(cycles, other, masks):
    """Per region of `masks` ({name: boolean mask}): (name, pixels, Cycles mean, ratio, RMS
    difference, Cycles noise) of other (a luminance image, or None) against the mean of the two
    Cycles seeds `cycles`, as region_compare."""
    cy, noise = two_seed_mean(*cycles)
    return [
        (region, int(m.sum()), *region_compare(cy, noise, other, m)) for region, m in masks.items()
    ]


def print_region_table(rows, lead=None):
    """region_stats' rows as a table. With `lead` (the name of a first column) each row is
    (that column's value, *region_stats row)."""
    head = f"{lead:<8} " if lead else ""
    print(f"\n{head}{'region':<6} {'pixels':>6} {'Cycles mean':>11} {'ratio':>7} "
          f"{'RMS diff':>9} {'cy noise':>9}")
    for row in rows:
        first = f"{row[0]:<8} " if lead else ""
        region, n, c, ratio, rms, nz = row[1:] if lead else row
        print(f"{first}{region:<6} {n:6d} {c:11.5f} {ratio:7.3f} {100 * rms:8.1f}% "
              f"{100 * nz:8.1f}%")


# --- Mitsuba 3 --------------------------------------------------------------------------------


def write_ply(path, tris, uvs):
    """Triangles (n, 3, 3) with per-corner uvs (n, 3, 2) as a binary PLY, vertices unshared."""
    n = len(tris)
    verts = np.concatenate([np.reshape(tris, (-1, 3)), np.reshape(uvs, (-1, 2))], axis=1)
    faces = np.zeros(n, dtype=[("k", "u1"), ("i", "<i4", 3)])
    faces["k"] = 3
    faces["i"] = np.arange(3 * n).reshape(n, 3)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {3 * n}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float u\nproperty float v\n"
        f"element face {n}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(verts.astype("<f4").tobytes())
        f.write(faces.tobytes())


def mesh_triangles(obj):
    """World-space triangles of obj's evaluated mesh (Blender's winding) and their corners' uvs
    as Blender has them (v up the image; (0, 0) without a uv map)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    mesh.calc_loop_triangles()
    m = np.array(obj.matrix_world)
    uv_layer = mesh.uv_layers.active.data if mesh.uv_layers.active else None
    tris, uvs = [], []
    for t in mesh.loop_triangles:
        tris.append([(m @ np.array([*mesh.vertices[v].co, 1.0]))[:3] for v in t.vertices])
        uvs.append([tuple(uv_layer[l].uv) if uv_layer else (0.0, 0.0) for l in t.loops])
    ev.to_mesh_clear()
    return np.array(tris), np.array(uvs)


def mitsuba_point(obj):
    """A Blender point lamp as Mitsuba's point emitter: intensity P/(4 pi) W/sr x colour."""
    p = obj.data.energy / (4 * math.pi)
    return {
        "position": list(obj.matrix_world.translation),
        "intensity": [p * c for c in obj.data.color],
    }


def mitsuba_camera(width, height):
    """The scene's camera for Mitsuba: Mitsuba looks down +Z with +X to the left, so to_world =
    camera matrix x diag(-1, 1, -1, 1); the horizontal field of view in degrees."""
    cam = bpy.context.scene.camera
    to_world = np.array(cam.matrix_world) @ np.diag([-1.0, 1.0, -1.0, 1.0])
    return {"to_world": to_world.tolist(), "fov_x_degrees": math.degrees(cam.data.angle_x),
            "width": width, "height": height}


def mitsuba_sensor(c):
    """Mitsuba's perspective sensor for mitsuba_camera's description c: box filter, RGB film."""
    import mitsuba as mi

    return {
        "type": "perspective",
        "fov_axis": "x",
        "fov": c["fov_x_degrees"],
        "to_world": mi.ScalarTransform4f(c["to_world"]),
        "film": {
            "type": "hdrfilm",
            "width": c["width"],
            "height": c["height"],
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
    }


def mitsuba_points(points):
    """Mitsuba point emitters {"point<i>": ...} for mitsuba_point's descriptions."""
    return {
        f"point{i}": {
            "type": "point",
            "position": p["position"],
            "intensity": {"type": "rgb", "value": p["intensity"]},
        }
        for i, p in enumerate(points)
    }


def mitsuba_flip_v():
    """A bitmap's to_uv for Blender's uvs: v' = 1 - v (Blender's v = 0 is the image's bottom
    row, Mitsuba's its top row)."""
    import mitsuba as mi

    return mi.ScalarTransform4f().translate([0, 1, 0]).scale([1, -1, 1])
