#!/usr/bin/env python3
"""The Python module's speed (docs/python.md "Speed"): solve_batch postures per second, a pose,
and the fixture's run, each the median of a few rounds. Prints one line per figure.

    /usr/bin/python3 bench/python_bench.py [--rows N] [--rounds R] [--no-run]
"""
import argparse
import pathlib
import statistics
import tempfile
import time

import numpy as np

import handskin

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIX = ROOT / "fixtures" / "default"


def median_time(fn, rounds):
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=200000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--no-run", action="store_true", help="skip the fixture's run")
    a = ap.parse_args()
    rng = np.random.default_rng(7)
    m = handskin.PostureModel("builtin:anatomical")
    # rows pinning 1-3 of 6 DOFs, values varying (as BM_PostureBatch in bench/bench_main.cpp)
    cols = ["index.mcp.flex", "index.pip.flex", "middle.mcp.flex", "middle.pip.flex", "thumb.mcp.flex", "thumb.ip.flex"]
    X = rng.uniform(0, 60, size=(a.rows, len(cols)))
    keep = rng.integers(1, 4, size=a.rows)
    for r in range(a.rows):
        free = rng.permutation(len(cols))[keep[r]:]
        X[r, free] = np.nan
    t = median_time(lambda: m.solve_batch(cols, X), a.rounds)
    print(f"solve_batch: {a.rows} rows in {t * 1e3:.1f} ms = {a.rows / t:,.0f} postures/s (pins 1-3 of 6 DOFs)")
    one = np.array([[30.0]])
    t = median_time(lambda: [m.solve_batch(["index.pip.flex"], one) for _ in range(10000)], a.rounds) / 10000
    print(f"solve_batch of one row: {t * 1e6:.1f} us per call")
    if a.no_run:
        return
    with tempfile.TemporaryDirectory() as d:
        rep = {}
        t = median_time(lambda: rep.update(handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json",
                                                        out=pathlib.Path(d) / "out", force=True)), 3)
        print(f"run on the fixture: {t:.2f} s (report total {rep['total_seconds']:.2f} s)")
        skin = handskin.RiggedSkin(pathlib.Path(d) / "out" / "skin.glb")
        angles = m.solve({"index.pip.flex": 60.0})
        t = median_time(lambda: [skin.pose(angles) for _ in range(50)], a.rounds) / 50
        print(f"pose ({len(skin.vertices)} vertices, DQS, crease guard): {t * 1e3:.2f} ms = {1 / t:,.0f} postures/s")


if __name__ == "__main__":
    main()
