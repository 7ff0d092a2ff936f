"""What the Blender client checks (blender_import.py, blender_animation.py) share: Blender's
glTF importer made to run on Debian, the glb imported into an empty scene, the skinned mesh's
evaluated vertices, and the one JSON line and exit code each check ends with."""
import json
import os
import shutil
import sys
import tempfile

import bpy
import numpy

# Debian 12's Blender 3.4 glTF importer still uses numpy.bool, which NumPy 1.24 (Debian's)
# removed; the alias is the builtin bool, as NumPy's deprecation note says.
if "bool" not in vars(numpy):
    numpy.bool = bool


def glb_argument():
    """The glb given after `--` on Blender's command line."""
    return sys.argv[sys.argv.index("--") + 1]


def import_glb(glb, result):
    """The glb imported into an empty scene: its armature and mesh (counts into `result`)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=glb)
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    result["armatures"], result["meshes"] = len(arms), len(meshes)
    return arms[0], meshes[0]


def world_vertices(mesh):
    """The mesh's vertices as the armature deforms them now, in world coordinates."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = mesh.evaluated_get(dg)
    m = ev.to_mesh()
    out = [ev.matrix_world @ v.co for v in m.vertices]
    ev.to_mesh_clear()
    return out


def finish(name, result, ok):
    """One JSON line of figures; exit 0 when every check held. Blender's own exit is skipped (it
    would exit 0 whatever the check found), so its session folder (/tmp/blender_XXXXXX, which
    its exit removes) is removed here: only that folder, the one this Blender made."""
    print(name + ": " + json.dumps(result), flush=True)
    sys.stdout.flush()
    session = os.path.normpath(bpy.app.tempdir or "")
    if (os.path.basename(session).startswith("blender_")
            and os.path.dirname(session) == os.path.normpath(tempfile.gettempdir())):
        shutil.rmtree(session, ignore_errors=True)
    os._exit(0 if ok else 1)
