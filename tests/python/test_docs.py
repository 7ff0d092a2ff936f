"""docs/python.md's examples, run as written (from a folder holding the project's fixtures/)."""
import os
import re

import numpy as np

from conftest import ROOT


def test_the_examples_of_docs_python_md_run(tmp_path, capsys):
    text = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) >= 3
    (tmp_path / "fixtures").symlink_to(ROOT / "fixtures")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        first = {}
        for i, code in enumerate(blocks):
            ns = {}
            exec(compile(code, f"docs/python.md example {i + 1}", "exec"), ns)
            if i == 0:
                first = ns
    finally:
        os.chdir(cwd)
    # the first example's figures, as the issue states them
    V, F, X, P, angles, m = (first[k] for k in ("V", "F", "X", "P", "angles", "m"))
    assert V.shape[1] == 3 and F.shape[1] == 3 and V.dtype == np.float64
    assert X.shape == (3, len(m.dofs)) and set(angles) == set(m.dofs)
    assert P.shape == V.shape
    assert first["rep"]["format"] == "handskin-report/1"
    assert (tmp_path / "out" / "py-auto" / "rig_auto.json").exists()
