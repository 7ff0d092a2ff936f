"""A real client on handskin animate's output: Blender imports the glb (its glTF importer),
finds the armature's action with keyframes, and sees the skin move between the first and the
last frame of the animation.

    blender --background --factory-startup --python scripts/blender_animation.py -- anim.glb

Prints one JSON line of figures; exits 0 when every check holds, 1 otherwise.
"""
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

    def at_frame(frame):
        bpy.context.scene.frame_set(int(frame))
        return world_vertices(mesh)

    a, b = at_frame(first), at_frame(last)
    moved = [(p - q).length for p, q in zip(a, b)]
    result["moved"] = sum(1 for d in moved if d > 1e-4)
    result["most_moved_m"] = max(moved)
    ok = (result["bones"] == 25 and result["fcurves"] > 0 and result["keyframes_per_curve"] >= 2
          and result["moved"] > 50 and result["most_moved_m"] > 0.01)
except Exception as e:  # noqa: BLE001 - any failure is the test's answer
    result["error"] = str(e)
finish("blender_animation", result, ok)
