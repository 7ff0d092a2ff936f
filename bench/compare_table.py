#!/usr/bin/env python3
"""The ratio of every benchmark between two builds (bench/compare.sh).

    python3 bench/compare_table.py --base A1.json [A2.json ...] --head B1.json [B2.json ...]

Each file is Google Benchmark's JSON (--benchmark_format=json). Per benchmark and side: the
median of its runs' real times (a repeated benchmark that reports aggregates only gives its
"median" aggregate per file; the median is then taken over the files), in milliseconds, and
the median of its peak_rss_MB counter where it has one. Prints a Markdown table, HEAD / BASE
per benchmark, and the geometric mean of the ratios; a benchmark missing on one side is
listed with "—". Exits 2 on a file that is not benchmark JSON.
"""
import argparse
import json
import math
import statistics
import sys

TO_MS = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}


def load(files):
    times, rss = {}, {}
    for f in files:
        try:
            with open(f) as fh:
                doc = json.load(fh)
            rows = doc["benchmarks"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(f"error: {f}: not Google Benchmark JSON ({e})", file=sys.stderr)
            sys.exit(2)
        per_file = {}
        for b in rows:
            name = b.get("run_name", b["name"])
            kind = b.get("run_type", "iteration")
            if kind == "aggregate" and b.get("aggregate_name") != "median":
                continue
            if b.get("error_occurred"):
                continue
            ms = b["real_time"] * TO_MS[b.get("time_unit", "ns")]
            per_file.setdefault(name, []).append(ms)
            if "peak_rss_MB" in b:
                rss.setdefault(name, []).append(b["peak_rss_MB"])
        for name, v in per_file.items():
            times.setdefault(name, []).append(statistics.median(v))
    return ({k: statistics.median(v) for k, v in times.items()}, {k: statistics.median(v) for k, v in rss.items()})


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", nargs="+", required=True)
    ap.add_argument("--head", nargs="+", required=True)
    ap.add_argument("--base-name", default="base")
    ap.add_argument("--head-name", default="HEAD")
    a = ap.parse_args()
    bt, br = load(a.base)
    ht, hr = load(a.head)
    names = sorted(set(bt) | set(ht))
    print(f"| benchmark | {a.base_name} (ms) | {a.head_name} (ms) | {a.head_name} / {a.base_name} | peak MB {a.base_name} → {a.head_name} |")
    print("|---|---:|---:|---:|---|")
    logs = []
    for n in names:
        b, h = bt.get(n), ht.get(n)
        ratio = h / b if b and h else None
        if ratio:
            logs.append(math.log(ratio))
        fmt = lambda x: "—" if x is None else (f"{x:.3f}" if x < 10 else f"{x:.1f}")
        mem = f"{br[n]:.0f} → {hr[n]:.0f}" if n in br and n in hr else ""
        print(f"| {n} | {fmt(b)} | {fmt(h)} | {'—' if ratio is None else f'{ratio:.2f}'} | {mem} |")
    if logs:
        print(f"\ngeometric mean of the ratios: {math.exp(sum(logs) / len(logs)):.3f} over {len(logs)} benchmarks")


if __name__ == "__main__":
    main()
