"""A lamp as an artist models it in Blender, without portals, for `portalview portals --find`.

Run with Blender 3.4 from the repository root (the output goes to --out, not the repository):

    blender -b --factory-startup -P bench/blender/find_portals.py -- --out /tmp/shade.glb
    target/release/portalview portals --find /tmp/shade.glb --out /tmp/shade_portals.glb

The scene (Blender Z up): a floor, a table, a 16-sided cone frustum shade open at both ends
(radius 0.22 m at the bottom, 0.14 m at the top, 0.3 m high, centred 1.2 m up) made with *Add →
Cone* and *Cap Fill Type: Nothing*, a 10 cm emissive plane inside it (Principled emission 50,
backface culling off: two-sided), and a camera. Exported as GLB with custom properties. Measured
(2026-12-03): two portals found, a 12-gon of 0.0614 m² over the top rim (its 16-gon is 0.0600 m²)
and one of 0.1515 m² over the bottom (0.1482 m²), each covering its rim (the 16 sides are
reduced to 12 by extending edges, so the portal is 2% larger); the check finds 55% of the
bulb's light through them and no leak, and `auto` sets alpha to 0.02.
"""

import math
import sys

import bpy


def out_path():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    return argv[argv.index("--out") + 1] if "--out" in argv else "shade.glb"


def material(name, color, emission=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1)
    if emission:
        p.inputs["Emission"].default_value = (1, 0.9, 0.8, 1)
        p.inputs["Emission Strength"].default_value = emission
    return m


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 0))
    bpy.context.object.name = "Floor"
    bpy.context.object.data.materials.append(material("floor", (0.5, 0.4, 0.3)))
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.35), scale=(0.5, 0.5, 0.35))
    bpy.context.object.name = "Table"
    bpy.context.object.data.materials.append(material("table", (0.3, 0.2, 0.1)))
    bpy.ops.mesh.primitive_cone_add(
        vertices=16, radius1=0.22, radius2=0.14, depth=0.3, end_fill_type='NOTHING',
        location=(0, 0, 1.2))
    bpy.context.object.name = "Shade"
    bpy.context.object.data.materials.append(material("shade", (0.8, 0.7, 0.5)))
    bpy.ops.mesh.primitive_plane_add(size=0.1, location=(0, 0, 1.2))
    bpy.context.object.name = "Bulb"
    bulb = material("bulb", (0, 0, 0), emission=50.0)
    bulb.use_backface_culling = False
    bpy.context.object.data.materials.append(bulb)
    bpy.ops.object.camera_add(
        location=(2.5, -2.5, 1.8), rotation=(math.radians(70), 0, math.radians(45)))
    scene.camera = bpy.context.object
    bpy.ops.export_scene.gltf(
        filepath=out_path(), export_format='GLB', export_extras=True, export_cameras=True)


main()
