"""A real client on skin.glb: Blender imports it (its glTF importer), finds an armature of the
25 joints, turns the index PIP bone and sees the skin move.

    blender --background --factory-startup --python scripts/blender_import.py -- skin.glb

Prints one JSON line of figures; exits 0 when every check holds, 1 otherwise.
"""
import json
import math
import os
import sys

import bpy
import numpy

# Debian 12's Blender 3.4 glTF importer still uses numpy.bool, which NumPy 1.24 (Debian's)
# removed; the alias is the builtin bool, as NumPy's deprecation note says.
if "bool" not in vars(numpy):
    numpy.bool = bool

glb = sys.argv[sys.argv.index("--") + 1]
result = {"blender": bpy.app.version_string}
ok = False
try:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=glb)
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    result["armatures"], result["meshes"] = len(arms), len(meshes)
    arm, mesh = arms[0], meshes[0]
    result["bones"] = len(arm.data.bones)

    def world_vertices():
        dg = bpy.context.evaluated_depsgraph_get()
        ev = mesh.evaluated_get(dg)
        m = ev.to_mesh()
        out = [ev.matrix_world @ v.co for v in m.vertices]
        ev.to_mesh_clear()
        return out

    before = world_vertices()
    pb = arm.pose.bones["index-finger-phalanx-intermediate"]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler[0] = math.radians(60)
    bpy.context.view_layer.update()
    after = world_vertices()
    moved = [(a - b).length for a, b in zip(after, before)]
    result["vertices"] = len(before)
    result["moved"] = sum(1 for d in moved if d > 1e-5)
    result["most_moved_m"] = max(moved)
    ok = result["bones"] == 25 and result["armatures"] == 1 and result["moved"] > 50 and result["most_moved_m"] > 0.01
except Exception as e:  # noqa: BLE001 - any failure is the test's answer
    result["error"] = str(e)
print("blender_import: " + json.dumps(result), flush=True)
sys.stdout.flush()
os._exit(0 if ok else 1)
