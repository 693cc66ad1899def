"""The README's example runs and writes a result a user can open."""

import json
import runpy
import sys
from pathlib import Path

import numpy as np

import fem

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "thick_sphere.py"


def test_thick_sphere_example(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["thick_sphere.py", "--out", str(tmp_path), "--size", "0.003"])
    namespace = runpy.run_path(str(EXAMPLE), run_name="example")
    assert namespace["main"]() == 0
    summary = json.loads((tmp_path / "thick_sphere.json").read_text())
    assert summary["max_relative_error"] < 0.05
    mesh, point_data, cell_data = fem.read_mesh_data(tmp_path / "thick_sphere.vtu")
    assert mesh.n_points == summary["nodes"]
    u = np.asarray(point_data["displacement"])
    assert np.abs(u).max() > 0
    assert "von_mises" in cell_data
