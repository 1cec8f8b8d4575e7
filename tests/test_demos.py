"""Every demo runs as a plain script at a small size (DOLFINx's habit)."""

import subprocess
import sys
from pathlib import Path

import pytest

DEMOS = sorted((Path(__file__).resolve().parent.parent / "demos").glob("*.py"))


@pytest.mark.parametrize("demo", DEMOS, ids=[d.stem for d in DEMOS])
def test_demo_runs(demo, tmp_path):
    done = subprocess.run([sys.executable, str(demo), "--cells", "80", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert list(tmp_path.glob("*.png")), "the demo wrote no plot"


def test_demos_are_jupytext_light_scripts():
    jupytext = pytest.importorskip("jupytext")
    for demo in DEMOS:
        notebook = jupytext.read(demo, fmt="py:light")
        kinds = {cell.cell_type for cell in notebook.cells}
        assert kinds == {"markdown", "code"}, demo.name
