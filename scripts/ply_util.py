"""Reading the binary little-endian PLY files handskin and synth write, for the study and
plot scripts (numpy only)."""
import sys

import numpy as np

TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1", "char": "i1",
         "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4", "short": "<i2", "ushort": "<u2"}


def read_ply(path, who):
    """(vertex records: a numpy record array with the file's vertex properties, x y z and any
    others such as the merged cloud's label; triangles m x 3, or None) of a binary
    little-endian PLY. Anything else ends the script with one line naming `who` and the file."""
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            sys.exit(f"{who}: {path}: not a PLY file")
        elements = []
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"{who}: {path}: header has no end_header")
            words = line.decode("ascii", "replace").split()
            if words[:1] == ["format"] and words[1] != "binary_little_endian":
                sys.exit(f"{who}: {path}: format {words[1]}, only binary_little_endian is read")
            if words[:1] == ["element"]:
                elements.append((words[1], int(words[2]), []))
            elif words[:1] == ["property"]:
                elements[-1][2].append(words[1:])
            elif words[:1] == ["end_header"]:
                break
        verts, faces = None, None
        for name, count, props in elements:
            if props and props[0][0] == "list":
                dt = np.dtype([("n", TYPES[props[0][1]]), ("v", TYPES[props[0][2]], (3,))] +
                              [(p[1], TYPES[p[0]]) for p in props[1:]])
                a = np.frombuffer(f.read(count * dt.itemsize), dtype=dt, count=count)
                if name == "face":
                    if np.any(a["n"] != 3):
                        sys.exit(f"{who}: {path}: faces must be triangles")
                    faces = a["v"].astype(np.int64)
            else:
                dt = np.dtype([(p[1], TYPES[p[0]]) for p in props])
                a = np.frombuffer(f.read(count * dt.itemsize), dtype=dt, count=count)
                if name == "vertex":
                    verts = a
    if verts is None:
        sys.exit(f"{who}: {path}: no vertices")
    return verts, faces


def xyz(verts):
    """The vertex records' positions, n x 3 (float64)."""
    return np.stack([verts["x"], verts["y"], verts["z"]], 1).astype(float)
