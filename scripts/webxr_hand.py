#!/usr/bin/env python3
"""A hand handskin did not make: the WebXR Input Profiles' generic hand (MIT, Amazon 2019;
npm @webxr-input-profiles/assets, profiles/generic-hand/{left,right}.glb) as a replica mesh
and its rig, for `handskin synth scan --mesh ... --rig ...`.

The glTF holds one skinned mesh in its bind pose (metres, closed: a ~22 mm forearm stub
beyond the wrist joint) and the 25 WebXR hand joints, whose names are the rig's
(../shared/formats/hand-rig.md). This script welds the mesh's seams (normals and texture
coordinates split its vertices), checks it closed and two-manifold, optionally smooths it by
Loop subdivision (the asset is low-poly, 2314 triangles with 3-5 mm edges; a plaster cast is
smooth), scales it to millimetres and writes hand.ply and hand_rig.json (joints from the
skin's inverse bind matrices, palm_normal out of the back of the hand). A glTF with no skin
(profiles/generic-fixed-hand: one posture, no joints) gives hand.ply alone, for `handskin run
--cloud` with the skeleton placed automatically.

    python3 scripts/webxr_hand.py --glb right.glb --side right --out DIR [--subdivide 2]
"""
import argparse
import json
import os
import struct
import sys

import numpy as np

JOINTS = ["wrist"] + [f"thumb-{j}" for j in ("metacarpal", "phalanx-proximal", "phalanx-distal", "tip")] + [
    f"{f}-finger-{j}" for f in ("index", "middle", "ring", "pinky")
    for j in ("metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip")]


def read_glb(path):
    b = open(path, "rb").read()
    if b[:4] != b"glTF":
        sys.exit(f"{path}: not a binary glTF")
    jl = struct.unpack("<I", b[12:16])[0]
    js = json.loads(b[20:20 + jl])
    off = 20 + jl
    bl = struct.unpack("<I", b[off:off + 4])[0]
    blob = b[off + 8:off + 8 + bl]

    def accessor(i):
        a = js["accessors"][i]
        bv = js["bufferViews"][a["bufferView"]]
        ct = {5126: np.float32, 5123: np.uint16, 5125: np.uint32, 5121: np.uint8}[a["componentType"]]
        n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a["type"]]
        arr = np.frombuffer(blob, dtype=ct, count=a["count"] * n, offset=bv.get("byteOffset", 0) + a.get("byteOffset", 0))
        return arr.reshape(a["count"], n) if n > 1 else arr

    return js, accessor


def weld(V, F):
    """Vertices at one position (to 1e-7 m) become one; faces re-indexed. Also returns, per
    welded vertex, the index of its first original vertex (for its skin weights)."""
    keys = np.round(V / 1e-7).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return V[first], inverse.reshape(-1)[F], first


def edges_of(F):
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    return np.unique(E, axis=0, return_inverse=True, return_counts=True)


def check_closed(F, what):
    _, _, counts = edges_of(F)
    if (counts != 2).any():
        sys.exit(f"{what}: {int((counts == 1).sum())} boundary and {int((counts > 2).sum())} non-manifold edges; "
                 "the replica must be a closed surface")


def loop_subdivide(V, F):
    """One round of Loop subdivision of a closed triangle mesh."""
    E, inv, _ = edges_of(F)
    nv, ne = len(V), len(E)
    inv = inv.reshape(-1)
    # The two vertices opposite each edge: each edge of a closed mesh occurs twice among the
    # faces' edges (0,1), (1,2), (2,0), whose opposite corners are 2, 0, 1.
    opposite = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    opp = opposite[np.argsort(inv, kind="stable")].reshape(ne, 2)
    Vn = np.empty((nv + ne, 3))
    Vn[nv:] = 0.375 * (V[E[:, 0]] + V[E[:, 1]]) + 0.125 * (V[opp[:, 0]] + V[opp[:, 1]])
    nb = np.zeros((nv, 3))
    deg = np.zeros(nv)
    np.add.at(nb, E[:, 0], V[E[:, 1]])
    np.add.at(nb, E[:, 1], V[E[:, 0]])
    np.add.at(deg, E[:, 0], 1)
    np.add.at(deg, E[:, 1], 1)
    beta = (0.625 - (0.375 + 0.25 * np.cos(2 * np.pi / deg)) ** 2) / deg
    Vn[:nv] = (1 - deg * beta)[:, None] * V + beta[:, None] * nb
    m = nv + inv.reshape(3, -1).T  # per face: the new vertices of edges (0,1), (1,2), (2,0)
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
    Fn = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1), np.stack([ca, bc, c], 1),
                         np.stack([ab, bc, ca], 1)])
    return Vn, Fn


