"""Shared tiny fixtures built in code."""

from __future__ import annotations

import pytest

import fem
from tests.helpers import distort, mixed_mesh


@pytest.fixture
def steel() -> fem.LinearElastic:
    return fem.LinearElastic(E=210e9, nu=0.3, density=7850.0)


@pytest.fixture(params=["tetra", "hexahedron", "wedge", "mixed"])
def any_mesh(request: pytest.FixtureRequest) -> fem.Mesh:
    if request.param == "mixed":
        return distort(mixed_mesh(), 0.15, seed=3)
    return distort(fem.box_mesh((1.0, 1.2, 0.8), (3, 3, 3), element=request.param), 0.15)
