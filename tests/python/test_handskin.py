"""The Python module against the CLI on the same inputs, its errors, and its threads."""
import json
import math
import os
import pathlib
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import handskin
from conftest import BIN, FIX, cli, manifest

# Outputs that carry the run's own times or paths: compared by figures, not bytes.
TIMED = {"report.json", "report.html", "registration.json"}


def test_version_is_the_programs():
    out = subprocess.run([BIN, "--version"], capture_output=True, text=True).stdout.strip()
    assert out == "handskin " + handskin.__version__


def test_the_system_python_imports_this_build_in_a_new_shell():
    # No PYTHONPATH: what scripts/install_python.sh set up (the README's set-up runs it).
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    r = subprocess.run(["/usr/bin/python3", "-c", "import handskin, sys; print(handskin.__file__)"],
                       capture_output=True, text=True, env=env, cwd="/")
    assert r.returncode == 0, r.stderr
    assert pathlib.Path(r.stdout.strip()).resolve().parent == pathlib.Path(handskin.__file__).resolve().parent


def test_run_writes_the_same_files_as_the_cli(runs):
    py, cl = manifest(runs["py"]), manifest(runs["cli"])
    assert sorted(py) == sorted(cl)
    assert "skin.glb" in py and "patches.step" in py
    for name in py:
        if name not in TIMED:
            assert py[name] == cl[name], name
    # registration.json differs only in its timings
    a, b = (json.loads((runs[k] / "registration.json").read_text()) for k in ("py", "cli"))
    assert a.pop("timings_ms") and b.pop("timings_ms") and a == b


def test_run_report_figures_equal_the_clis(runs):
    rep = runs["report"]
    cli_rep = json.loads((runs["cli"] / "report.json").read_text())
    assert rep["format"] == cli_rep["format"] == "handskin-report/1"
    # the dict returned is report.json as written
    assert rep == json.loads((runs["py"] / "report.json").read_text())

    def figures(r):  # every number but the timings and the inputs' and outputs' paths
        out = {}

        def walk(x, key):
            if isinstance(x, dict):
                for k, v in x.items():
                    if k in ("inputs", "inputs_absolute", "outputs") or "seconds" in k or k.endswith("_ms"):
                        continue
                    walk(v, key + "." + k)
            elif isinstance(x, list):
                for i, v in enumerate(x):
                    walk(v, f"{key}[{i}]")
            elif isinstance(x, (int, float)) and not isinstance(x, bool):
                out[key] = x
        walk(r, "")
        return out

    a, b = figures(rep), figures(cli_rep)
    assert len(a) > 200
    assert a.keys() == b.keys()
    assert {k: v for k, v in a.items() if v != b[k]} == {}


def test_progress_reaches_the_callback(runs):
    lines = runs["progress"]
    assert lines and all(stage == "run" for stage, _ in lines)
    text = [line for _, line in lines]
    assert any("patches" in t for t in text) and text[-1] == "writing the outputs"


def test_read_mesh_reads_what_the_project_writes(runs):
    V, F = handskin.read_mesh(runs["py"] / "skin.ply")
    assert V.dtype == np.float64 and V.shape[1] == 3 and F.dtype == np.int32 and F.shape[1] == 3
    assert F.min() == 0 and F.max() == len(V) - 1
    G, H = handskin.read_mesh(runs["py"] / "skin.glb")
    assert H.shape == F.shape and G.shape == V.shape
    assert np.abs(G - V).max() < 1e-3  # the glb stores float32 metres, skin.ply float32 mm
    P, Q = handskin.read_mesh(str(runs["py"] / "patches.ply"))
    assert len(Q) > 1000
    P, Q = handskin.read_mesh(runs["py"] / "patches.obj")  # the Bezier patches, tessellated
    assert len(Q) == 98 * 2 * 12 * 12
    assert V.flags.writeable  # the caller's own arrays


def test_posture_model_solves_as_the_cli():
    m = handskin.PostureModel("builtin:anatomical")
    assert m.name and len(m.dofs) == len(handskin.dofs()) and m.dofs == handskin.dofs()
    a = m.solve({"index.pip.flex": 60.0})
    assert set(a) == set(m.dofs) and a["index.pip.flex"] == 60.0
    out = json.loads(cli("solve", "--model", "builtin:anatomical", "--set", "index.pip.flex=60", "--json").stdout)
    assert out["angles"] == a
    d = m.solve({"index.pip.flex": 60.0}, details=True)
    assert d["format"] == "handskin-posture-solution/1" and d["angles"] == a and d["pinned"] == ["index.pip.flex"]
    lo, hi = m.limits["index.pip.flex"]
    assert lo < hi and m.relaxed["index.pip.flex"] >= lo
    # torques and soft targets, as --torque and --target
    t = m.solve(torques={"index.mcp.flex": 20.0}, targets={"middle.pip.flex": (50.0, 10.0)})
    out = json.loads(cli("solve", "--model", "builtin:anatomical", "--torque", "index.mcp.flex=20", "--target", "middle.pip.flex=50@10", "--json").stdout)
    assert out["angles"] == t
    assert m.to_dict()["format"] == "hand-posture/1"


