"""A real client on skin.obj and an STL: Blender imports `run`'s skin.obj with its material
(skin.mtl, whose map is texture.png) and finds the skin's vertices and faces, a UV layer and
the texture image loaded at its size; and imports an STL (from `convert`) with the same faces.

    blender --background --factory-startup --python scripts/blender_obj.py -- skin.obj skin.stl VERTICES FACES TEXTURE_SIZE

Prints one JSON line of figures; exits 0 when every check holds, 1 otherwise.
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_glb import finish  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
obj, stl, vertices, faces, size = args[0], args[1], int(args[2]), int(args[3]), int(args[4])
result = {"blender": bpy.app.version_string}
ok = False
try:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=obj)
    mesh = [o for o in bpy.context.scene.objects if o.type == "MESH"][0]
    me = mesh.data
    result["obj_vertices"] = len(me.vertices)
    result["obj_faces"] = len(me.polygons)
    result["uv_layers"] = len(me.uv_layers)
    images = []
    for mat in me.materials:
        if mat and mat.use_nodes:
            for node in mat.node_tree.nodes:
                if node.type == "TEX_IMAGE" and node.image:
                    images.append(node.image)
    result["images"] = [(os.path.basename(i.filepath), list(i.size)) for i in images]
    uv_ok = len(me.uv_layers) == 1
    if uv_ok:  # every corner's coordinate inside the image
        uvs = me.uv_layers[0].data
        result["uv_range"] = [min(min(d.uv) for d in uvs), max(max(d.uv) for d in uvs)]
        uv_ok = result["uv_range"][0] >= 0 and result["uv_range"][1] <= 1
    image_ok = (len(images) == 1 and os.path.basename(images[0].filepath) == "texture.png"
                and list(images[0].size) == [size, size])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_mesh.stl(filepath=stl)
    st = [o for o in bpy.context.scene.objects if o.type == "MESH"][0].data
    result["stl_faces"] = len(st.polygons)
    ok = (result["obj_vertices"] == vertices and result["obj_faces"] == faces and uv_ok and image_ok
          and result["stl_faces"] == faces)
except Exception as e:  # reported as a failed check
    result["error"] = repr(e)
finish("blender_obj", result, ok)
