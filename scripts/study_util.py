"""Helpers shared by the study scripts (family, WebXR, skin, patch and posture studies)."""
import argparse
import json
import os
import statistics
import subprocess
import sys


def run(args):
    """Run a command; return its exit code and its output (stdout and stderr together)."""
    r = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return r.returncode, r.stdout


def run_or_exit(args):
    """Run a command; return its output, or end the study with the command and its output."""
    code, out = run(args)
    if code != 0:
        sys.exit(f"failed ({code}): {' '.join(args)}\n{out}")
    return out


def study_args(doc, work, names_flag, names, extra=None):
    """A study's options: --bin, --work (default `work`), `names_flag` (the hands or postures
    to run, default all of `names`) and those `extra(parser)` adds; parsed, the work folder made."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default=work)
    ap.add_argument(names_flag, default=",".join(names))
    if extra:
        extra(ap)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    return a


def no_baseline_pipeline(work):
    """The default pipeline without the baseline skin (the studies measure the skin alone)."""
    path = os.path.join(work, "no-baseline.json")
    p = json.load(open(os.path.join(os.path.dirname(__file__), "..", "pipelines", "cubist.json")))
    p["skin"]["baseline"] = False
    json.dump(p, open(path, "w"))
    return path


# Issue 35's bars, per pair and mode: the skin closed, manifold, not self-intersecting (in the
# written file, as the report's gates say), within mean / p95 of the true skin, that share of
# the true skin within 1 mm; the same for the patch surface, and its largest distance.
SKIN_BARS = {"mean": 0.10, "p95": 0.35, "within_1mm": 0.985}
PATCH_BARS = {"mean": 0.15, "p95": 0.40, "max": 3.0, "within_1mm": 0.985}


def stage(report, name):
    return next((s for s in report["stages"] if s["name"] == name), None)


def pair_figures(report):
    """The figures of one run's report.json that the study holds to the bars."""
    sk, pa = stage(report, "skin"), stage(report, "patches")
    gates = {g["name"]: g for g in report.get("gates", [])}
    f = {"skin_closed": sk["mesh"]["closed"] and sk["mesh"]["manifold"] and sk["mesh"]["outward"],
         "skin_self_intersections": sk["mesh"]["self_intersections"],
         "skin_mean": sk["truth"]["skin_to_truth_mm"]["mean"], "skin_p95": sk["truth"]["skin_to_truth_mm"]["p95"],
         "skin_within_1mm": sk["truth"]["truth_to_skin_mm"]["within_1mm"],
         "gates_failed": [n for n, g in gates.items() if not g["pass"]],
         "seconds": report["total_seconds"],
         # The run as a user runs it: less the comparisons with the truth (a study's evaluation,
         # timed inside the skin and patch stages).
         "seconds_without_truth": report["total_seconds"] - sk["truth"].get("seconds", 0)
         - (pa["truth"].get("seconds", 0) if pa else 0)}
    if pa:
        t = pa["truth"]
        f.update({"patch_mean": t["surface_to_truth_mm"]["mean"], "patch_p95": t["surface_to_truth_mm"]["p95"],
                  "patch_max": t["surface_to_truth_mm"]["max"], "patch_within_1mm": t["truth_to_surface_mm"]["within_1mm"],
                  "patch_worst": pa.get("farthest_point_patch")})
    return f


def misses(f):
    """The bars a pair's figures miss (names), none when it meets them all."""
    m = []
    if not f["skin_closed"]:
        m.append("skin not closed")
    if f["skin_self_intersections"]:
        m.append("skin self-intersects")
    for k, bar in SKIN_BARS.items():
        v = f["skin_" + k]
        if (v < bar) if k == "within_1mm" else (v > bar):
            m.append(f"skin {k} {v:.3f}")
    if "patch_mean" not in f:
        m.append("no patches")
        return m
    for k, bar in PATCH_BARS.items():
        v = f["patch_" + k]
        if (v < bar) if k == "within_1mm" else (v > bar):
            m.append(f"patches {k} {v:.3f}")
    return m


