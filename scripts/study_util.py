"""Helpers shared by the study scripts (family, WebXR, skin, patch and posture studies)."""
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


def no_baseline_pipeline(work):
    """The default pipeline without the baseline skin (the studies measure the skin alone)."""
    path = os.path.join(work, "no-baseline.json")
    p = json.load(open(os.path.join(os.path.dirname(__file__), "..", "pipelines", "cubist.json")))
    p["skin"]["baseline"] = False
    json.dump(p, open(path, "w"))
    return path


def measure_pair(binary, name, d, out_dir, pipeline, stats, regs):
    """Register the scan pair in `d` (the marker radius estimated) and skin it with the pair's
    rig and with the automatic skeleton, each measured against d/truth.json. Returns the
    table row and the number of failed stages; appends to stats[mode] (pair, watertight,
    triangles, mean, p95, within 1 mm, seconds) and regs (pair, rotation deg, skin mean mm)."""
    rc, out = run([binary, "-q", "register", "--back", d + "/back", "--palm", d + "/palm", "--truth",
                   d + "/truth.json", "--out", out_dir])
    if rc:
        return [name, "-", "register: " + out.strip().splitlines()[-1]], 1
    reg = json.load(open(out_dir + "/registration.json"))
    tr = reg["against_truth"]["chosen"]
    row = [name, f'{reg["marker_radius"]["radius_mm"]:.3f}', f'{tr["rotation_deg"]:.4f} / {tr["skin_mean_mm"]:.4f}']
    regs.append((name, tr["rotation_deg"], tr["skin_mean_mm"]))
    fails = 0
    for mode, extra in (("given", ["--rig", d + "/rig.json"]), ("auto", ["--rig", d + "/rig.json", "--auto-rig"])):
        sk = os.path.join(out_dir, mode)
        rc, out = run([binary, "-q", "skin", "--merged", out_dir + "/merged.ply", "--truth", d + "/truth.json",
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
    return row, fails


def study_pair(binary, name, work, mesh, seed, radius, scan_extra, pipeline, stats, regs):
    """A scan pair of the replica in `mesh` (hand.ply, hand_rig.json) in work/name (made with
    the seed and marker radius, unless it is there already), measured by measure_pair.
    Returns the table row and the number of failed stages."""
    d = os.path.join(work, name)
    if not os.path.exists(os.path.join(d, "truth.json")):
        rc, out = run([binary, "-q", "synth", "scan", "--mesh", mesh + "/hand.ply", "--rig", mesh + "/hand_rig.json",
                       "--out", d, "--seed", str(seed), "--marker-radius", radius, "--no-render"] + scan_extra)
        if rc:
            return [name, "-", "synth scan: " + out.strip().splitlines()[-1]], 1
    row, failed = measure_pair(binary, name, d, os.path.join(work, "out-" + name), pipeline, stats, regs)
    print(name, "done", file=sys.stderr)
    return row, failed


def print_table(rows, fails, stats, regs):
    """The pairs' Markdown table, then the summary against issue 11's figures: closed,
    6 000-10 000 triangles, skin -> truth mean <= 0.1 mm, p95 <= 0.35 mm, >= 98.5 % of the true
    skin within 1 mm; registration within 0.02 deg and 0.05 mm (mean skin displacement)."""
    head = ["pair", "marker radius (est.)", "registration deg / mm",
            "given rig: skin→truth mean / p95 / truth within 1 mm, build_skin time",
            "automatic: the same, joint error mean / max"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    print(f"\n{len(rows)} pairs, {fails} failed stages")
    for mode, st in stats.items():
        if not st:
            continue
        miss = [x[0] for x in st if not (x[1] and 6000 <= x[2] <= 10000 and x[3] <= 0.1 and x[4] <= 0.35 and x[5] >= 0.985)]
        times = sorted(st, key=lambda x: x[6])
        print(f"- {mode}: {len(st) - len(miss)} of {len(st)} skins meet the issue's figures"
              + (f" (not: {', '.join(miss)})" if miss else "")
              + f"; mean over the pairs {statistics.mean(x[3] for x in st):.4f} mm, worst mean {max(x[3] for x in st):.4f},"
              f" worst p95 {max(x[4] for x in st):.3f}, worst within 1 mm {100 * min(x[5] for x in st):.2f} %;"
              f" build_skin median {1000 * statistics.median(x[6] for x in st):.0f} ms, slowest {times[-1][0]}"
              f" {1000 * times[-1][6]:.0f} ms")
    if regs:
        over = [f"{n} ({r:.4f} deg / {m:.4f} mm)" for n, r, m in regs if r > 0.02 or m > 0.05]
        print(f"- registration: {len(regs) - len(over)} of {len(regs)} pairs within 0.02 deg / 0.05 mm"
              + (f" (not: {', '.join(over)})" if over else ""))
