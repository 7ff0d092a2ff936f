#!/usr/bin/env python3
"""Posture-calibration study (issue 14): held-out errors of the three calibration methods
(gaussian, mixture, thesis-pairs) on the shared Qualisys recording and on synthetic
recordings with known structure — a Gaussian with gaps, a curved grasp, and seven people
(different hands, their own offsets) left out one at a time — against the training mean
posture and a linear regression fitted on the same frames. Also checks the user's path:
calibrate on six people, then `solve --inputs` on the seventh's given joints.

    python3 scripts/posture_study.py [--bin build/handskin] [--work /tmp/posture-study]

Prints Markdown tables (the ones in docs/posture.md).
"""
import argparse
import csv
import json
import math
import os

from study_util import run_or_exit as sh


def calibrate(bin_, work, name, angles, method):
    out = os.path.join(work, f"{name}-{method}.json")
    rep = os.path.join(work, f"{name}-{method}-report.json")
    args = [bin_, "-q", "calibrate", "--out", out, "--report", rep, "--method", method]
    for a in angles:
        args += ["--angles", a]
    sh(args)
    with open(rep) as f:
        return out, json.load(f)


def fmt(v):
    return "–" if v is None else f"{v:.2f}"


def table(title, reports, scheme):
    print(f"\n**{title}** (held-out {'blocks' if scheme == 'blocks' else 'recordings'}, RMS deg)\n")
    print("| task | gaussian (default) | mixture | thesis-pairs | mean posture | linear regression | default / regression |")
    print("|---|---|---|---|---|---|---|")
    g = reports["gaussian"]["cross_validation"][scheme]["tasks"]
    for i, t in enumerate(g):
        row = [reports[m]["cross_validation"][scheme]["tasks"][i]["model_rms_deg"] for m in ("gaussian", "mixture", "thesis-pairs")]
        print(f"| {t['task']} | {fmt(row[0])} | {fmt(row[1])} | {fmt(row[2])} | {fmt(t['mean_posture_rms_deg'])} | "
              f"{fmt(t['linear_regression_rms_deg'])} | {t['model_over_regression']:.3f} |")
    for s in reports["gaussian"].get("tasks_skipped", []):
        print(f"\n(skipped: {s})")


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = rows[0]
    return head, [[float(v) if v else None for v in r] for r in rows[1:]]


def lstsq(X, y):
    """Ordinary least squares by the normal equations (small systems; no numpy here)."""
    n = len(X[0])
    A = [[sum(r[i] * r[j] for r in X) for j in range(n)] for i in range(n)]
    b = [sum(r[i] * v for r, v in zip(X, y)) for i in range(n)]
    for i in range(n):
        A[i][i] += 1e-9 * (1 + A[i][i])
    for c in range(n):  # Gaussian elimination with partial pivoting
        p = max(range(c, n), key=lambda r: abs(A[r][c]))
        A[c], A[p], b[c], b[p] = A[p], A[c], b[p], b[c]
        for r in range(c + 1, n):
            f = A[r][c] / A[c][c]
            for k in range(c, n):
                A[r][k] -= f * A[c][k]
            b[r] -= f * b[c]
    x = [0.0] * n
    for c in range(n - 1, -1, -1):
        x[c] = (b[c] - sum(A[c][k] * x[k] for k in range(c + 1, n))) / A[c][c]
    return x


