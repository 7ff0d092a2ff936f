#!/usr/bin/env python3
"""What the patch layout can reach at all (issue 13's accuracy bars; docs/patches.md).

    python3 scripts/patch_bound.py [--bin build/handskin] [--work /tmp/patch-study]
                                   [--hands fixture,H01,H05,H07] [--counts 96,392]

For each hand (the default fixture, and hands of the family as scripts/patch_study.py makes
them), the merged cloud's every point is moved onto the true skin (its closest point on
truth_skin.ply: no noise, no registration error, the scans' coverage kept), and the patches
are fitted to those exact points three ways: as `run` does (C1 across the borders), and with
G0 alone (`patches.c1_weight` 0: neighbours share their borders, nothing else asked — the
least-squares fit with the most freedom the layout gives), at each count. The figures are
the surface's distance to the true skin (mean, p95) and the exact data's distance to the
surface. Where even the G0-only fit to exact data stays above a bar, no fit on that layout
reaches it: the bar asks for a finer layout, not a better fit.

Needs numpy and scipy (Debian's python3-numpy, python3-scipy; scripts/setup.sh installs both).
"""
import argparse
import json
import os
import shutil
import sys

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from patch_study import make_pair  # noqa: E402
from ply_util import read_ply, xyz  # noqa: E402
from study_util import run as sh  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def closest_on_triangles(p, a, b, c):
    """Closest points on triangles (a, b, c) to points p, row by row (Ericson, Real-Time
    Collision Detection §5.1.5, vectorised)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp, cp = p - b, p - c
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    safe = lambda x: np.where(x == 0, 1e-300, x)  # noqa: E731
    den = safe(va + vb + vc)
    q = a + ab * (vb / den)[:, None] + ac * (vc / den)[:, None]
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    q[m] = (a + ab * (d1 / safe(d1 - d3))[:, None])[m]
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    q[m] = (a + ac * (d2 / safe(d2 - d6))[:, None])[m]
    m = (va <= 0) & (d4 >= d3) & (d5 >= d6)
    q[m] = (b + (c - b) * ((d4 - d3) / safe((d4 - d3) + (d5 - d6)))[:, None])[m]
    m = (d1 <= 0) & (d2 <= 0)
    q[m] = a[m]
    m = (d3 >= 0) & (d4 <= d3)
    q[m] = b[m]
    m = (d6 >= 0) & (d5 <= d6)
    q[m] = c[m]
    return q


def exact_cloud(truth_ply, merged_ply, out_ply):
    """merged_ply's points moved to their closest points on truth_ply (its x, y, z and label
    kept), written to out_ply; returns the mean move (the data's own error, mm)."""
    V, F = read_ply(truth_ply, "patch_bound")
    if F is None:
        sys.exit(f"patch_bound: {truth_ply}: no triangles")
    V = xyz(V)
    rec, _ = read_ply(merged_ply, "patch_bound")
    P = xyz(rec)
    # The closest point lies on one of the triangles whose centroids are nearest (the skin's
    # triangles are ~1.6 mm; 16 candidates reach well past the data's 0.3 mm from the skin).
    _, cand = cKDTree(V[F].mean(1)).query(P, k=16)
    best, q_best = np.full(len(P), np.inf), P.copy()
    for j in range(cand.shape[1]):
        f = F[cand[:, j]]
        q = closest_on_triangles(P, V[f[:, 0]], V[f[:, 1]], V[f[:, 2]])
        d = np.linalg.norm(q - P, axis=1)
        m = d < best
        best[m], q_best[m] = d[m], q[m]
    out = np.zeros(len(P), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("label", "<u4")])
    out["x"], out["y"], out["z"], out["label"] = q_best[:, 0], q_best[:, 1], q_best[:, 2], rec["label"]
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(out)}\n"
              "property float x\nproperty float y\nproperty float z\nproperty uint label\nend_header\n")
    with open(out_ply, "wb") as f:
        f.write(header.encode("ascii") + out.tobytes())
    return float(best.mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default="/tmp/patch-study")
    ap.add_argument("--hands", default="fixture,H01,H05,H07")
    ap.add_argument("--counts", default="96,392")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    with open(os.path.join(ROOT, "pipelines", "cubist.json")) as f:
        pipeline = json.load(f)
    pipelines = {}
    for name, c1 in (("C1", None), ("G0", 0)):
        p = json.loads(json.dumps(pipeline))
        if c1 is not None:
            p["patches"]["c1_weight"] = c1
        pipelines[name] = os.path.join(a.work, f"bound-{name}.json")
        with open(pipelines[name], "w") as f:
            json.dump(p, f)
    print("| hand | data's own error (mm) | patches | fit | exact data → surface mean | surface → truth mean / p95 |")
    print("|---|---|---|---|---|---|")
    for h in a.hands.split(","):
        if h == "fixture":
            scan = os.path.join(ROOT, "fixtures", "default")
            reg = os.path.join(a.work, "fixture-out")
            if not os.path.exists(os.path.join(reg, "merged.ply")):
                rc, out = sh([a.bin, "-q", "register", "--back", scan + "/back", "--palm", scan + "/palm", "--out", reg])
                if rc:
                    print(f"| {h} | register: {out.strip().splitlines()[-1]} |")
                    continue
        else:
            scan, reg, error = make_pair(a.bin, a.work, h)
            if error:
                print(f"| {h} | {error} |")
                continue
        exact = os.path.join(a.work, h + "-exact")
        os.makedirs(exact, exist_ok=True)
        own = exact_cloud(os.path.join(scan, "truth_skin.ply"), os.path.join(reg, "merged.ply"),
                          os.path.join(exact, "merged.ply"))
        for count in a.counts.split(","):
            for name, path in pipelines.items():
                o = os.path.join(exact, f"patches-{count}-{name}")
                rc, out = sh([a.bin, "-q", "patches", "--skin-dir", exact, "--rig", scan + "/rig.json", "--truth",
                              scan + "/truth.json", "--count", count, "--pipeline", path, "--out", o])
                if rc:
                    print(f"| {h} | {own:.3f} | {count} | {name} | patches: {out.strip().splitlines()[-1]} |")
                    continue
                r = json.load(open(os.path.join(o, "report.json")))
                ds, t = r["data_to_surface_mm"], r["truth"]["surface_to_truth_mm"]
                n = ds["palm"]["points"] + ds["back"]["points"]
                mean = (ds["palm"]["mean"] * ds["palm"]["points"] + ds["back"]["mean"] * ds["back"]["points"]) / n
                print(f"| {h} | {own:.3f} | {r['patches']} | {name} | {mean:.3f} | {t['mean']:.3f} / {t['p95']:.3f} |",
                      flush=True)
        shutil.rmtree(exact)


if __name__ == "__main__":
    main()
