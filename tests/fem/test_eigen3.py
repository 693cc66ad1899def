"""The closed-form 3 x 3 eigen- and singular value decompositions against LAPACK."""

from __future__ import annotations

import numpy as np
import pytest

from fem.eigen3 import CLOSED_FORM_FROM, eigh3, rotation_svd3


def _matrices(n: int = 2000) -> np.ndarray:
    """Random 3 x 3 matrices with the hard cases first: repeated, flat, zero, rank one."""
    rng = np.random.default_rng(3)
    f = rng.normal(size=(n, 3, 3))
    f[:5] = np.eye(3)
    f[5:10] = np.diag([1.0, 1.0, -0.5])  # an inverted one, a repeated pair
    f[10:15] = np.diag([1e-9, 1.0, 2.0])  # nearly flat
    f[15:20] = -np.eye(3)
    f[20:25] = 0.0
    f[25:30] = np.outer([1.0, 2.0, 3.0], [0.5, -1.0, 2.0])  # rank one
    f[30:35] = np.diag([1.0, 1.0 + 1e-9, 2.0])  # nearly repeated
    f[35:40] = np.eye(3) + 1e-8 * rng.normal(size=(5, 3, 3))
    f[40:45] = np.diag([3.0, 0.0, 0.0])  # a line
    # the rest turned by random rotations, so that no case is axis-aligned
    r = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    f[45:] = r[45:] @ f[45:] @ np.transpose(r[45:], (0, 2, 1))
    return f


@pytest.fixture(params=["closed form", "lapack"])
def count(request) -> int:
    """Stacks long enough for the closed forms, and short enough for LAPACK."""
    return 2000 if request.param == "closed form" else CLOSED_FORM_FROM - 1


def test_eigh3_is_lapacks_eigendecomposition(count):
    f = _matrices(count)
    a = f + np.transpose(f, (0, 2, 1))
    a[45:60] = np.transpose(f[45:60], (0, 2, 1)) @ f[45:60]  # positive semidefinite ones
    w, v = eigh3(a)
    scale = np.abs(a).max(axis=(1, 2)) + 1e-300
    residual = np.abs(a @ v - v * w[:, None, :]).max(axis=(1, 2)) / scale
    assert residual.max() < 1e-14
    np.testing.assert_allclose(
        np.transpose(v, (0, 2, 1)) @ v, np.broadcast_to(np.eye(3), a.shape), atol=1e-14
    )
    assert (np.diff(w, axis=1) >= 0.0).all()
    np.testing.assert_allclose(w, np.linalg.eigh(a)[0], rtol=0.0, atol=1e-14 * scale.max())
    # exactly repeated: any orthonormal basis of the eigenspace, the values exact
    np.testing.assert_allclose(w[:5], 2.0, atol=1e-15)
    np.testing.assert_allclose(w[20:25], 0.0, atol=0.0)


def test_rotation_svd3_is_a_proper_rotation_svd(count):
    f = _matrices(count)
    u, s, vt = rotation_svd3(f)
    eye = np.broadcast_to(np.eye(3), f.shape)
    np.testing.assert_allclose(u @ np.transpose(u, (0, 2, 1)), eye, atol=1e-14)
    np.testing.assert_allclose(vt @ np.transpose(vt, (0, 2, 1)), eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(u), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(vt), 1.0, atol=1e-14)
    scale = np.abs(f).max(axis=(1, 2))[:, None, None] + 1e-300
    np.testing.assert_allclose((u * s[:, None, :]) @ vt / scale, f / scale, rtol=0.0, atol=1e-14)
    tie = 1e-14 * scale[:, 0, 0]  # round-off between repeated values
    assert (s[:, 0] >= s[:, 1] - tie).all() and (s[:, 1] >= np.abs(s[:, 2]) - tie).all()
    np.testing.assert_allclose(np.abs(s), np.linalg.svd(f, compute_uv=False), atol=1e-14 * 10)
    det = np.linalg.det(f)
    signed = np.abs(det) > 1e-12
    assert (np.sign(s[signed, 2]) == np.sign(det[signed])).all()
    np.testing.assert_allclose(s[5:10], np.broadcast_to([1.0, 1.0, -0.5], (5, 3)), atol=1e-15)
    np.testing.assert_allclose(s[15:20], np.broadcast_to([1.0, 1.0, -1.0], (5, 3)), atol=1e-15)
    np.testing.assert_allclose(s[40:45], np.broadcast_to([3.0, 0.0, 0.0], (5, 3)), atol=1e-15)


@pytest.mark.parametrize("func", [eigh3, rotation_svd3])
def test_not_a_stack_of_3x3_is_an_error(func):
    with pytest.raises(ValueError, match="3 x 3"):
        func(np.zeros((4, 2, 2)))
