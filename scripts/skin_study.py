#!/usr/bin/env python3
"""Skin acceptance study (issue 5): synthetic pairs of several flat hands, each registered and
skinned with the given rig and with the automatic skeleton, measured against its true skin.

    python3 scripts/skin_study.py [--bin build/handskin] [--work /tmp/skin-study]

Prints a Markdown table (docs/skin.md holds the last one). Pairs already in --work are reused.
"""
import argparse
import json
import os
import sys

from study_util import run_or_exit as sh

HANDS = {  # name: synth hand options
    "A": [],
    "B": ["--hand-length", "200", "--spread", "10", "--thickness", "1.2", "--width", "1.15", "--thumb-abduction", "55"],
    "C": ["--hand-length", "165", "--spread", "2", "--thickness", "0.85", "--width", "0.9", "--thumb-abduction", "30"],
}
SEEDS = [11, 12]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default="/tmp/skin-study")
    ap.add_argument("--fixture", default="fixtures/default")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    pairs = [("fixture", a.fixture)]
    for h, opts in HANDS.items():
        hand = os.path.join(a.work, h)
        if not os.path.exists(os.path.join(hand, "hand.ply")):
            sh([a.bin, "-q", "synth", "hand", "--out", hand, "--posture", "flat", "--no-render"] + opts)
        for s in SEEDS:
            d = os.path.join(a.work, f"{h}{s}")
            if not os.path.exists(os.path.join(d, "truth.json")):
                sh([a.bin, "-q", "synth", "scan", "--mesh", hand + "/hand.ply", "--rig", hand + "/hand_rig.json",
                    "--out", d, "--seed", str(s), "--no-render"])
            pairs.append((f"{h}{s}", d))
    rows = []
    for name, d in pairs:
        out = os.path.join(a.work, "out-" + name)
        sh([a.bin, "-q", "register", "--back", d + "/back", "--palm", d + "/palm", "--out", out])
        sh([a.bin, "-q", "skin", "--merged", out + "/merged.ply", "--rig", d + "/rig.json", "--truth", d + "/truth.json",
            "--baseline", "--out", out + "/given"])
        sh([a.bin, "-q", "skin", "--merged", out + "/merged.ply", "--rig", d + "/rig.json", "--auto-rig", "--truth",
            d + "/truth.json", "--out", out + "/auto"])
        g = json.load(open(out + "/given/skin_report.json"))
        au = json.load(open(out + "/auto/skin_report.json"))
        e = au["skeleton"]["automatic"]["against_given_rig"]
        t, ta, b = g["truth"], au["truth"], g["baseline"]
        rows.append([
            name, g["mesh"]["triangles"], "yes" if g["mesh"]["watertight"] else "NO",
            f'{t["skin_to_truth_mm"]["mean"]:.3f}', f'{t["skin_to_truth_mm"]["p95"]:.3f}',
            f'{100 * t["truth_to_skin_mm"]["within_1mm"]:.2f}', f'{1000 * g["seconds"]:.0f}',
            f'{e["mean_joint_error_mm"]:.2f}', f'{e["max_joint_error_mm"]:.1f}',
            f'{ta["skin_to_truth_mm"]["mean"]:.3f} / {ta["skin_to_truth_mm"]["p95"]:.3f} / {100 * ta["truth_to_skin_mm"]["within_1mm"]:.2f}',
            "yes" if au["mesh"]["watertight"] else "NO",
            b["mesh"]["triangles"], f'{b["seconds"]:.1f}',
            f'{t["baseline_to_truth_mm"]["mean"]:.3f} / {t["baseline_to_truth_mm"]["p95"]:.3f} / {100 * t["truth_to_baseline_mm"]["within_1mm"]:.2f}',
        ])
        print(name, "done", file=sys.stderr)
    head = ["pair", "triangles", "watertight", "skin→truth mean", "p95", "truth within 1 mm %", "build ms",
            "auto joint error mean", "max", "auto skin: mean / p95 / within %", "auto watertight",
            "Poisson triangles", "Poisson s", "Poisson: mean / p95 / within %"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")


if __name__ == "__main__":
    main()
