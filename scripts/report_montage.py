#!/usr/bin/env python3
"""A montage of the pictures in a report.html (the posed skins of `run`'s report, for docs).

    python3 scripts/report_montage.py out/default/report.html docs/img/rigging_postures.png \
        --from 4 --count 6 --columns 3

Takes the report's embedded PNGs (8-bit RGB or RGBA, as handskin writes them) in page order,
from the --from-th (0-based), and lays --count of them out in a grid, row by row. Standard
library only (zlib): nothing to install.
"""
import argparse
import base64
import re
import struct
import sys
import zlib


def read_png(data):
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                raise ValueError("only 8-bit RGB/RGBA non-interlaced PNGs")
            bpp = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, stride = zlib.decompress(idat), w * bpp
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line[k] for k in range(stride) if bpp == 3 or k % 4 != 3))
        prev = line
    return w, h, rows


def write_png(path, w, h, rows):
    raw = b"".join(b"\x00" + r for r in rows)
    chunk = lambda k, b: struct.pack(">I", len(b)) + k + b + struct.pack(">I", zlib.crc32(k + b) & 0xffffffff)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("report")
    ap.add_argument("out")
    ap.add_argument("--from", dest="first", type=int, default=0)
    ap.add_argument("--count", type=int, default=6)
    ap.add_argument("--columns", type=int, default=3)
    a = ap.parse_args()
    html = open(a.report, encoding="utf-8").read()
    found = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", html)
    pics = [read_png(base64.b64decode(s)) for s in found[a.first:a.first + a.count]]
    if len(pics) < a.count:
        sys.exit(f"error: {a.report}: {len(found)} pictures, need {a.first + a.count}")
    w, h = pics[0][0], pics[0][1]
    if any(p[0] != w or p[1] != h for p in pics):
        sys.exit(f"error: {a.report}: the pictures differ in size")
    rows_n = (len(pics) + a.columns - 1) // a.columns
    blank = b"\xff" * (3 * w)
    out = []
    for r in range(rows_n):
        for y in range(h):
            out.append(b"".join(pics[r * a.columns + c][2][y] if r * a.columns + c < len(pics) else blank
                                for c in range(a.columns)))
    write_png(a.out, w * a.columns, h * rows_n, out)
    print(f"{a.out}: {len(pics)} pictures, {w * a.columns} x {h * rows_n}")


if __name__ == "__main__":
    main()
