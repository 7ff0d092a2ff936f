"""handskin: range scans of a hand to a rigged, animatable skin (docs/python.md).

The same stages as the `handskin` command, over NumPy arrays and dicts:

    import handskin, numpy as np
    rep = handskin.run(back="fixtures/default/back", palm="fixtures/default/palm",
                       rig="fixtures/default/rig.json", out="out/py")      # the report as a dict
    V, F = handskin.read_mesh("out/py/skin.ply")                         # float64 (n,3), int32 (m,3)
    m = handskin.PostureModel("builtin:anatomical")                      # or a hand-posture/1 file
    angles = m.solve({"index.pip.flex": 60.0})                           # dict: every DOF, degrees
    X = m.solve_batch(["index.pip.flex"], np.array([[0.0], [30.0], [60.0]]))  # (3, len(m.dofs))
    P = handskin.pose("out/py/skin.glb", angles)                         # posed vertices (n,3)

Errors: bad data or arguments raise ValueError, files that cannot be read or written OSError
(FileNotFoundError for a missing one), with the command's one-line messages; a failed quality
gate under strict=True raises GateFailure (a RuntimeError) and writes nothing. Long calls
release the GIL, so two runs can go on two threads at once. A `progress` callable receives
(stage, line) for every progress line; if it raises, or Ctrl-C is pressed, the call stops there
and writes nothing.
"""
from __future__ import annotations

import os
from typing import Any, Callable, Mapping, Optional, Sequence, Tuple, Union

from . import _core
from ._core import (  # noqa: F401  (the public API)
    GateFailure,
    Patches,
    PostureModel,
    Registration,
    RiggedSkin,
    Skin,
)

__version__: str = _core.__version__

__all__ = [
    "__version__", "GateFailure", "Patches", "PostureModel", "Registration", "RiggedSkin", "Skin",
    "build_skin", "dofs", "fit_patches", "pose", "read_merged", "read_mesh", "register", "run",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Optional[Callable[[str, str], Any]]


def dofs() -> list:
    """The names of every degree of freedom, in the order arrays use (formats/ DOF table)."""
    return _core.dofs()


def run(back: Optional[PathLike] = None, palm: Optional[PathLike] = None, rig: Optional[PathLike] = None,
        out: Optional[PathLike] = None, *, clouds: Sequence[PathLike] = (), units: str = "mm",
        hand: Optional[str] = None, auto_rig: bool = False, markers: Optional[PathLike] = None,
        pipeline: Optional[PathLike] = None, truth: Optional[PathLike] = None,
        posture_model: str = "builtin:anatomical", patch_tolerance: Optional[float] = None,
        scan_clouds: bool = False, force: bool = False, strict: bool = False,
        progress: Progress = None) -> dict:
    """`handskin run`: the whole pipeline into the folder `out`; returns report.json as a dict.

    back, palm: the two scans' stems (`<stem>.png` + `<stem>.json`), or clouds: one merged
    cloud or two halves from any scanner (units, hand as for `run --cloud`). rig: a hand-rig/1
    file (palm frame); without it the skeleton is placed automatically. The other keywords are
    the command's flags. Everything is computed first, then written at once: a failure leaves
    `out` as it was.
    """
    return _core.run(back=_p(back), palm=_p(palm), clouds=[os.fspath(c) for c in clouds], rig=_p(rig), out=_p(out),
                     units=units, hand=hand, auto_rig=auto_rig, markers=_p(markers), pipeline=_p(pipeline),
                     truth=_p(truth), posture_model=posture_model, patch_tolerance=patch_tolerance,
                     scan_clouds=scan_clouds, force=force, strict=strict, progress=progress)


def read_mesh(path: PathLike) -> Tuple["np.ndarray", "np.ndarray"]:
    """A mesh the project writes (.ply, .obj, .off, .stl, or skin.glb's mesh) as
    (vertices float64 (n, 3) in mm, faces int32 (m, 3))."""
    return _core.read_mesh(os.fspath(path))


def read_merged(path: PathLike) -> Tuple["np.ndarray", "np.ndarray", "np.ndarray"]:
    """merged.ply (a run's merged cloud) as (points (n, 3), normals (n, 3), sides uint32 (n,)):
    side 0 is the palm scan's, 1 the back scan's — what build_skin and fit_patches take."""
    return _core.read_merged(os.fspath(path))


def pose(skin: Union[PathLike, RiggedSkin], angles: Union[Mapping[str, float], Sequence[float], "np.ndarray"], *,
         blend: str = "dqs", crease_guard: bool = True) -> "np.ndarray":
    """The skin of skin.glb (a path or a RiggedSkin) posed at `angles`: posed vertices (n, 3).

    `angles`: a dict naming every DOF (as PostureModel.solve returns), or an array of every DOF
    in dofs() order; a dict naming only some pins them and the skin's own posture model solves
    the rest (as `handskin pose --set`). blend: "dqs" or "lbs"; crease_guard as `pose`'s.
    """
    if not isinstance(skin, RiggedSkin):
        skin = RiggedSkin(os.fspath(skin))
    return skin.pose(angles, blend=blend, crease_guard=crease_guard)


def register(back: PathLike, palm: PathLike, *, markers: Optional[PathLike] = None,
             pipeline: Optional[PathLike] = None, refine: bool = True, progress: Progress = None) -> Registration:
    """`handskin register` without files: the back scan into the palm scan's frame. Returns a
    Registration (transform, merged points/normals/sides, markers, figures = registration.json)."""
    return _core.register(os.fspath(back), os.fspath(palm), markers=_p(markers), pipeline=_p(pipeline),
                          refine=refine, progress=progress)


def build_skin(points, normals, sides, *, rig: Union[None, PathLike, Mapping[str, Any]] = None,
               pipeline: Optional[PathLike] = None, auto_rig: bool = False, progress: Progress = None) -> Skin:
    """`handskin skin` on arrays: the closed skin mesh from a merged cloud (points and normals
    (n, 3) in mm, palm frame; sides 0/1 per point). rig: a hand-rig/1 path or dict; none: the
    skeleton is placed automatically. Returns a Skin (vertices, faces, rig, figures)."""
    return _core.build_skin(points, normals, sides, rig=_p(rig) if not isinstance(rig, Mapping) else dict(rig),
                            pipeline=_p(pipeline), auto_rig=auto_rig, progress=progress)


def fit_patches(skin: Skin, points, sides, *, pipeline: Optional[PathLike] = None,
                tolerance: Optional[float] = None, progress: Progress = None) -> Patches:
    """`handskin patches` on arrays: bicubic Bézier patches fitted to `points` over `skin`'s
    layout, with parameter correction (tolerance, mm: split the patches that miss it, or whose points stray near it; docs/patches.md)."""
    return _core.fit_patches(skin, points, sides, pipeline=_p(pipeline), tolerance=tolerance, progress=progress)


def _p(path):
    return None if path is None else os.fspath(path)
