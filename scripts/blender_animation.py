"""A real client on handskin animate's output: Blender imports the glb (its glTF importer),
finds the armature's action with keyframes, and sees the skin move between the first and the
last frame of the animation.

    blender --background --factory-startup --python scripts/blender_animation.py -- anim.glb

Prints one JSON line of figures; exits 0 when every check holds, 1 otherwise.
"""
import json
import os
import sys

import bpy
import numpy

# Debian 12's Blender 3.4 glTF importer still uses numpy.bool, which NumPy 1.24 removed.
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
    arm, mesh = arms[0], meshes[0]
    result["bones"] = len(arm.data.bones)
    result["actions"] = [a.name for a in bpy.data.actions]
    action = arm.animation_data.action if arm.animation_data else None
    if action is None and bpy.data.actions:  # the importer may leave it in the NLA
        action = bpy.data.actions[0]
        arm.animation_data_create()
        arm.animation_data.action = action
    result["fcurves"] = len(action.fcurves)
    keys = [len(fc.keyframe_points) for fc in action.fcurves]
    result["keyframes_per_curve"] = max(keys) if keys else 0
    first, last = action.frame_range
    result["frame_range"] = [first, last]

    def world_vertices(frame):
        bpy.context.scene.frame_set(int(frame))
        dg = bpy.context.evaluated_depsgraph_get()
        ev = mesh.evaluated_get(dg)
        m = ev.to_mesh()
        out = [ev.matrix_world @ v.co for v in m.vertices]
        ev.to_mesh_clear()
        return out

    a, b = world_vertices(first), world_vertices(last)
    moved = [(p - q).length for p, q in zip(a, b)]
    result["moved"] = sum(1 for d in moved if d > 1e-4)
    result["most_moved_m"] = max(moved)
    ok = (result["bones"] == 25 and result["fcurves"] > 0 and result["keyframes_per_curve"] >= 2
          and result["moved"] > 50 and result["most_moved_m"] > 0.01)
except Exception as e:  # noqa: BLE001 - any failure is the test's answer
    result["error"] = str(e)
print("blender_animation: " + json.dumps(result), flush=True)
sys.stdout.flush()
os._exit(0 if ok else 1)
