"""Filled object meshes kept between runs: the same file and size give the same tetrahedra."""

from __future__ import annotations

import hashlib
import multiprocessing
import os
import subprocess
import sys
import time
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
    with pytest.warns(UserWarning, match="was changed after it was kept"):
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


def _scaled(target: Path, factor: float) -> None:
    """Rewrite the kept mesh ``target`` scaled by ``factor``."""
    import fem

    mesh = fem.read_mesh(target)
    fem.write_mesh(target, fem.Mesh(mesh.points * factor, mesh.cells, mesh.regions))


def test_a_kept_fill_that_is_not_the_surfaces_is_filled_again(
    cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import json
    import warnings

    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    first = mesh_object(cube, 0.04, optimize=False)
    (target,) = (tmp_path / "cache" / "objects").glob("*.vtu")
    _scaled(target, 1000.0)  # changed behind the record's back
    with pytest.warns(UserWarning) as said:
        mesh = mesh_object(cube, 0.04, optimize=False)
    assert len(said) == 1 and "was changed after it was kept: filled again" in str(said[0].message)
    assert np.ptp(mesh.points, axis=0).max() == pytest.approx(0.04, rel=1e-3)
    _scaled(target, 1000.0)  # and the record rewritten to match: the geometry tells
    record = target.with_suffix(".json")
    digest = hashlib.sha256(target.read_bytes()).hexdigest()
    record.write_text(json.dumps({"sha256": digest}))
    with pytest.warns(UserWarning) as said:
        mesh = mesh_object(cube, 0.04, optimize=False)
    assert len(said) == 1
    assert "is not a fill of the surface: it spans 40 m, the surface 0.04 m" in str(said[0].message)
    assert np.ptp(mesh.points, axis=0).max() == pytest.approx(0.04, rel=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the refill was kept: read without a word
        again = mesh_object(cube, 0.04, optimize=False)
        assert np.array_equal(again.points, mesh.points)
    assert first.n_points > 0


def _box() -> tuple:
    """A 40 mm box of bricks and its boundary triangles (as a fill and its surface)."""
    import fem
    from contact.geometry.triangles import surface_of_mesh

    mesh = fem.box_mesh((0.04, 0.04, 0.04), (2, 2, 2), (-0.02, -0.02, -0.02))
    return mesh, (mesh.points, surface_of_mesh(mesh)[1])


def _fill_at_once(cube: Path, barrier, out, slow: float) -> None:
    """One run: wait for the other, fill ``cube`` (slowly, differently each time), report."""
    import fem
    from contact.objects.cache import cached

    box, surface = _box()

    def fill() -> fem.Mesh:
        time.sleep(slow)
        jitter = np.random.default_rng().uniform(-1e-7, 1e-7, box.points.shape)
        out.put("filled")
        return fem.Mesh(box.points + jitter, box.cells, box.regions)

    barrier.wait()
    mesh = cached(cube, "size=0.04", fill, surface)
    out.put(hashlib.sha256(mesh.points.tobytes()).hexdigest())


def test_runs_filling_at_once_share_one_mesh(
    cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    ctx = multiprocessing.get_context("fork")
    barrier, out = ctx.Barrier(2), ctx.Queue()
    runs = [ctx.Process(target=_fill_at_once, args=(cube, barrier, out, 0.5)) for _ in range(2)]
    for p in runs:
        p.start()
    said = [out.get(timeout=30) for _ in range(3)]
    for p in runs:
        p.join(timeout=30)
        assert p.exitcode == 0
    assert said.count("filled") == 1  # one fill; the other run waited for it
    meshes = [s for s in said if s != "filled"]
    assert len(meshes) == 2 and meshes[0] == meshes[1]


def test_a_lock_left_by_a_dead_run_does_not_block(
    cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from contact.objects.cache import _key, cached

    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    lock = tmp_path / "cache" / "objects" / f"{_key(cube, 'size=0.04')}.lock"
    lock.parent.mkdir(parents=True)
    code = (
        "import fcntl, os, sys; fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT); "
        "fcntl.flock(fd, fcntl.LOCK_EX); os._exit(0)"  # dies holding the lock
    )
    subprocess.run([sys.executable, "-c", code, str(lock)], check=True, timeout=30)
    assert lock.exists()
    box, surface = _box()
    start = time.monotonic()
    mesh = cached(cube, "size=0.04", lambda: box, surface)
    assert time.monotonic() - start < 2.0 and mesh is box


def test_a_mesh_kept_without_its_record_is_filled_again_quietly(
    cube: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import json
    import warnings

    from contact.objects.cache import cached

    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    box, surface = _box()
    cached(cube, "size=0.04", lambda: box, surface)
    (target,) = (tmp_path / "cache" / "objects").glob("*.vtu")
    record = target.with_suffix(".json")
    record.unlink()  # as an older cache kept its meshes
    fills = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cached(cube, "size=0.04", lambda: fills.append(1) or box, surface)
    assert fills == [1]
    kept = json.loads(record.read_text())["sha256"]
    assert kept == hashlib.sha256(target.read_bytes()).hexdigest()


def test_a_generated_tetrahedral_ball_is_meshed_alike_by_every_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from contact.objects.ball import BallSpec, make_ball

    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    spec = BallSpec(radius=0.02, element="tet", mesh_size=0.006)
    first = make_ball(spec).mesh
    assert len(list((tmp_path / "cache" / "objects").glob("*.vtu"))) == 1
    # another process (fTetWild alone would fill it otherwise each time)
    code = (
        "import numpy as np; from contact.objects.ball import BallSpec, make_ball;"
        "m = make_ball(BallSpec(radius=0.02, element='tet', mesh_size=0.006)).mesh;"
        "np.save(__import__('sys').argv[1], m.points)"
    )
    out = tmp_path / "points.npy"
    env = {**os.environ, CACHE_ENV: str(tmp_path / "cache")}
    subprocess.run([sys.executable, "-c", code, str(out)], check=True, env=env)
    assert np.array_equal(np.load(out), first.points)
    again = make_ball(spec).mesh
    assert np.array_equal(again.cells["tetra"], first.cells["tetra"])
    # another size, another centre: other meshes
    make_ball(BallSpec(radius=0.02, element="tet", mesh_size=0.005))
    make_ball(BallSpec(radius=0.02, element="tet", mesh_size=0.006, center=(0.0, 0.0, 0.1)))
    assert len(list((tmp_path / "cache" / "objects").glob("*.vtu"))) == 3