def user_path(bin_, work, people):
    """Calibrate on all but the last person, solve the last one's frames with `solve --inputs`."""
    train, test = people[:-1], people[-1]
    head, rows = read_csv(test)
    tasks = {
        "middle MCP -> 7 finger joints": (["middle.mcp.flex"],
                                          ["index.mcp.flex", "ring.mcp.flex", "little.mcp.flex", "index.pip.flex",
                                           "middle.pip.flex", "ring.pip.flex", "little.pip.flex"]),
        "4 PIPs -> 4 DIPs": ([f"{f}.pip.flex" for f in ("index", "middle", "ring", "little")],
                             [f"{f}.dip.flex" for f in ("index", "middle", "ring", "little")]),
        "5 MCPs -> PIPs, DIPs, thumb IP": ([f"{f}.mcp.flex" for f in ("thumb", "index", "middle", "ring", "little")],
                                           [f"{f}.{j}.flex" for f in ("index", "middle", "ring", "little") for j in ("pip", "dip")]
                                           + ["thumb.ip.flex"]),
    }
    train_rows = []
    for p in train:
        h, r = read_csv(p)
        assert h == head
        train_rows += r
    print("\n**The user's path** (calibrate on six people, `solve --inputs` on the seventh; RMS deg)\n")
    print("| task | gaussian (default) | mixture | thesis-pairs | mean posture | linear regression | default / regression |")
    print("|---|---|---|---|---|---|---|")
    models = {m: calibrate(bin_, work, "users-" + m, train, m)[0] for m in ("gaussian", "mixture", "thesis-pairs")}
    for name, (given, pred) in tasks.items():
        gi = [head.index(g) for g in given]
        pi = [head.index(p) for p in pred]
        rows_t = [r for r in rows if all(r[g] is not None for g in gi)]
        inputs = os.path.join(work, "inputs.csv")
        with open(inputs, "w") as f:
            f.write(",".join(given) + "\n")
            for r in rows_t:
                f.write(",".join(f"{r[i]:.6f}" for i in gi) + "\n")
        errs = {}
        for m, model in models.items():
            out = os.path.join(work, f"solved-{m}.csv")
            sh([bin_, "-q", "solve", "--model", model, "--inputs", inputs, "--out", out])
            sh_head, solved = read_csv(out)
            se, n = 0.0, 0
            for r, s in zip(rows_t, solved):
                for i in pi:
                    if r[i] is not None:
                        se += (s[sh_head.index(head[i])] - r[i]) ** 2
                        n += 1
            errs[m] = math.sqrt(se / n)
        se_mean = se_lr = 0.0
        n = 0
        for i in pi:
            tr = [r for r in train_rows if all(r[g] is not None for g in gi) and r[i] is not None]
            mean = sum(r[i] for r in tr) / len(tr)
            beta = lstsq([[1.0] + [r[g] for g in gi] for r in tr], [r[i] for r in tr])
            for r in rows_t:
                if r[i] is None:
                    continue
                se_mean += (mean - r[i]) ** 2
                se_lr += (beta[0] + sum(b * r[g] for b, g in zip(beta[1:], gi)) - r[i]) ** 2
                n += 1
        lr = math.sqrt(se_lr / n)
        print(f"| {name} | {errs['gaussian']:.2f} | {errs['mixture']:.2f} | {errs['thesis-pairs']:.2f} | "
              f"{math.sqrt(se_mean / n):.2f} | {lr:.2f} | {errs['gaussian'] / lr:.3f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/handskin")
    ap.add_argument("--work", default="/tmp/posture-study")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    bin_ = os.path.abspath(a.bin)
    here = os.path.dirname(os.path.abspath(__file__))
    tsv = os.path.join(here, "..", "..", "shared", "data", "mocap", "qualisys-hand-recording.tsv")
    q = os.path.join(a.work, "qualisys.csv")
    sh([bin_, "-q", "mocap", "--in", tsv, "--out", q])
    g = os.path.join(a.work, "gaussian.csv")
    sh([bin_, "-q", "synth", "angles", "--kind", "gaussian", "--rows", "8000", "--seed", "2", "--gaps", "0.05", "--out", g])
    c = os.path.join(a.work, "curved.csv")
    sh([bin_, "-q", "synth", "angles", "--kind", "curved", "--rows", "6000", "--seed", "4", "--out", c])
    people = []
    for p in range(1, 8):
        f = os.path.join(a.work, f"person{p}.csv")
        sh([bin_, "-q", "synth", "angles", "--rows", "2000", "--seed", str(p), "--person", str(p), "--gaps", "0.02", "--out", f])
        people.append(f)
    for title, name, angles, scheme in (("Shared Qualisys recording (6000 frames, 14 DOFs)", "qualisys", [q], "blocks"),
                                        ("Synthetic Gaussian, 5 % of cells empty (8000 frames, 19 DOFs)", "gaussian", [g], "blocks"),
                                        ("Synthetic curved grasp (6000 frames, 19 DOFs)", "curved", [c], "blocks"),
                                        ("Seven synthetic people, each left out in turn (2000 frames each)", "people", people,
                                         "recordings")):
        reports = {m: calibrate(bin_, a.work, name, angles, m)[1] for m in ("gaussian", "mixture", "thesis-pairs")}
        table(title, reports, scheme)
    user_path(bin_, a.work, people)


if __name__ == "__main__":
    main()
