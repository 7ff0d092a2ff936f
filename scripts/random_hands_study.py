#!/usr/bin/env python3
"""Random hands study: hands and scans drawn at random, where the family (scripts/family_study.py)
and the unusual hands (scripts/unusual_hands_study.py) are chosen — right or left, 150-230 mm,
breadth 0.8-1.25, palm thickness 0.85-1.2, finger girth 0.85-1.2, fingers spread 0-12 deg, the
thumb at 20-60 deg; each finger's MCP flexed -5-45 deg, PIP 0-50, DIP 0-30, each drawn on its
own (so fingers may cross or touch: postures a hand can hardly hold are among them), the thumb's
CMC, MCP and IP 0-30 deg; scanned with depth noise 0.03-0.1 mm, the laser tilted 15-25 deg,
surfaces returning up to 66-78 deg, the table tilted 0-3 deg, markers 2.5-4.5 mm — one pair
each, run through `handskin run` (the marker radius estimated) with the pair's rig and with the
automatic skeleton, measured against its truth.

    python3 scripts/random_hands_study.py [--bin build/handskin] [--work /tmp/random-hands] [--draw 69] [--count 12] [--hands R01,R02]

The same --draw gives the same hands and scans. Prints the family study's Markdown table and
summary (scripts/study_util.py) and writes every pair's figures to <work>/random_hands.json;
scan pairs already in --work are reused. A failing run is a row with its one-line error, not
an abort.
"""
import argparse
import os
import random
import sys

from study_util import no_baseline_pipeline, print_table, run as sh, study_pair


def draw(seed, count):
    """name -> (synth hand options, scan seed, marker radius, synth scan options)."""
    rng = random.Random(seed)
    hands = {}
    for i in range(count):
        a = ["--side", rng.choice(["right", "left"])]
        a += ["--hand-length", "%.0f" % rng.uniform(150, 230), "--width", "%.2f" % rng.uniform(0.8, 1.25),
              "--thickness", "%.2f" % rng.uniform(0.85, 1.2), "--finger-thickness", "%.2f" % rng.uniform(0.85, 1.2),
              "--spread", "%.1f" % rng.uniform(0, 12), "--thumb-abduction", "%.0f" % rng.uniform(20, 60)]
        for f in ["index", "middle", "ring", "little"]:
            a += ["--set", "%s.mcp.flex=%.0f" % (f, rng.uniform(-5, 45)), "--set", "%s.pip.flex=%.0f" % (f, rng.uniform(0, 50)),
                  "--set", "%s.dip.flex=%.0f" % (f, rng.uniform(0, 30))]
        for j in ["cmc", "mcp", "ip"]:
            a += ["--set", "thumb.%s.flex=%.0f" % (j, rng.uniform(0, 30))]
        seed_scan = rng.randint(1, 99)
        radius = "%.1f" % rng.choice([2.5, 3, 3.5, 4, 4.5])
        scan = ["--noise", "%.3f" % rng.uniform(0.03, 0.1), "--laser-tilt", "%.0f" % rng.uniform(15, 25),
                "--max-incidence", "%.0f" % rng.uniform(66, 78), "--table-tilt", "%.1f" % rng.uniform(0, 3),
                "--x-extent", "300", "--y-extent", "240"]
        hands["R%02d" % (i + 1)] = (a, seed_scan, radius, scan)
    return hands


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bin", default=os.path.join(here, "..", "build", "handskin"))
    p.add_argument("--work", default="/tmp/random-hands")
    p.add_argument("--draw", type=int, default=69, help="the random draw's seed")
    p.add_argument("--count", type=int, default=12)
    p.add_argument("--hands", default="", help="a comma-separated subset (R01,R02); default: every one")
    a = p.parse_args()
    if not os.path.exists(a.bin):
        sys.exit(f"{a.bin}: no such binary (build first, or give --bin)")
    hands = draw(a.draw, a.count)
    names = a.hands.split(",") if a.hands else list(hands)
    for n in names:
        if n not in hands:
            sys.exit(f"--hands: {n} is not one of {', '.join(hands)}")
    work = os.path.join(a.work, f"draw{a.draw}")
    os.makedirs(work, exist_ok=True)
    pipeline = no_baseline_pipeline(work)
    rows, fails = [], 0
    stats = {"given": [], "auto": []}
    regs = []
    for n in names:
        options, seed, radius, scan = hands[n]
        hand = os.path.join(work, n)
        if not os.path.exists(os.path.join(hand, "hand.ply")):
            rc, out = sh([a.bin, "-q", "synth", "hand", "--out", hand, "--no-render"] + options)
            if rc:
                rows.append([n, "-", "synth hand: " + out.strip().splitlines()[-1]])
                fails += 1
                continue
        row, failed = study_pair(a.bin, f"{n}-s{seed}-r{radius}", work, hand, seed, radius, scan, pipeline, stats, regs)
        rows.append(row)
        fails += failed
    print_table(rows, fails, stats, regs, os.path.join(work, "random_hands.json"))


if __name__ == "__main__":
    main()