def test_solve_batch_equals_row_by_row_and_the_clis_batch(tmp_path):
    m = handskin.PostureModel()
    cols = ["index.pip.flex", "thumb.mcp.flex"]
    X = np.array([[0.0, 10.0], [30.0, np.nan], [60.0, 40.0], [np.nan, np.nan]])
    Y = m.solve_batch(cols, X)
    assert Y.shape == (4, len(m.dofs))
    for row, y in zip(X, Y):
        pins = {c: v for c, v in zip(cols, row) if not math.isnan(v)}
        assert list(y) == list(m.solve(pins).values())
    csv = tmp_path / "in.csv"
    csv.write_text(",".join(cols) + "\n" + "\n".join(",".join("" if math.isnan(v) else repr(v) for v in r) for r in X) + "\n")
    cli("solve", "--model", "builtin:anatomical", "--inputs", csv, "--out", tmp_path / "out.csv")
    lines = (tmp_path / "out.csv").read_text().splitlines()
    header = lines[0].split(",")
    got = np.array([[float(c) for c in line.split(",")] for line in lines[1:]])
    order = [header.index(n) for n in m.dofs]
    assert np.allclose(got[:, order], Y, rtol=1e-5, atol=1e-4)  # the CSV holds 6 significant digits


def test_pose_equals_the_clis_pose(runs, tmp_path):
    glb = runs["py"] / "skin.glb"
    m = handskin.PostureModel()
    angles = m.solve({"index.pip.flex": 60.0})
    P = handskin.pose(glb, angles)
    cli("pose", "--skin", glb, "--set", "index.pip.flex=60", "--out", tmp_path / "posed.ply")
    Q, _ = handskin.read_mesh(tmp_path / "posed.ply")
    assert P.shape == Q.shape
    assert np.abs(P - Q).max() < 1e-3  # the PLY holds float32
    skin = handskin.RiggedSkin(glb)
    # a partial dict is pinned and the skin's model solves the rest (as pose --set)
    assert np.array_equal(skin.pose({"index.pip.flex": 60.0}), P)
    # every DOF as an array in dofs() order
    assert np.array_equal(skin.pose(np.array([angles[n] for n in handskin.dofs()])), P)
    assert not np.array_equal(skin.pose(angles, blend="lbs"), P)
    with pytest.raises(ValueError, match="blend"):
        skin.pose(angles, blend="smooth")
    with pytest.raises(ValueError, match="angles"):
        skin.pose([1.0, 2.0])
    assert skin.vertices.shape == P.shape and not skin.vertices.flags.writeable
    assert skin.rig["format"] == "hand-rig/1" and skin.has_texture


def test_stages_on_their_own_equal_the_run(runs, tmp_path):
    reg = handskin.register(FIX / "back", FIX / "palm")
    rj = json.loads((runs["cli"] / "registration.json").read_text())
    untimed = lambda d: {k: v for k, v in d.items() if k not in ("timings_ms", "gates", "gates_passed")}
    assert untimed(reg.figures) == untimed(rj)
    assert reg.transform.shape == (4, 4) and reg.refined and len(reg.markers) == 9
    assert np.array_equal(reg.transform, np.array(rj["back_to_palm"]))
    pts, nrm, sides = handskin.read_merged(runs["cli"] / "merged.ply")
    assert reg.points.shape == pts.shape and np.abs(reg.points - pts).max() < 1e-4  # merged.ply holds float32
    assert np.array_equal(reg.sides, sides) and set(np.unique(sides)) == {0, 1}
    skin = handskin.build_skin(reg.points, reg.normals, reg.sides, rig=FIX / "rig.json")
    V, F = handskin.read_mesh(runs["cli"] / "skin.ply")
    assert skin.faces.shape == F.shape and np.abs(skin.vertices - V).max() < 1e-3
    assert skin.watertight and not skin.automatic_rig
    # saved as the CLI writes files: a file of the user's in the way is refused, and with
    # force moved aside; its own file it replaces
    mine = tmp_path / "skin.ply"
    mine.write_text("my own skin")
    with pytest.raises(OSError, match="skin.ply: is in the way: it was not written by handskin"):
        skin.save(mine)
    assert mine.read_text() == "my own skin"
    skin.save(mine, force=True)
    assert np.array_equal(handskin.read_mesh(mine)[1], F)
    assert [p.read_text() for p in tmp_path.glob("handskin-backup-*/skin.ply")] == ["my own skin"]
    skin.save(mine)
    stages = {s["name"]: s for s in json.loads((runs["cli"] / "report.json").read_text())["stages"]}
    assert skin.figures["cloud_to_skin_mm"] == stages["skin"]["cloud_to_skin_mm"]
    patches = handskin.fit_patches(skin, reg.points, reg.sides)
    run_p = stages["patches"]
    assert len(patches.names) == run_p["patches"] == patches.bezier.shape[0]
    assert patches.bezier.shape[1:] == (4, 4, 3)
    assert np.array_equal(patches.bezier.reshape(-1, 3), patches.control[patches.patch_control.reshape(-1)])
    assert patches.figures["data_to_surface_mm"] == run_p["data_to_surface_mm"]
    assert patches.figures["table_4_1"]["cell_grid_mm"] == run_p["table_4_1"]["cell_grid_mm"]
    assert patches.to_dict()["format"] == "handskin-patches/1"


