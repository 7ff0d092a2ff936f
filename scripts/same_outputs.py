#!/usr/bin/env python3
"""Compare two snapshots of every command's outputs (scripts/snapshot_outputs.sh): the proof
that a refactor left behaviour unchanged (issue 36).

    python3 scripts/same_outputs.py <before> <after>

Every file must be in both and byte-identical, except what a clock writes: in JSON files the
values of timing keys (total_seconds, seconds, *_seconds, timings_ms, *_ms); in report.html the
cells of the run's timing table ("The run"), the refinement table's fit times and "N ms"; in the commands' printed lines, "N ms";
the manifest's digests of the JSON and HTML files follow.
Prints each difference, one line each; exits 1 when there is any.
"""
import json
import os
import re
import sys

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


def strip_text(text):
    return re.sub(r"[0-9]+ ms\b", "# ms", text)


def same(a, b, name):
    if name == ".handskin-manifest.json":   # digests of files with timings in them
        ja, jb = json.load(open(a)), json.load(open(b))
        for j in (ja, jb):
            for path, entry in j.get("files", {}).items():
                if path.endswith((".json", ".html")):
                    entry.pop("sha256", None), entry.pop("size", None)
        return ja == jb
    da, db = open(a, "rb").read(), open(b, "rb").read()
    if da == db:
        return True
    if name.endswith(".json"):
        return strip_json(json.loads(da)) == strip_json(json.loads(db))
    if name.endswith(".html"):
        return strip_html(da.decode()) == strip_html(db.decode())
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
    a, b = sys.argv[1], sys.argv[2]
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
