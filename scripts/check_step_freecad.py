#!/usr/bin/python3
"""FreeCAD reads handskin's patches.step (issue 40): a client the project does not hold.

    python3 scripts/check_step_freecad.py RUN_DIR

RUN_DIR holds patches.step and patches.json (a `run` or `patches` output folder). FreeCAD
(Debian's freecad-python3, no GUI) imports the STEP file; the check passes when FreeCAD finds
one face per patch, one shell, closed (a solid), valid, its bounding box equal to the
patches' control points' box (an untessellated Bézier face is bounded by its control points),
and the surface's exact box within 0.25 mm of its samples' box (patches.ply, the tessellation, whose
vertices lie on the surface but miss its extremes between them: 0.12 mm on the fixture). Prints the figures; exit 0 when every
check holds, 1 otherwise.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ply_util import read_ply  # noqa: E402  (numpy: Debian python3-numpy)

FREECAD_LIB = "/usr/lib/freecad-python3/lib"


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    run = sys.argv[1]
    sys.path.append(FREECAD_LIB)
    try:
        import FreeCAD  # noqa: F401
        import Part
    except ImportError as e:
        print(f"error: FreeCAD is not importable from {FREECAD_LIB} ({e}); install Debian's freecad-python3",
              file=sys.stderr)
        return 1
    patches = json.load(open(os.path.join(run, "patches.json")))["patches"]
    shape = Part.Shape()
    shape.read(os.path.join(run, "patches.step"))
    faces, shells, solids = len(shape.Faces), len(shape.Shells), len(shape.Solids)
    closed = all(s.isClosed() for s in shape.Shells)
    valid = shape.isValid()
    bb = shape.BoundBox
    lo = [min(c[k] for p in patches for c in p["control_points"]) for k in range(3)]
    hi = [max(c[k] for p in patches for c in p["control_points"]) for k in range(3)]
    box_err = max(max(abs(a - b) for a, b in zip((bb.XMin, bb.YMin, bb.ZMin), lo)),
                  max(abs(a - b) for a, b in zip((bb.XMax, bb.YMax, bb.ZMax), hi)))
    verts, _ = read_ply(os.path.join(run, "patches.ply"), "patches.ply")
    slo = [float(verts[k].min()) for k in "xyz"]
    shi = [float(verts[k].max()) for k in "xyz"]
    # The surface's own box (OCCT's optimal box, no tessellation) against the box of the
    # patches' samples (patches.ply: their tessellation, every vertex on the surface).
    ob = shape.optimalBoundingBox(False)  # not from a tessellation
    surf_err = max(max(abs(a - b) for a, b in zip((ob.XMin, ob.YMin, ob.ZMin), slo)),
                   max(abs(a - b) for a, b in zip((ob.XMax, ob.YMax, ob.ZMax), shi)))
    print(f"FreeCAD {'.'.join(FreeCAD.Version()[:3])}: {faces} faces for {len(patches)} patches, {shells} shell(s), "
          f"{solids} solid(s), closed {closed}, valid {valid}, volume {shape.Volume:.0f} mm^3; its box off the "
          f"control points' by {box_err:.2e} mm; the surface's exact box off its samples' (patches.ply) by "
          f"{surf_err:.3f} mm")
    ok = faces == len(patches) and shells == 1 and closed and solids == 1 and valid and box_err < 1e-5 \
        and surf_err < 0.25 and shape.Volume > 0
    if not ok:
        print("error: FreeCAD's reading of patches.step does not hold one closed shell of one face per patch",
              file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
