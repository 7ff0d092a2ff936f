#!/usr/bin/env python3
"""Hand-family study (issue 11): scan pairs of a varied synthetic hand family — right and
left hands, 160-215 mm, thin and thick, relaxed, curled and flat postures, raised and
pronated thumbs, forearm stubs of 0-40 mm, marker radii 2.5-4 mm — each registered with the
marker radius estimated (not given) and skinned with the pair's rig and with the automatic
skeleton, measured against its truth.

    python3 scripts/family_study.py [--bin build/handskin] [--work /tmp/family-study] [--hands H01,H02]

Prints a Markdown table and the summary (median and slowest pair); pairs already in --work
are reused. A failing stage is a row with its one-line error, not an abort.
"""
import argparse
import json
import os
import statistics
import sys

from study_util import run as sh

# name: synth hand options
HANDS = {
    "H01": [],                                                   # right, relaxed, nominal
    "H02": ["--side", "left"],                                   # left, relaxed
    "H03": ["--hand-length", "160", "--thickness", "0.8", "--width", "0.9", "--finger-thickness", "0.85",
            "--forearm", "0"],
    "H04": ["--side", "left", "--hand-length", "215", "--thickness", "1.25", "--width", "1.15",
            "--finger-thickness", "1.2", "--forearm", "40"],
    "H05": ["--hand-length", "175", "--finger-length", "1.1", "--set", "index.pip.flex=25", "--set",
            "middle.pip.flex=28", "--set", "ring.pip.flex=30", "--set", "little.pip.flex=32", "--set",
            "middle.dip.flex=15"],                               # curled fingers
    "H06": ["--side", "left", "--hand-length", "200", "--posture", "flat", "--spread", "10"],
    "H07": ["--hand-length", "170", "--set", "thumb.cmc.flex=18", "--thumb-pronation", "60"],  # raised thumb
    "H08": ["--side", "left", "--hand-length", "190", "--spread", "1"],          # fingers close together
    "H09": ["--hand-length", "165", "--index-ring-ratio", "1.0", "--finger-length", "0.9"],
    "H10": ["--hand-length", "205", "--thumb-abduction", "55", "--set", "index.mcp.abd=8", "--set",
            "little.mcp.abd=10", "--forearm", "25"],
    "H11": ["--side", "left", "--hand-length", "180", "--thumb-abduction", "30", "--set", "ring.mcp.flex=20",
            "--set", "little.mcp.flex=24"],
    "H12": ["--hand-length", "195", "--width", "1.3", "--thickness", "1.1", "--spread", "3"],
}
PAIRS = [(1, "2.5"), (2, "3.0"), (3, "3.5"), (4, "4.0")]  # seed, marker radius (mm)
# synth scan options per hand: the largest hand with the longest stub and a spread thumb
# spans 255 x 191 mm, more than the default 250 x 200 mm field holds.
SCAN = {"H04": ["--x-extent", "300", "--y-extent", "240"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default="/tmp/family-study")
    ap.add_argument("--hands", default=",".join(HANDS))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    pipeline = os.path.join(a.work, "no-baseline.json")
    p = json.load(open(os.path.join(os.path.dirname(__file__), "..", "pipelines", "cubist.json")))
    p["skin"]["baseline"] = False
    json.dump(p, open(pipeline, "w"))
    rows, fails = [], 0
    stats = {"given": [], "auto": []}  # (pair, watertight, triangles, mean, p95, within 1 mm, seconds)
    regs = []  # (pair, rotation deg, skin mean mm)
    for h in a.hands.split(","):
        hand = os.path.join(a.work, h)
        if not os.path.exists(os.path.join(hand, "hand.ply")):
            rc, out = sh([a.bin, "-q", "synth", "hand", "--out", hand, "--no-render"] + HANDS[h])
            if rc:
                rows.append([h, "-", "synth hand: " + out.strip().splitlines()[-1]])
                fails += 1
                continue
        for seed, radius in PAIRS:
            name = f"{h}-s{seed}-r{radius}"
            d = os.path.join(a.work, name)
            if not os.path.exists(os.path.join(d, "truth.json")):
                rc, out = sh([a.bin, "-q", "synth", "scan", "--mesh", hand + "/hand.ply", "--rig", hand + "/hand_rig.json",
                              "--out", d, "--seed", str(seed), "--marker-radius", radius, "--no-render"] + SCAN.get(h, []))
                if rc:
                    rows.append([name, "-", "synth scan: " + out.strip().splitlines()[-1]])
                    fails += 1
                    continue
            out_dir = os.path.join(a.work, "out-" + name)
            rc, out = sh([a.bin, "-q", "register", "--back", d + "/back", "--palm", d + "/palm", "--truth",
                          d + "/truth.json", "--out", out_dir])
            if rc:
                rows.append([name, "-", "register: " + out.strip().splitlines()[-1]])
                fails += 1
                continue
            reg = json.load(open(out_dir + "/registration.json"))
            tr = reg["against_truth"]["chosen"]
            row = [name, f'{reg["marker_radius"]["radius_mm"]:.3f}', f'{tr["rotation_deg"]:.4f} / {tr["skin_mean_mm"]:.4f}']
            regs.append((name, tr["rotation_deg"], tr["skin_mean_mm"]))
            for mode, extra in (("given", ["--rig", d + "/rig.json"]), ("auto", ["--rig", d + "/rig.json", "--auto-rig"])):
                sk = os.path.join(out_dir, mode)
                rc, out = sh([a.bin, "-q", "skin", "--merged", out_dir + "/merged.ply", "--truth", d + "/truth.json",
                              "--pipeline", pipeline, "--out", sk] + extra)
                if rc:
                    row += ["FAIL: " + out.strip().splitlines()[-1]]
                    fails += 1
                    continue
                r = json.load(open(sk + "/skin_report.json"))
                t = r["truth"]
                stats[mode].append((name, r["mesh"]["watertight"], r["mesh"]["triangles"], t["skin_to_truth_mm"]["mean"],
                                    t["skin_to_truth_mm"]["p95"], t["truth_to_skin_mm"]["within_1mm"], r["build_seconds"]))
                cell = (f'{"ok" if r["mesh"]["watertight"] else "NOT watertight"} {r["mesh"]["triangles"]} tri, '
                        f'{t["skin_to_truth_mm"]["mean"]:.3f} / {t["skin_to_truth_mm"]["p95"]:.3f} / '
                        f'{100 * t["truth_to_skin_mm"]["within_1mm"]:.2f} %, {1000 * r["build_seconds"]:.0f} ms')
                if mode == "auto":
                    e = r["skeleton"]["automatic"]["against_given_rig"]
                    cell += f', joints {e["mean_joint_error_mm"]:.2f} / {e["max_joint_error_mm"]:.1f} mm'
                row.append(cell)
            rows.append(row)
            print(name, "done", file=sys.stderr)
    head = ["pair", "marker radius (est.)", "registration deg / mm",
            "given rig: skin→truth mean / p95 / truth within 1 mm, build_skin time",
            "automatic: the same, joint error mean / max"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    print(f"\n{len(rows)} pairs, {fails} failed stages")
    # Against issue 11's figures: closed, 6 000-10 000 triangles, skin -> truth mean <= 0.1 mm,
    # p95 <= 0.35 mm, >= 98.5 % of the true skin within 1 mm; registration 0.02 deg, 0.05 mm.
    for mode, st in stats.items():
        if not st:
            continue
        miss = [x[0] for x in st if not (x[1] and 6000 <= x[2] <= 10000 and x[3] <= 0.1 and x[4] <= 0.35 and x[5] >= 0.985)]
        times = sorted(st, key=lambda x: x[6])
        print(f"{mode}: {len(st) - len(miss)} of {len(st)} skins meet the issue's figures"
              + (f" (not: {', '.join(miss)})" if miss else "")
              + f"; mean over the pairs {statistics.mean(x[3] for x in st):.4f} mm, worst mean {max(x[3] for x in st):.4f},"
              f" worst p95 {max(x[4] for x in st):.3f}, worst within 1 mm {100 * min(x[5] for x in st):.2f} %;"
              f" build_skin median {1000 * statistics.median(x[6] for x in st):.0f} ms, slowest {times[-1][0]}"
              f" {1000 * times[-1][6]:.0f} ms")
    if regs:
        over = [f"{n} ({r:.4f} deg / {m:.4f} mm)" for n, r, m in regs if r > 0.02 or m > 0.05]
        print(f"registration: {len(regs) - len(over)} of {len(regs)} pairs within 0.02 deg / 0.05 mm"
              + (f" (not: {', '.join(over)})" if over else ""))


if __name__ == "__main__":
    main()
