#!/usr/bin/env python3
"""Hand-family study (issues 11 and 35): scan pairs of a varied synthetic hand family — right
and left hands, 160-215 mm, thin and thick, relaxed, curled and flat postures, raised and
pronated thumbs, forearm stubs of 0-40 mm, marker radii 2.5-4 mm — each run through
`handskin run` (the marker radius estimated, not given) with the pair's rig and with the
automatic skeleton, its skin and its patch surface measured against its truth.

    python3 scripts/family_study.py [--bin build/handskin] [--work /tmp/family-study] [--hands H01,H02]

Prints a Markdown table and the summary against issue 35's bars (scripts/study_util.py) and
writes every pair's figures to <work>/family_study.json; scan pairs already in --work are
reused. A failing run is a row with its one-line error, not an abort.
"""
import os

from study_util import no_baseline_pipeline, print_table, run as sh, study_args, study_pair

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


def family_args(doc, extra=None):
    """The family studies' options (--bin, --work, --hands, and those `extra(parser)` adds),
    parsed; the work folder made."""
    return study_args(doc, "/tmp/family-study", "--hands", HANDS, extra)


def family_hand(binary, work, h):
    """Hand h of the family in work/h (made unless it is there): (its folder, None), or
    (its folder, the synth command's last line) when it could not be made."""
    hand = os.path.join(work, h)
    if not os.path.exists(os.path.join(hand, "hand.ply")):
        rc, out = sh([binary, "-q", "synth", "hand", "--out", hand, "--no-render"] + HANDS[h])
        if rc:
            return hand, "synth hand: " + out.strip().splitlines()[-1]
    return hand, None


def main():
    a = family_args(__doc__)
    pipeline = no_baseline_pipeline(a.work)
    rows, fails = [], 0
    stats = {"given": [], "auto": []}  # (pair, figures)
    regs = []  # (pair, rotation deg, skin mean mm)
    for h in a.hands.split(","):
        hand, error = family_hand(a.bin, a.work, h)
        if error:
            rows.append([h, "-", error])
            fails += 1
            continue
        for seed, radius in PAIRS:
            row, failed = study_pair(a.bin, f"{h}-s{seed}-r{radius}", a.work, hand, seed, radius, SCAN.get(h, []),
                                     pipeline, stats, regs)
            rows.append(row)
            fails += failed
    print_table(rows, fails, stats, regs, os.path.join(a.work, "family_study.json"))


if __name__ == "__main__":
    main()
