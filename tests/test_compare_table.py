#!/usr/bin/env python3
"""bench/compare_table.py on made-up benchmark JSON: medians, aggregates, units, ratios, a
benchmark on one side only, and a file that is not benchmark JSON."""
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def write(path, rows):
    with open(path, "w") as f:
        json.dump({"context": {}, "benchmarks": rows}, f)


def it(name, t, unit="ms", **extra):
    return {"name": name, "run_name": name, "run_type": "iteration", "real_time": t, "time_unit": unit, **extra}


def agg(name, kind, t, unit="ms", **extra):
    return {"name": f"{name}_{kind}", "run_name": name, "run_type": "aggregate", "aggregate_name": kind,
            "real_time": t, "time_unit": unit, **extra}


def main():
    d = tempfile.mkdtemp()
    # base: A 10 ms (median of 9, 10, 50), B 2 s as aggregates (median 2000 ms, mean ignored), C only here
    write(f"{d}/b1.json", [it("A", 9), it("A", 10), it("A", 50), agg("B", "mean", 9.0, "s", peak_rss_MB=400),
                           agg("B", "median", 2.0, "s", peak_rss_MB=400), it("C", 1)])
    # head: A 5 ms in microseconds, B 1000 ms, D only here
    write(f"{d}/h1.json", [it("A", 5000, "us"), agg("B", "median", 1000, "ms", peak_rss_MB=200), it("D", 3)])
    out = subprocess.run([sys.executable, f"{ROOT}/bench/compare_table.py", "--base", f"{d}/b1.json", "--head",
                          f"{d}/h1.json"], capture_output=True, text=True, check=True).stdout
    rows = {l.split("|")[1].strip(): [c.strip() for c in l.split("|")[2:-1]] for l in out.splitlines() if l.startswith("| ") and "benchmark" not in l}
    assert rows["A"][:3] == ["10.0", "5.000", "0.50"], rows["A"]
    assert rows["B"][:3] == ["2000.0", "1000.0", "0.50"], rows["B"]
    assert rows["B"][3] == "400 → 200", rows["B"]
    assert rows["C"][1:3] == ["—", "—"] and rows["D"][0] == "—", (rows["C"], rows["D"])
    assert "geometric mean of the ratios: 0.500 over 2 benchmarks" in out, out
    open(f"{d}/bad.json", "w").write("not json")
    r = subprocess.run([sys.executable, f"{ROOT}/bench/compare_table.py", "--base", f"{d}/bad.json", "--head",
                        f"{d}/h1.json"], capture_output=True, text=True)
    assert r.returncode == 2 and "bad.json" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r
    # compare.sh refuses what is not a revision, with exit 2
    r = subprocess.run(["bash", f"{ROOT}/bench/compare.sh", "no-such-revision"], capture_output=True, text=True)
    assert r.returncode == 2 and "no-such-revision" in r.stderr, r
    print("compare_table: ok")


main()
