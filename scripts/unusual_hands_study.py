#!/usr/bin/env python3
"""Unusual hands study: hands outside the family's ranges (scripts/family_study.py) — the thumb
spread to 68 deg, fingers spread 14 deg, a broad thick hand at 240 mm with its fingers
touching, PIPs bent 55-60 deg, a thumb laid along the index, a flat hand with thin fingers
pressed together, MCPs bent with the thumb's IP, a raised and turned thumb — one scan pair each
(seed 7, 3.5 mm markers), run through `handskin run` (the marker radius estimated) with the
pair's rig and with the automatic skeleton, measured against its truth.

    python3 scripts/unusual_hands_study.py [--bin build/handskin] [--work /tmp/unusual-hands] [--hands P01,P04]

Prints the family study's Markdown table and summary (scripts/study_util.py) and writes every
pair's figures to <work>/unusual_hands.json; scan pairs already in --work are reused. A
failing run is a row with its one-line error, not an abort. These hands are where handskin
is known to be weakest (docs/skin.md, "Known limits"): the study says how far.
"""
import os

from study_util import no_baseline_pipeline, print_table, run as sh, study_args, study_pair

# name: synth hand options
HANDS = {
    "P01": ["--thumb-abduction", "68", "--side", "left"],                 # thumb spread wide
    "P02": ["--spread", "14", "--hand-length", "150"],                    # small, fingers spread
    "P03": ["--hand-length", "240", "--width", "1.35", "--thickness", "1.35", "--finger-thickness", "1.35",
            "--spread", "0"],                                             # large, thick, fingers touching
    "P04": ["--set", "index.pip.flex=55", "--set", "middle.pip.flex=60", "--set", "ring.pip.flex=60",
            "--set", "little.pip.flex=55", "--side", "left"],             # fingers curled
    "P05": ["--thumb-abduction", "22", "--thumb-pronation", "10", "--hand-length", "200"],  # thumb along the index
    "P06": ["--posture", "flat", "--spread", "0", "--width", "0.75", "--finger-thickness", "0.75"],  # flat, pressed
    "P07": ["--set", "index.mcp.flex=35", "--set", "middle.mcp.flex=40", "--set", "thumb.ip.flex=30",
            "--forearm", "0"],                                            # MCPs bent, no stub
    "P08": ["--side", "left", "--thumb-abduction", "60", "--thumb-pronation", "80",
            "--set", "thumb.cmc.flex=25"],                                # thumb raised and turned
}
# The large hand spans more than the default 250 x 200 mm table.
SCAN = {"P03": ["--x-extent", "300", "--y-extent", "240"]}
SEED, RADIUS = 7, "3.5"


def main():
    a = study_args(__doc__, "/tmp/unusual-hands", "--hands", HANDS)
    pipeline = no_baseline_pipeline(a.work)
    rows, fails = [], 0
    stats = {"given": [], "auto": []}
    regs = []
    for h in a.hands.split(","):
        hand = os.path.join(a.work, h)
        if not os.path.exists(os.path.join(hand, "hand.ply")):
            rc, out = sh([a.bin, "-q", "synth", "hand", "--out", hand, "--no-render"] + HANDS[h])
            if rc:
                rows.append([h, "-", "synth hand: " + out.strip().splitlines()[-1]])
                fails += 1
                continue
        row, failed = study_pair(a.bin, f"{h}-s{SEED}-r{RADIUS}", a.work, hand, SEED, RADIUS, SCAN.get(h, []), pipeline,
                                 stats, regs)
        rows.append(row)
        fails += failed
    print_table(rows, fails, stats, regs, os.path.join(a.work, "unusual_hands.json"))


if __name__ == "__main__":
    main()
