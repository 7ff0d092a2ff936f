#!/usr/bin/env python3
"""The family's runs timed as a user runs them (issue 39: every pair's run within 1.5 s): each
scan pair of scripts/family_study.py's work folder through `handskin run` with its rig, and
with no rig (the skeleton placed automatically), without `--truth` — the study's comparisons
with the truth are an evaluation a user's run does not make (0.3–0.75 s of the study's times).

    python3 scripts/family_timing.py [--bin build/handskin] [--work /tmp/family-study] [--rounds 1]

Runs family_study.py's pairs that are in --work (make them with it first). Prints, per mode,
the median and the slowest of report.json's in-process totals and of the process's wall time
(each pair's fastest of --rounds), and the pairs over 1.5 s. Exits 1 when a run fails.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from family_study import HANDS, PAIRS


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default="/tmp/family-study")
    ap.add_argument("--rounds", type=int, default=1)
    a = ap.parse_args()
    pipeline = os.path.join(a.work, "no-baseline.json")
    pairs = [f"{h}-s{seed}-r{radius}" for h in HANDS for seed, radius in PAIRS]
    pairs = [p for p in pairs if os.path.exists(os.path.join(a.work, p, "truth.json"))]
    if not pairs:
        sys.exit(f"family_timing: no pairs in {a.work} (run scripts/family_study.py first)")
    times = {"given": {}, "automatic": {}}
    with tempfile.TemporaryDirectory(prefix="handskin-family-timing-") as tmp:
        for p in pairs:
            d = os.path.join(a.work, p)
            for mode, extra in (("given", ["--rig", d + "/rig.json"]), ("automatic", [])):
                best = None
                for r in range(a.rounds):
                    out = os.path.join(tmp, f"{p}-{mode}-{r}")
                    cmd = [a.bin, "-q", "run", "--back", d + "/back", "--palm", d + "/palm", "--out", out] + extra
                    if os.path.exists(pipeline):
                        cmd += ["--pipeline", pipeline]
                    t0 = time.monotonic()
                    rc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                    wall = time.monotonic() - t0
                    if rc.returncode:
                        sys.exit(f"family_timing: {p} ({mode}) failed: {rc.stderr.strip().splitlines()[-1]}")
                    total = json.load(open(os.path.join(out, "report.json")))["total_seconds"]
                    if best is None or total < best[0]:
                        best = (total, wall)
                times[mode][p] = best
    for mode, t in times.items():
        inproc = [x for x, _ in t.values()]
        wall = [w for _, w in t.values()]
        over = [p for p, (x, _) in t.items() if x > 1.5]
        print(f"- {mode}: {len(t)} pairs; report.json total median {statistics.median(inproc):.2f} s, slowest "
              f"{max(inproc):.2f} s ({max(t, key=lambda p: t[p][0])}); process wall median "
              f"{statistics.median(wall):.2f} s, slowest {max(wall):.2f} s; over 1.5 s: "
              + (", ".join(over) if over else "none"))


if __name__ == "__main__":
    main()
