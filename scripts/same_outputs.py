#!/usr/bin/env python3
"""Compare two snapshots of every command's outputs (scripts/snapshot_outputs.sh): the proof
that a refactor left behaviour unchanged (issue 36).

    python3 scripts/same_outputs.py [--pixels] <before> <after>

Every file must be in both and byte-identical, except what a clock writes: in JSON files the
values of timing keys (total_seconds, seconds, *_seconds, timings_ms, *_ms); in report.html the
cells of the run's timing table ("The run"), the refinement table's fit times and "N ms"; in the commands' printed lines, "N ms";
the manifest's digests of the JSON and HTML files follow.
With --pixels (for a change of the PNG encoder's settings), PNG images are compared by their
decoded pixels instead of their bytes: the .png files, the images report.html embeds and the
texture a .glb carries (its other buffer views byte by byte, its JSON but for the buffer
layout); the manifest's digests of .png, .glb and .html files are then left out (it needs
Pillow: Debian's python3-pil).
Prints each difference, one line each; exits 1 when there is any.
"""
import base64
import io
import json
import os
import re
import struct
import sys

PIXELS = False  # --pixels: PNGs compared by their decoded pixels

TIMING = re.compile(r"(^seconds$|_seconds$|_ms$|^timings_ms$)")


def strip_json(o):
    if isinstance(o, dict):
        return {k: (None if TIMING.search(k) else strip_json(v)) for k, v in o.items()}
    if isinstance(o, list):
        return [strip_json(v) for v in o]
    return o


def strip_html(text):
    text = re.sub(r"[0-9]+ ms\b", "# ms", text)
    i = text.find("<h2>The run</h2>")
    if i >= 0:
        j = text.find("</table>", i)
        text = text[:i] + re.sub(r"<td>[0-9.]+</td>", "<td>#</td>", text[i:j]) + text[j:]
    # The refinement's table: its last column is each fit's time.
    i = text.find("<h2>Refinement to ")
    if i >= 0:
        j = text.find("</table>", i)
        text = text[:i] + re.sub(r"<td>[0-9.]+</td>(\s*</tr>)", r"<td>#</td>\1", text[i:j]) + text[j:]
    return text


def pixels(png):
    """A PNG's size, mode and decoded pixels (bytes)."""
    from PIL import Image  # only for --pixels
    im = Image.open(io.BytesIO(png))
    im.load()
    return (im.size, im.mode, im.tobytes())


def html_images(text):
    """report.html's embedded PNGs decoded, and the text with each replaced by a mark."""
    found = []

    def take(m):
        found.append(pixels(base64.b64decode(m.group(1))))
        return "data:image/png;base64,#"
    return re.sub(r"data:image/png;base64,([A-Za-z0-9+/=]+)", take, text), found


def glb_parts(data):
    """A .glb's JSON (buffer layout left out), its images decoded and its other views' bytes."""
    n_json, _ = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + n_json])
    at = 20 + n_json
    n_bin, _ = struct.unpack_from("<II", data, at)
    binary = data[at + 8:at + 8 + n_bin]
    views = doc.get("bufferViews", [])
    image_views = {im["bufferView"] for im in doc.get("images", []) if "bufferView" in im}
    parts = []
    for k, v in enumerate(views):
        b = binary[v.get("byteOffset", 0):v.get("byteOffset", 0) + v["byteLength"]]
        parts.append(pixels(b) if k in image_views else b)
    for k in image_views:
        views[k].pop("byteLength", None)
    for v in views:
        v.pop("byteOffset", None)
    for b in doc.get("buffers", []):
        b.pop("byteLength", None)
    return doc, parts


def strip_text(text):
    return re.sub(r"[0-9]+ ms\b", "# ms", text)


def same(a, b, name):
    if name == ".handskin-manifest.json":   # digests of files with timings in them
        ja, jb = json.load(open(a)), json.load(open(b))
        for j in (ja, jb):
            for path, entry in j.get("files", {}).items():
                if path.endswith((".json", ".html") + ((".png", ".glb") if PIXELS else ())):
                    entry.pop("sha256", None), entry.pop("size", None)
        return ja == jb
    da, db = open(a, "rb").read(), open(b, "rb").read()
    if da == db:
        return True
    if name.endswith(".json"):
        return strip_json(json.loads(da)) == strip_json(json.loads(db))
    if PIXELS and name.endswith(".png"):
        return pixels(da) == pixels(db)
    if PIXELS and name.endswith(".glb"):
        return glb_parts(da) == glb_parts(db)
    if name.endswith(".html"):
        ta, tb = da.decode(), db.decode()
        if PIXELS:
            (ta, ia), (tb, ib) = html_images(ta), html_images(tb)
            if ia != ib:
                return False
        return strip_html(ta) == strip_html(tb)
    if name.endswith(".txt"):
        return strip_text(da.decode()) == strip_text(db.decode())
    return False


def files(root):
    out = set()
    for d, _, fs in os.walk(root):
        for f in fs:
            out.add(os.path.relpath(os.path.join(d, f), root))
    return out


def main():
    global PIXELS
    args = sys.argv[1:]
    if args and args[0] == "--pixels":
        PIXELS, args = True, args[1:]
    if len(args) != 2:
        print("usage: same_outputs.py [--pixels] BEFORE AFTER", file=sys.stderr)
        return 2
    a, b = args
    fa, fb = files(a), files(b)
    diffs = [f"only in {a}: {f}" for f in sorted(fa - fb)] + [f"only in {b}: {f}" for f in sorted(fb - fa)]
    for f in sorted(fa & fb):
        if not same(os.path.join(a, f), os.path.join(b, f), os.path.basename(f)):
            diffs.append(f"differs: {f}")
    for d in diffs:
        print(d)
    print(f"{len(fa & fb)} files compared, {len(diffs)} differences")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
