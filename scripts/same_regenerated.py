#!/usr/bin/env python3
"""Compare a committed folder with a fresh regeneration of it (scripts/check_regenerated.sh).

    python3 scripts/same_regenerated.py <committed> <regenerated>

Every file must be present in both. Files must be byte-identical, except JSON files, whose
structure, keys, strings and integers must be identical and whose floating-point numbers may
differ by a relative 1e-9 (at least 1e-12 absolute): the same code gives the same bytes on
one machine, but glibc picks its exp/log/pow variants by the processor (FMA or not), so
iterative fits (the mixture's EM) can differ in the last bits between machines. A stale file
(the generator changed) differs far more than that. Prints each difference, one line each,
and exits 1 when there is any.
"""
import json
import math
import os
import sys

REL = 1e-9
ABS = 1e-12


def walk(a, b, where, out):
    if isinstance(a, bool) or isinstance(b, bool) or isinstance(a, int) and isinstance(b, int):
        if a != b or type(a) is not type(b):
            out.append(f"{where}: {a!r} != {b!r}")
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if not (math.isfinite(a) and math.isfinite(b)):
            if not (a == b or (math.isnan(a) and math.isnan(b))):
                out.append(f"{where}: {a!r} != {b!r}")
        elif abs(a - b) > max(ABS, REL * max(abs(a), abs(b))):
            out.append(f"{where}: {a!r} != {b!r} (beyond a relative {REL})")
    elif isinstance(a, dict) and isinstance(b, dict):
        if list(a.keys()) != list(b.keys()):
            out.append(f"{where}: keys {sorted(set(a) ^ set(b)) or 'in another order'}")
        for k in a:
            if k in b:
                walk(a[k], b[k], f"{where}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{where}: {len(a)} entries != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{where}[{i}]", out)
    elif a != b:
        out.append(f"{where}: {a!r} != {b!r}")


def files(root):
    return sorted(os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs)


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    old, new = sys.argv[1:]
    fo, fn = files(old), files(new)
    diffs = [f"only in {old}: {f}" for f in sorted(set(fo) - set(fn))]
    diffs += [f"only in the regeneration: {f}" for f in sorted(set(fn) - set(fo))]
    for f in sorted(set(fo) & set(fn)):
        a, b = open(os.path.join(old, f), "rb").read(), open(os.path.join(new, f), "rb").read()
        if a == b:
            continue
        if not f.endswith(".json"):
            diffs.append(f"{f}: the bytes differ")
            continue
        try:
            ja, jb = json.loads(a), json.loads(b)
        except ValueError as e:
            diffs.append(f"{f}: not JSON ({e})")
            continue
        out = []
        walk(ja, jb, f, out)
        diffs += out[:20] + ([f"{f}: {len(out) - 20} more"] if len(out) > 20 else [])
    for d in diffs:
        print(d)
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