def measure_pair(binary, name, d, out_dir, pipeline, stats, regs):
    """Run the scan pair in `d` through `handskin run` (the marker radius estimated, patches
    and all) with the pair's rig and with the automatic skeleton, each measured against
    d/truth.json. Returns the table row and the number of failed runs; appends to
    stats[mode] (pair, figures) and regs (pair, rotation deg, skin mean mm)."""
    row, fails = [name], 0
    for mode, extra in (("given", ["--rig", d + "/rig.json"]), ("auto", ["--rig", d + "/rig.json", "--auto-rig"])):
        out = os.path.join(out_dir, mode)
        rc, text = run([binary, "-q", "run", "--back", d + "/back", "--palm", d + "/palm", "--truth", d + "/truth.json",
                        "--pipeline", pipeline, "--out", out] + extra)
        if rc:
            row += ["FAIL: " + text.strip().splitlines()[-1]]
            fails += 1
            continue
        r = json.load(open(out + "/report.json"))
        if mode == "given":
            tr = stage(r, "registration")["against_truth"]["chosen"]
            row.insert(1, f'{tr["rotation_deg"]:.4f} / {tr["skin_mean_mm"]:.4f}')
            regs.append((name, tr["rotation_deg"], tr["skin_mean_mm"]))
        f = pair_figures(r)
        stats[mode].append((name, f))
        cell = (f'skin {f["skin_mean"]:.3f} / {f["skin_p95"]:.3f} / {100 * f["skin_within_1mm"]:.2f} %'
                f'{"" if f["skin_closed"] and not f["skin_self_intersections"] else " NOT CLEAN"}')
        if "patch_mean" in f:
            cell += (f'; patches {f["patch_mean"]:.3f} / {f["patch_p95"]:.3f} / {f["patch_max"]:.2f} / '
                     f'{100 * f["patch_within_1mm"]:.2f} %')
        m = misses(f)
        cell += "; " + ("ok" if not m else "MISSES " + ", ".join(m))
        if f["gates_failed"]:
            cell += "; gates failed: " + ", ".join(f["gates_failed"])
        row.append(cell)
    if len(row) == 3:
        row.insert(1, "-")
    return row, fails


def scan_pair(binary, name, work, mesh, seed, radius, scan_extra):
    """A scan pair of the replica in `mesh` (hand.ply, hand_rig.json) in work/name, made with the
    seed and marker radius unless it is there already: (its folder, None), or (its folder, the
    synth command's last line) when it could not be made."""
    d = os.path.join(work, name)
    if not os.path.exists(os.path.join(d, "truth.json")):
        rc, out = run([binary, "-q", "synth", "scan", "--mesh", mesh + "/hand.ply", "--rig", mesh + "/hand_rig.json",
                       "--out", d, "--seed", str(seed), "--marker-radius", radius, "--no-render"] + scan_extra)
        if rc:
            return d, "synth scan: " + out.strip().splitlines()[-1]
    return d, None


def study_pair(binary, name, work, mesh, seed, radius, scan_extra, pipeline, stats, regs):
    """A scan pair (scan_pair) measured by measure_pair. Returns the table row and the number
    of failed stages."""
    d, error = scan_pair(binary, name, work, mesh, seed, radius, scan_extra)
    if error:
        return [name, "-", error], 1
    row, failed = measure_pair(binary, name, d, os.path.join(work, "out-" + name), pipeline, stats, regs)
    print(name, "done", file=sys.stderr)
    return row, failed


def print_table(rows, fails, stats, regs, json_path=None):
    """The pairs' Markdown table, then the summary against issue 35's bars (SKIN_BARS,
    PATCH_BARS) per mode and issue 11's registration bound (0.02 deg, 0.05 mm); with
    `json_path`, every pair's figures written there too."""
    head = ["pair", "registration deg / mm",
            "given rig: skin→truth mean / p95 / truth within 1 mm; patches mean / p95 / max / within 1 mm",
            "automatic placement: the same"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    print(f"\n{len(rows)} pairs, {fails} failed runs")
    for mode, st in stats.items():
        if not st:
            continue
        miss = [n for n, f in st if misses(f)]
        fs = [f for _, f in st]
        line = (f"- {mode}: {len(st) - len(miss)} of {len(st)} pairs meet every bar"
                + (f" (not: {', '.join(miss)})" if miss else "")
                + f"; skin mean worst {max(f['skin_mean'] for f in fs):.4f}, p95 worst {max(f['skin_p95'] for f in fs):.3f},"
                f" within 1 mm worst {100 * min(f['skin_within_1mm'] for f in fs):.2f} %")
        pf = [f for f in fs if "patch_mean" in f]
        if pf:
            line += (f"; patches mean median {statistics.median(f['patch_mean'] for f in pf):.4f} worst "
                     f"{max(f['patch_mean'] for f in pf):.4f}, p95 worst {max(f['patch_p95'] for f in pf):.3f},"
                     f" max worst {max(f['patch_max'] for f in pf):.2f}, within 1 mm worst "
                     f"{100 * min(f['patch_within_1mm'] for f in pf):.2f} %")
        line += (f"; run median {statistics.median(f['seconds'] for f in fs):.2f} s,"
                 f" slowest {max(f['seconds'] for f in fs):.2f} s")
        bare = [f["seconds_without_truth"] for f in fs if "seconds_without_truth" in f]
        if bare:
            line += (f" (without the comparisons with the truth: median {statistics.median(bare):.2f} s,"
                     f" slowest {max(bare):.2f} s)")
        print(line)
    if regs:
        over = [f"{n} ({r:.4f} deg / {m:.4f} mm)" for n, r, m in regs if r > 0.02 or m > 0.05]
        print(f"- registration: {len(regs) - len(over)} of {len(regs)} pairs within 0.02 deg / 0.05 mm"
              + (f" (not: {', '.join(over)})" if over else ""))
    if json_path:
        json.dump({mode: {n: f for n, f in st} for mode, st in stats.items()}, open(json_path, "w"), indent=1)
