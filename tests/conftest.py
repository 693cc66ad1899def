"""Shared tiny fixtures built in code."""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

import pytest

import fem
from contact.grasp import main
from contact.objects.cache import CACHE_ENV
from tests.helpers import distort, mixed_mesh

_CACHE = None
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def pytest_sessionstart(session: pytest.Session) -> None:
    """Filled object meshes kept in a folder of this test session's, not the user's cache."""
    global _CACHE
    if CACHE_ENV not in os.environ:
        _CACHE = tempfile.mkdtemp(prefix="grasp-contact-cache-")
        os.environ[CACHE_ENV] = _CACHE


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if _CACHE is not None:
        shutil.rmtree(_CACHE, ignore_errors=True)
        os.environ.pop(CACHE_ENV, None)


@pytest.fixture
def steel() -> fem.LinearElastic:
    return fem.LinearElastic(E=210e9, nu=0.3, density=7850.0)


@pytest.fixture(params=["tetra", "hexahedron", "wedge", "mixed"])
def any_mesh(request: pytest.FixtureRequest) -> fem.Mesh:
    if request.param == "mixed":
        return distort(mixed_mesh(), 0.15, seed=3)
    return distort(fem.box_mesh((1.0, 1.2, 0.8), (3, 3, 3), element=request.param), 0.15)


class _Records(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@pytest.fixture(scope="session")
def finger_press(tmp_path_factory):
    """The index finger pressing a ball: stdout, warnings and summary of one run.

    Shared by the report's tests and the sample report's (``docs/results.md``).
    """
    out = tmp_path_factory.mktemp("finger_press") / "results"
    stdout = io.StringIO()
    log = logging.getLogger("contact.grasp")
    records = _Records()
    log.addHandler(records)
    try:
        with contextlib.redirect_stdout(stdout):
            code = main([str(EXAMPLES / "finger_press.toml"), "--no-pictures", "--out", str(out)])
    finally:
        log.removeHandler(records)
    summary = json.loads((out / "summary.json").read_text())
    return code, stdout.getvalue().splitlines(), records.messages, summary, out