def test_bad_arguments_and_data_raise_valueerror_with_the_clis_message(tmp_path):
    m = handskin.PostureModel()
    with pytest.raises(ValueError, match="unknown DOF 'index.pip.flx'"):
        m.solve({"index.pip.flx": 10.0})
    with pytest.raises(ValueError, match=r"pins\['index.pip.flex'\]: is not finite"):
        m.solve({"index.pip.flex": float("nan")})
    with pytest.raises(ValueError, match="values: must be an"):
        m.solve_batch(["index.pip.flex"], np.zeros((3, 2)))
    with pytest.raises(ValueError, match="given twice"):
        m.solve_batch(["index.pip.flex", "index.pip.flex"], np.zeros((3, 2)))
    with pytest.raises(ValueError, match="source: unknown built-in model 'nope'"):
        handskin.PostureModel("builtin:nope")
    with pytest.raises(ValueError, match="units"):
        handskin.run(back=FIX / "back", palm=FIX / "palm", out=tmp_path / "o", units="furlong")
    with pytest.raises(ValueError, match="back and palm"):
        handskin.run(back=FIX / "back", out=tmp_path / "o")
    with pytest.raises(ValueError, match="points: must be an"):
        handskin.build_skin(np.zeros((5, 2)), np.zeros((5, 3)), np.zeros(5))
    with pytest.raises(ValueError, match="sides"):
        handskin.build_skin(np.zeros((5, 3)), np.zeros((5, 3)), np.full(5, 7))
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="bad.json"):
        handskin.PostureModel(bad)
    assert not (tmp_path / "o").exists()  # nothing was made for a refused call


