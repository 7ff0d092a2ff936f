#!/usr/bin/env python3
"""Cross-sections of skins against the true skin and the cloud, side by side, to a PNG.

    python3 scripts/section_plot.py --truth truth_skin.ply --cloud merged.ply \\
        --skin before=a/skin.ply --skin after=b/skin.ply \\
        --section x=91:85,125,18,52 --section x=171:100,160,15,70 --out sections.png

Each --section is <axis>=<value>:<u0>,<u1>,<v0>,<v1>: the plane axis = value (palm frame, mm)
and the window over the other two axes in order (x: y then z; y: x then z; z: x then y).
One row per section, one column per skin: the true skin green, that skin red, the cloud's
points within 0.3 mm of the plane blue, a 5 mm grid grey. Binary little-endian PLY only
(what handskin and synth write). Needs numpy (Debian's python3-numpy) and nothing else.
"""
import argparse
import os
import struct
import sys
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ply_util  # noqa: E402

SCALE = 16  # pixels per mm


def read_ply(path):
    """Vertices (n x 3) and triangles (m x 3, or None) of a binary little-endian PLY."""
    verts, faces = ply_util.read_ply(path, "section_plot")
    return ply_util.xyz(verts), faces


def section_segments(verts, faces, axis, value):
    """The segments where the plane axis = value cuts the triangles."""
    d = verts[faces][:, :, axis] - value
    cut = ~(np.all(d > 0, axis=1) | np.all(d < 0, axis=1))
    segs = []
    for tri, dd in zip(faces[cut], d[cut]):
        pts = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            if (dd[i] < 0) != (dd[j] < 0):
                t = dd[i] / (dd[i] - dd[j])
                pts.append(verts[tri[i]] + t * (verts[tri[j]] - verts[tri[i]]))
        if len(pts) == 2:
            segs.append(pts)
    return segs


def panel(truth, cloud, skin, axis, value, window):
    u0, u1, v0, v1 = window
    ax = [i for i in range(3) if i != axis]
    w, h = int((u1 - u0) * SCALE), int((v1 - v0) * SCALE)
    img = np.full((h, w, 3), 255, np.uint8)
    for g in np.arange(np.ceil(u0 / 5) * 5, u1, 5):
        img[:, min(w - 1, int((g - u0) * SCALE))] = 215
    for g in np.arange(np.ceil(v0 / 5) * 5, v1, 5):
        img[min(h - 1, int((v1 - g) * SCALE))] = 215

    def put(p, colour, r=0):
        u, v = int((p[ax[0]] - u0) * SCALE), int((v1 - p[ax[1]]) * SCALE)
        img[max(0, v - r):max(0, min(h, v + r + 1)), max(0, u - r):max(0, min(w, u + r + 1))] = colour

    for p in cloud[np.abs(cloud[:, axis] - value) < 0.3]:
        put(p, (70, 90, 255), 1)
    for (verts, faces), colour in ((truth, (0, 150, 0)), (skin, (220, 0, 0))):
        for a, b in section_segments(verts, faces, axis, value):
            for t in np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) * SCALE * 1.5))):
                put(a + t * (b - a), colour)
    return img


def write_png(path, img):
    h, w, _ = img.shape
    raw = b"".join(b"\x00" + img[r].tobytes() for r in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--cloud", required=True)
    ap.add_argument("--skin", action="append", required=True, help="label=skin.ply (one column each)")
    ap.add_argument("--section", action="append", required=True, help="axis=value:u0,u1,v0,v1")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    truth = read_ply(a.truth)
    cloud = read_ply(a.cloud)[0]
    skins = []
    for s in a.skin:
        label, _, path = s.partition("=")
        if not path:
            ap.error(f"--skin {s}: expected label=path")
        v, f = read_ply(path)
        if f is None:
            ap.error(f"--skin {s}: no faces")
        skins.append((v, f))
    rows = []
    for s in a.section:
        try:
            plane, _, win = s.partition(":")
            axis_name, _, value = plane.partition("=")
            axis = "xyz".index(axis_name)
            window = [float(x) for x in win.split(",")]
            if len(window) != 4 or window[0] >= window[1] or window[2] >= window[3]:
                raise ValueError
        except ValueError:
            ap.error(f"--section {s}: expected axis=value:u0,u1,v0,v1 with u0 < u1, v0 < v1")
        panels = [panel(truth, cloud, skin, axis, float(value), window) for skin in skins]
        gap = np.full((panels[0].shape[0], 8, 3), 255, np.uint8)
        row = panels[0]
        for p in panels[1:]:
            row = np.concatenate([row, gap, p], axis=1)
        rows.append(row)
    width = max(r.shape[1] for r in rows)
    rows = [np.concatenate([r, np.full((r.shape[0], width - r.shape[1], 3), 255, np.uint8)], axis=1) for r in rows]
    out = rows[0]
    for r in rows[1:]:
        out = np.concatenate([out, np.full((8, width, 3), 255, np.uint8), r], axis=0)
    write_png(a.out, out)
    print(f"section_plot: {a.out} ({out.shape[1]} x {out.shape[0]})")


if __name__ == "__main__":
    main()
