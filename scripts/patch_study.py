#!/usr/bin/env python3
"""Patch study (issue 13): the Bézier patches on one scan pair of each hand of the family
(scripts/family_study.py's hands: right and left, 160-215 mm, curled fingers, raised thumbs,
markers 3 mm), with the pair's rig, measured against the truth.

    python3 scripts/patch_study.py [--bin build/handskin] [--work /tmp/patch-study] [--count 96] [--tolerance MM]

Prints a Markdown table and the median and worst figures; pairs already in --work are reused.
With --tolerance (issue 38), each pair is fitted twice, with the default layout and with
--patch-tolerance MM, and the table gives the refined fit's figures, its patch count, whether
every patch held the tolerance, and its fit time against the default's.
"""
import argparse
import json
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from family_study import HANDS, SCAN  # noqa: E402
from study_util import run as sh  # noqa: E402


def make_pair(binary, work, h):
    """One scan pair of family hand h, registered with the marker radius estimated, in
    `work` (reused when there): (scan folder, registration folder, None) or (.., .., the
    failing stage's last line)."""
    hand = os.path.join(work, h)
    d, o = os.path.join(work, h + "-scan"), os.path.join(work, h + "-out")
    if not os.path.exists(os.path.join(hand, "hand.ply")):
        rc, out = sh([binary, "-q", "synth", "hand", "--out", hand, "--no-render"] + HANDS[h])
        if rc:
            return d, o, "synth hand: " + out.strip().splitlines()[-1]
    if not os.path.exists(os.path.join(d, "truth.json")):
        rc, out = sh([binary, "-q", "synth", "scan", "--mesh", hand + "/hand.ply", "--rig", hand + "/hand_rig.json",
                      "--out", d, "--seed", "1", "--marker-radius", "3", "--no-render"] + SCAN.get(h, []))
        if rc:
            return d, o, "synth scan: " + out.strip().splitlines()[-1]
    if not os.path.exists(os.path.join(o, "merged.ply")):
        rc, out = sh([binary, "-q", "register", "--back", d + "/back", "--palm", d + "/palm", "--out", o])
        if rc:
            return d, o, "register: " + out.strip().splitlines()[-1]
    return d, o, None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default="/tmp/patch-study")
    ap.add_argument("--count", default="96")
    ap.add_argument("--tolerance", default="", help="also fit with --patch-tolerance MM")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    rows, figures = [], []
    for h in HANDS:
        d, o, error = make_pair(a.bin, a.work, h)
        if error:
            rows.append([h, error])
            continue
        rc, out = sh([a.bin, "-q", "patches", "--skin-dir", o, "--rig", d + "/rig.json", "--truth", d + "/truth.json",
                      "--count", a.count, "--out", o + "/patches", "--force"])
        if rc:
            rows.append([h, "patches: " + out.strip().splitlines()[-1]])
            continue
        r = json.load(open(o + "/patches/report.json"))
        default_ms = 1000 * r["fit_seconds"]
        if a.tolerance:
            rc, out = sh([a.bin, "-q", "patches", "--skin-dir", o, "--rig", d + "/rig.json", "--truth", d + "/truth.json",
                          "--count", a.count, "--patch-tolerance", a.tolerance, "--out", o + "/patches-tol", "--force"])
            if not os.path.exists(o + "/patches-tol/report.json"):
                rows.append([h, "patches --patch-tolerance: " + out.strip().splitlines()[-1]])
                continue
            r = json.load(open(o + "/patches-tol/report.json"))
        ds, nf, t = r["data_to_surface_mm"], r["table_4_1"]["noise_floor_mm"], r["truth"]
        g1 = r["continuity"]["g1_normal_jump_deg"]
        f = {"palm_mean": ds["palm"]["mean"], "palm_max": ds["palm"]["max"], "back_mean": ds["back"]["mean"],
             "back_max": ds["back"]["max"], "floor": max(nf["palm"], nf["back"]),
             "truth_mean": t["surface_to_truth_mm"]["mean"], "truth_p95": t["surface_to_truth_mm"]["p95"],
             "within": t["truth_to_surface_mm"]["within_1mm"], "g0": r["continuity"]["g0_gap_mm"],
             "g1_med": g1["median"], "g1_p95": g1["p95"], "g1_max": g1["max"], "ms": 1000 * r["fit_seconds"], "rounds": r["correction"]["rounds"],
             "patches": r["patches"], "ratio": 1000 * r["fit_seconds"] / default_ms,
             "held": r.get("refinement", {}).get("held", True)}
        figures.append(f)
        rows.append([h, f'{f["palm_mean"]:.3f} / {f["palm_max"]:.2f}', f'{f["back_mean"]:.3f} / {f["back_max"]:.2f}',
                     f'{nf["palm"]:.3f} / {nf["back"]:.3f}', f'{f["g0"]:.0e}', f'{f["g1_med"]:.3f} / {f["g1_p95"]:.3f} / {f["g1_max"]:.1f}',
                     f'{f["truth_mean"]:.3f} / {f["truth_p95"]:.3f}', f'{100 * f["within"]:.2f} %', str(f["rounds"]),
                     f'{f["ms"]:.0f}'] + ([str(f["patches"]), "yes" if f["held"] else "no", f'{f["ratio"]:.1f} ×']
                                          if a.tolerance else []))
        print(h, "done", file=sys.stderr)
    head = ["hand", "palm: data→surface mean / max", "back: mean / max", "noise floor palm / back", "G0 gap",
            "G1 median / p95 / max (deg)", "surface→truth mean / p95", "truth within 1 mm", "rounds", "fit ms"]
    if a.tolerance:
        head += ["patches", "every patch within " + a.tolerance + " mm", "fit time / the default's"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(r) + " |")
    if figures:
        for k in ("palm_mean", "back_mean", "palm_max", "back_max", "truth_mean", "truth_p95", "within", "ms") + (
                ("patches", "ratio") if a.tolerance else ()):
            v = [f[k] for f in figures]
            print(f"{k}: median {statistics.median(v):.3f}, min {min(v):.3f}, max {max(v):.3f}")
    print(f"{len(figures)} of {len(rows)} pairs fitted")


if __name__ == "__main__":
    main()
