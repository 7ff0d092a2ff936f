"""Shared fixtures of the Python module's tests (tests/python, run by CTest: python_module).

HANDSKIN_BIN names the `handskin` program of the same build (the CLI the module is compared
with); HANDSKIN_ROOT the source tree (fixtures/, docs/). The fixture's run is made once per
session by the module and once by the CLI, on the same inputs.
"""
import json
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(os.environ.get("HANDSKIN_ROOT", pathlib.Path(__file__).resolve().parents[2]))
BIN = os.environ.get("HANDSKIN_BIN", str(ROOT / "build" / "handskin"))
FIX = ROOT / "fixtures" / "default"


def cli(*args, check=True, cwd=None):
    """Run the handskin program; returns the CompletedProcess (text)."""
    r = subprocess.run([BIN, "-q", *map(str, args)], capture_output=True, text=True, cwd=cwd)
    if check and r.returncode != 0:
        raise AssertionError(f"handskin {' '.join(map(str, args))} exited {r.returncode}: {r.stderr}")
    return r


@pytest.fixture(scope="session")
def runs(tmp_path_factory):
    """The fixture run by the module (out_py) and by the CLI (out_cli), with the module's report."""
    import handskin

    base = tmp_path_factory.mktemp("runs")
    lines = []
    rep = handskin.run(back=FIX / "back", palm=FIX / "palm", rig=FIX / "rig.json", out=base / "py",
                       progress=lambda stage, line: lines.append((stage, line)))
    cli("run", "--back", FIX / "back", "--palm", FIX / "palm", "--rig", FIX / "rig.json", "--out", base / "cli")
    return {"py": base / "py", "cli": base / "cli", "report": rep, "progress": lines}


def manifest(folder):
    return json.loads((pathlib.Path(folder) / ".handskin-manifest.json").read_text())["files"]