def node_world(js):
    nodes = js["nodes"]
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}

    def local(n):
        if "matrix" in n:
            return np.array(n["matrix"], dtype=float).reshape(4, 4).T
        M = np.eye(4)
        x, y, z, w = n.get("rotation", [0, 0, 0, 1])
        M[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        M[:3, :3] *= np.array(n.get("scale", [1, 1, 1]))[None, :]
        M[:3, 3] = n.get("translation", [0, 0, 0])
        return M

    def world(i):
        M = local(nodes[i])
        while i in parent:
            i = parent[i]
            M = local(nodes[i]) @ M
        return M

    return world


# A rig DOF's joint (../shared/formats/hand-rig.md names) -> the WebXR joint it turns at.
# Flexion turns the bone and every bone beyond it about the
# joint's own flexion axis: WebXR joint frames have +Y out of the nail and -Z along the bone,
# so -X is the axis about which positive angles curl the digit toward its pad (for the
# fingers that is bone x palm-normal; the thumb, turned ~75 deg about its axis, curls
# across the palm).
DIGITS = {"thumb": "thumb", "index": "index-finger", "middle": "middle-finger", "ring": "ring-finger",
          "little": "pinky-finger"}
FLEX_AT = {"cmc": "metacarpal", "mcp": "phalanx-proximal", "pip": "phalanx-intermediate", "dip": "phalanx-distal"}
THUMB_FLEX_AT = {"cmc": "metacarpal", "mcp": "phalanx-proximal", "ip": "phalanx-distal"}
CHAINS = {d: [f"{p}-{j}" for j in (("metacarpal", "phalanx-proximal", "phalanx-distal", "tip") if d == "thumb" else
                                   ("metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"))]
          for d, p in DIGITS.items()}


def rotation(axis, deg):
    a = axis / np.linalg.norm(axis)
    t = np.radians(deg)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


def pose(J, frames, sets):
    """Rigid transforms (R, t), one per WebXR joint, for flexion angles {"index.pip.flex": deg};
    `frames`: each joint's rest orientation (3 x 3, columns its local axes).
    A joint's transform moves its bone (the one that starts there) and is the product of the
    flexions at it and at every joint before it on its digit, applied from the tip inward."""
    T = {name: (np.eye(3), np.zeros(3)) for name in J}
    for key, deg in sets.items():
        parts = key.split(".")
        table = THUMB_FLEX_AT if parts[0] == "thumb" else FLEX_AT
        if len(parts) != 3 or parts[0] not in DIGITS or parts[1] not in table or parts[2] != "flex":
            sys.exit(f"--set {key}: expected DIGIT.JOINT.flex with DIGIT one of {', '.join(DIGITS)} and JOINT one of "
                     f"{', '.join(FLEX_AT)} (thumb: {', '.join(THUMB_FLEX_AT)})")
    for digit, chain in CHAINS.items():
        table = THUMB_FLEX_AT if digit == "thumb" else FLEX_AT
        # From the tip inward, so each rotation acts in the rest frame on what lies beyond it.
        for joint in reversed(list(table)):
            deg = sets.get(f"{digit}.{joint}.flex", 0.0)
            if deg == 0.0:
                continue
            at = f"{DIGITS[digit]}-{table[joint]}"
            R = rotation(-frames[at][:, 0], deg)
            c = J[at]
            for name in chain[chain.index(at):]:
                R0, t0 = T[name]
                T[name] = (R @ R0, R @ (t0 - c) + c)
    return T


def write_ply(path, V, F, subdivide):
    """The mesh as an ASCII PLY in mm, its faces turned outward (a positive enclosed volume)."""
    vol = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6
    if vol < 0:
        F = F[:, [0, 2, 1]]
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(f"ply\nformat ascii 1.0\ncomment WebXR Input Profiles generic hand (MIT, Amazon 2019), "
                f"{subdivide} Loop subdivisions, mm\nelement vertex {len(V)}\nproperty double x\n"
                f"property double y\nproperty double z\nelement face {len(F)}\nproperty list uchar int vertex_indices\n"
                "end_header\n")
        for v in V:
            f.write(f"{v[0]:.6f} {v[1]:.6f} {v[2]:.6f}\n")
        for t in F:
            f.write(f"3 {t[0]} {t[1]} {t[2]}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--glb", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--side", choices=("right", "left"),
                    help="which hand the asset is (its joints alone cannot tell); not needed for one without a skin")
    ap.add_argument("--subdivide", type=int, default=2, help="Loop subdivision rounds (0: the asset's facets)")
    ap.add_argument("--set", action="append", default=[], metavar="DOF=DEG",
                    help="pose the hand through its own skin weights before subdividing: flexion in degrees, "
                         "e.g. index.pip.flex=30 (DIGIT: thumb index middle ring little; JOINT: cmc mcp pip dip, "
                         "thumb cmc mcp ip); the rig is posed with it")
    a = ap.parse_args()
    sets = {}
    for kv in a.set:
        k, eq, v = kv.partition("=")
        try:
            sets[k] = float(v)
        except ValueError:
            sets[k] = None
        if not eq or sets[k] is None or not -90 <= sets[k] <= 120:
            sys.exit(f"--set {kv}: expected DOF=DEG with DEG a number of degrees in [-90, 120]")
    js, accessor = read_glb(a.glb)
    nodes = js["nodes"]
    mesh_node = next(i for i, n in enumerate(nodes) if "mesh" in n)
    prim = js["meshes"][nodes[mesh_node]["mesh"]]["primitives"][0]
    V = accessor(prim["attributes"]["POSITION"]).astype(float)
    F = accessor(prim["indices"]).astype(np.int64).reshape(-1, 3)
    world = node_world(js)
    M = world(mesh_node)
    V = V @ M[:3, :3].T + M[:3, 3]
    V, F, first = weld(V, F)
    check_closed(F, a.glb)
    V *= 1000.0  # metres -> mm
    if not js.get("skins"):
        # A hand with no skeleton (the profiles' "generic-fixed-hand": one posture, no joints):
        # the mesh alone, for `run --cloud` with the skeleton placed automatically.
        if sets:
            sys.exit(f"{a.glb}: no skin (no joints) to pose with --set")
        for _ in range(a.subdivide):
            V, F = loop_subdivide(V, F)
        write_ply(os.path.join(a.out, "hand.ply"), V, F, a.subdivide)
        print(f"{len(V)} vertices, {len(F)} triangles, no rig (the asset has no joints)")
        return
    if a.side is None:
        sys.exit(f"{a.glb}: give --side right or --side left (the asset's joints alone cannot tell)")
    skin = js["skins"][0]
    ibm = accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    joints = {}
    skin_names = [nodes[ni].get("name") for ni in skin["joints"]]
    for k, name in enumerate(skin_names):
        if name in JOINTS:
            joints[name] = (np.linalg.inv(ibm[k])[:3, 3] * 1000.0).tolist()
    missing = [j for j in JOINTS if j not in joints]
    if missing:
        sys.exit(f"{a.glb}: joints missing: {', '.join(missing)}")
    J = {k: np.array(v) for k, v in joints.items()}
    # From the rest pose: the hand frame does not move with the fingers.
    across = J["pinky-finger-phalanx-proximal"] - J["index-finger-phalanx-proximal"]
    along = J["middle-finger-tip"] - J["wrist"]
    # For a right hand (index to little finger) x (wrist to tips) points out of the back; a
    # left hand is the mirror image, so the same product points out of its palm. Joint
    # positions alone cannot tell the two apart: the side is the asset's (its file name).
    back = np.cross(across, along) * (1 if a.side == "right" else -1)
    # The thumb confirms it: its metacarpal's base lies on the palm's side of the index's.
    # (The fingers' bend does not: this asset's fingers are a few degrees hyperextended.)
    if np.dot(J["thumb-metacarpal"] - J["index-finger-metacarpal"], back) > 0:
        sys.exit(f"{a.glb}: the thumb's base lies on the back of the hand for --side {a.side}; is it the other side's?")
    back /= np.linalg.norm(back)
    if sets:
        # Linear blend skinning with the asset's own weights (its bind pose is the rest pose),
        # on the asset's facets, before the subdivision smooths them.
        frames = {}
        for k, name in enumerate(skin_names):
            Rb = np.linalg.inv(ibm[k])[:3, :3]
            frames[name] = Rb / np.linalg.norm(Rb, axis=0)
        T = pose(J, frames, sets)
        idx = accessor(prim["attributes"]["JOINTS_0"]).astype(np.int64)[first]
        wts = accessor(prim["attributes"]["WEIGHTS_0"]).astype(float)[first]
        wts /= wts.sum(1, keepdims=True)
        P = np.zeros_like(V)
        for k, name in enumerate(skin_names):
            R, t = T.get(name, (np.eye(3), np.zeros(3)))
            w = (wts * (idx == k)).sum(1)
            P += w[:, None] * (V @ R.T + t)
        V = P
        joints = {name: (T[name][0] @ np.array(p) + T[name][1]).tolist() for name, p in joints.items()}
    for _ in range(a.subdivide):
        V, F = loop_subdivide(V, F)
    write_ply(os.path.join(a.out, "hand.ply"), V, F, a.subdivide)
    rig = {"format": "hand-rig/1", "units": "mm", "frame": "hand", "joints": joints, "palm_normal": back.tolist()}
    with open(os.path.join(a.out, "hand_rig.json"), "w") as f:
        json.dump(rig, f, indent=2, sort_keys=True)
    print(f"{len(V)} vertices, {len(F)} triangles, {a.side} hand, "
          f"wrist to middle tip joint {np.linalg.norm(along):.1f} mm")


if __name__ == "__main__":
    main()