def test_files_raise_oserror(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothing.ply"):
        handskin.read_mesh(tmp_path / "nothing.ply")
    with pytest.raises(FileNotFoundError):
        handskin.register(tmp_path / "none", FIX / "palm")
    with pytest.raises(FileNotFoundError, match="none.glb: no such file"):
        handskin.RiggedSkin(tmp_path / "none.glb")
    blocker = tmp_path / "afile"
    blocker.write_text("mine")
    with pytest.raises(OSError, match="afile"):
        handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json", out=blocker / "out")
    assert blocker.read_text() == "mine"
    # a user's file in the way is refused before any work, and left alone
    out = tmp_path / "out"
    out.mkdir()
    (out / "skin.ply").write_text("my own skin")
    t0 = time.monotonic()
    with pytest.raises(OSError, match="skin.ply: is in the way"):
        handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json", out=out)
    assert time.monotonic() - t0 < 2.0 and (out / "skin.ply").read_text() == "my own skin"


def test_a_failed_gate_under_strict_raises_and_writes_nothing(tmp_path):
    pipe = tmp_path / "tight.json"
    pipe.write_text(json.dumps({"format": "handskin-pipeline/1", "gates": {"cloud_to_skin_p95_mm": 0.001}}))
    out = tmp_path / "out"
    with pytest.raises(handskin.GateFailure, match=r"cloud_to_skin\.p95"):
        handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json", out=out, pipeline=pipe, strict=True)
    assert not out.exists() or not any(out.iterdir())
    assert issubclass(handskin.GateFailure, RuntimeError)


def test_a_callback_that_raises_stops_the_run_and_writes_nothing(tmp_path):
    out = tmp_path / "out"
    seen = []

    def stop(stage, line):
        seen.append(line)
        if "skin" in line:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json", out=out, progress=stop)
    assert seen and not out.exists()
    assert not list(tmp_path.glob(".handskin-staging-*"))


def test_two_runs_started_on_two_threads_at_once_equal_one(runs, tmp_path):
    spans, errors = {}, []

    def one(name):
        t0 = time.monotonic()
        try:
            handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json", out=tmp_path / name)
        except BaseException as e:  # reported below
            errors.append(e)
        spans[name] = (t0, time.monotonic())

    threads = [threading.Thread(target=one, args=(n,)) for n in ("a", "b")]
    for t in threads:
        t.start()
    # the GIL is released: this thread goes on while both run
    m = handskin.PostureModel()
    ticks = 0
    while any(t.is_alive() for t in threads):
        m.solve({"index.pip.flex": float(ticks % 90)})
        ticks += 1
    for t in threads:
        t.join()
    assert errors == []
    (a0, a1), (b0, b1) = spans["a"], spans["b"]
    assert a0 < b1 and b0 < a1  # both were under way at once (the module runs their stages one at a time)
    assert ticks > 100  # the GIL was released: this thread kept working
    ref = manifest(runs["py"])
    for name in ("a", "b"):
        got = manifest(tmp_path / name)
        assert {k for k in got} == {k for k in ref}
        for k in got:
            if k not in TIMED:
                assert got[k] == ref[k], (name, k)


def test_two_threads_share_a_model(tmp_path):
    m = handskin.PostureModel()
    X = np.linspace(0, 90, 20000).reshape(-1, 1)
    ref = m.solve_batch(["index.pip.flex"], X)
    out = [None, None]

    def one(i):
        out[i] = m.solve_batch(["index.pip.flex"], X)

    ts = [threading.Thread(target=one, args=(i,)) for i in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert np.array_equal(out[0], ref) and np.array_equal(out[1], ref)


def test_no_bad_input_crashes_each_is_a_valueerror_or_oserror(tmp_path):
    rng = np.random.default_rng(3)
    garbage_ply = tmp_path / "g.ply"
    garbage_ply.write_text("ply\nformat ascii 1.0\nelement vertex 99999999999\nend_header\n")
    garbage_glb = tmp_path / "g.glb"
    garbage_glb.write_bytes(b"glTF" + bytes(100))
    m = handskin.PostureModel()
    calls = {
        "five points": lambda: handskin.build_skin(np.zeros((5, 3)), np.zeros((5, 3)), np.zeros(5)),
        "random cloud": lambda: handskin.build_skin(rng.random((1000, 3)) * 100, rng.random((1000, 3)),
                                                    rng.integers(0, 2, 1000)),
        "no points": lambda: handskin.build_skin(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)),
        "NaN points": lambda: handskin.build_skin(np.full((5, 3), np.nan), np.zeros((5, 3)), np.zeros(5)),
        "a string for points": lambda: handskin.build_skin("abc", np.zeros((5, 3)), np.zeros(5)),
        "a rig dict that is not one": lambda: handskin.build_skin(np.zeros((5, 3)), np.zeros((5, 3)), np.zeros(5),
                                                                  rig={"a": 1}),
        "a pin that is a string": lambda: m.solve({"index.pip.flex": "y"}),
        "a pin of 1e300": lambda: m.solve({"index.pip.flex": 1e300}),
        "pins not a dict": lambda: m.solve([1, 2]),
        "a target not a pair": lambda: m.solve(targets={"index.pip.flex": 3}),
        "a negative target weight": lambda: m.solve(targets={"index.pip.flex": (3, -1)}),
        "batch of 1-D values": lambda: m.solve_batch(["index.pip.flex"], np.zeros(3)),
        "batch of infinity": lambda: m.solve_batch(["index.pip.flex"], np.array([[np.inf]])),
        "a folder as a mesh": lambda: handskin.read_mesh(tmp_path),
        "a PLY header of 1e11 vertices": lambda: handskin.read_mesh(garbage_ply),
        "a broken glb": lambda: handskin.RiggedSkin(garbage_glb),
        "a broken merged cloud": lambda: handskin.read_merged(garbage_ply),
        "a folder as scans": lambda: handskin.register(tmp_path, tmp_path),
        "run without inputs": lambda: handskin.run(out=tmp_path / "x"),
        "run on a missing cloud": lambda: handskin.run(clouds=[tmp_path / "none.ply"], out=tmp_path / "x"),
        "a negative tolerance": lambda: handskin.run(back="a", palm="b", out=tmp_path / "x", patch_tolerance=-1),
    }
    for name, call in calls.items():
        with pytest.raises((ValueError, OSError)) as e:
            call()
        assert "\n" not in str(e.value) and len(str(e.value)) < 400, name
    assert not (tmp_path / "x").exists()
