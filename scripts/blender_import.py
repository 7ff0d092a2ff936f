"""A real client on skin.glb: Blender imports it (its glTF importer), finds an armature of the
25 joints, turns the index PIP bone and sees the skin move.

    blender --background --factory-startup --python scripts/blender_import.py -- skin.glb

Prints one JSON line of figures; exits 0 when every check holds, 1 otherwise.
"""
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_glb import finish, glb_argument, import_glb, world_vertices  # noqa: E402

result = {"blender": bpy.app.version_string}
ok = False
try:
    arm, mesh = import_glb(glb_argument(), result)
    result["bones"] = len(arm.data.bones)
    before = world_vertices(mesh)
    pb = arm.pose.bones["index-finger-phalanx-intermediate"]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler[0] = math.radians(60)
    bpy.context.view_layer.update()
    after = world_vertices(mesh)
    moved = [(a - b).length for a, b in zip(after, before)]
    result["vertices"] = len(before)
    result["moved"] = sum(1 for d in moved if d > 1e-5)
    result["most_moved_m"] = max(moved)
    ok = result["bones"] == 25 and result["armatures"] == 1 and result["moved"] > 50 and result["most_moved_m"] > 0.01
except Exception as e:  # noqa: BLE001 - any failure is the test's answer
    result["error"] = str(e)
finish("blender_import", result, ok)
