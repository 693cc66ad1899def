"""Filled object meshes kept between runs: the same file and size give the same tetrahedra."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from contact.objects import mesh_object
from contact.objects.cache import CACHE_ENV, cache_dir


@pytest.fixture
def cube(tmp_path: Path) -> Path:
    """A 40 mm cube of 12 triangles: a quick fill."""
    import pyvista as pv

    path = tmp_path / "cube.stl"
    pv.Cube(x_length=0.04, y_length=0.04, z_length=0.04).triangulate().save(path)
    return path


def test_a_second_fill_reads_the_first(
    cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    first = mesh_object(cube, 0.04, optimize=False)
    kept = list((tmp_path / "cache" / "objects").glob("*.vtu"))
    assert len(kept) == 1
    again = mesh_object(cube, 0.04, optimize=False)
    assert np.array_equal(again.points, first.points)
    assert np.array_equal(again.cells["tetra"], first.cells["tetra"])
    # another size is another mesh; a file that cannot be read is filled again
    mesh_object(cube, 0.03, optimize=False)
    assert len(list((tmp_path / "cache" / "objects").glob("*.vtu"))) == 2
    kept[0].write_bytes(b"not a mesh")
    refilled = mesh_object(cube, 0.04, optimize=False)
    assert refilled.n_points > 0 and kept[0].stat().st_size > 100


def test_off_keeps_nothing(cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(CACHE_ENV, "off")
    assert cache_dir() is None
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    mesh_object(cube, 0.03, optimize=False)
    assert not (tmp_path / ".cache").exists()


def test_a_cache_that_cannot_be_written_is_skipped(
    cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should be")
    monkeypatch.setenv(CACHE_ENV, str(blocker))
    mesh = mesh_object(cube, 0.03, optimize=False)
    assert mesh.n_points > 0
