"""Shared tiny fixtures built in code."""

from __future__ import annotations

import os
import shutil
import tempfile

import pytest

import fem
from contact.objects.cache import CACHE_ENV
from tests.helpers import distort, mixed_mesh

_CACHE = None


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
