"""An object's fill estimated from its target edge: a scan of millions of triangles fits."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from contact.errors import ObjectError
from contact.objects.meshing import _check_fill
from contact.scene import sizing

PREFIX = "object[0].mesh = 'scan.stl': "


@pytest.fixture(scope="module")
def scan() -> tuple[np.ndarray, np.ndarray]:
    """A sphere of radius 30 mm in two million triangles, as a scan gives it."""
    import pyvista as pv

    s = pv.Sphere(radius=0.03, theta_resolution=1000, phi_resolution=1002)
    return np.asarray(s.points, np.float64), np.asarray(s.regular_faces, np.int64)


def test_a_scan_fills_at_its_own_size(
    scan: tuple[np.ndarray, np.ndarray],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    points, tri = scan
    assert len(tri) == 2_000_000
    monkeypatch.setattr(sizing, "available_memory", lambda: 16e9)
    with caplog.at_level(logging.WARNING):
        _check_fill(points, tri, 0.06, PREFIX, sizing.ENVELOPE)  # its own size: no refusal
    (said,) = [r.getMessage() for r in caplog.records]
    assert said.startswith(f"{PREFIX}2000000 triangles: fTetWild takes minutes on them; ")
    assert "simplify it to about" in said and ".decimate(0.99" in said
    size = sizing.fill_size(1.13e-4, 1.13e-2, 0.104, len(tri), 0.06)
    assert size.nodes < 1e4 and size.memory < 5e9  # the input's 1e6 nodes would be 138 GB


def test_a_scan_too_big_to_fill_is_told_to_be_simplified(
    scan: tuple[np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    points, tri = scan
    monkeypatch.setattr(sizing, "available_memory", lambda: 2e9)
    with pytest.raises(ObjectError) as info:
        _check_fill(points, tri, 0.01, PREFIX, sizing.ENVELOPE)
    msg = str(info.value)
    assert msg.startswith(f"{PREFIX}2000000 triangles, too many to fill: fTetWild needs about ")
    assert "2 GB available: simplify it to about" in msg and "\n" not in msg
