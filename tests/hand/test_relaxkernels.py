"""The relaxer's compiled kernels against their numpy reference and against plain algebra."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import fem
from contact.hand import blockcg, relaxkernels
from contact.hand.quality import tet_quality, tet_volumes
from contact.hand.relax import FleshRelaxer
from contact.hand.relax_reference import terms
from contact.hand.relaxkernels import EXACT_J
from contact.hand.relaxnewton import _CG_RTOL


def _box_relaxer() -> FleshRelaxer:
    """A 4 x 4 x 4 Kuhn-split box, its boundary held (384 tetrahedra, 27 free nodes)."""
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (4, 4, 4), element="tetra")
    pts = mesh.points
    boundary = np.any((pts <= 1e-12) | (pts >= 1.0 - 1e-12), axis=1)
    return FleshRelaxer(pts, mesh.cells["tetra"], boundary)


def _entry_slots(pair_slot: np.ndarray, pair_diag: np.ndarray, ndata: int) -> np.ndarray:
    """The value index of every entry of the (m, 12, 12) element matrices, raveled.

    As :func:`contact.hand.blockcg.block_pattern` says: ``pair_diag[p, 0] + i w + j``;
    ``ndata`` (one past the end: dropped) on a held node.
    """
    p = pair_slot.reshape(-1, 4, 4)
    b0 = np.append(pair_diag[:, 0], ndata)[p][:, :, None, :, None]
    w = np.append(pair_diag[:, 1] - pair_diag[:, 0] - 1, 0)[p][:, :, None, :, None]
    i = np.arange(3)
    slot = b0 + i[:, None, None] * w + i
    held = (p == len(pair_diag))[:, :, None, :, None]
    return np.where(held, ndata, slot).ravel()


def _reference(relaxer: FleshRelaxer, x: np.ndarray, free: np.ndarray, delta: float) -> tuple:
    """The numpy reference terms assembled on the kernels' pattern."""
    cells = relaxer.mesh.cells(free)
    tets = relaxer.tets[cells]
    patch = relaxer.mesh.gather(cells)
    local = np.full(len(x), -1)
    local[free] = np.arange(len(free))
    dof = (3 * local[tets][:, :, None] + np.arange(3)).reshape(-1, 12)
    dof[np.repeat(local[tets] < 0, 3, axis=1)] = -1
    n = 3 * len(free)
    indptr, indices, diag, pair_slot, pair_diag = blockcg.block_pattern(local[tets], len(free))
    slot = _entry_slots(pair_slot, pair_diag, len(indices))
    e, g, hk, lap = terms(x, patch, delta, relaxer.kappa)
    gslot = dof.ravel()
    keep = gslot >= 0
    grad = np.bincount(gslot[keep], g.reshape(-1)[keep], minlength=n)
    data = np.bincount(slot, hk.ravel(), minlength=len(indices) + 1)[:-1]
    data[pair_diag] += np.bincount(pair_slot, lap.ravel(), minlength=len(pair_diag) + 1)[:-1, None]
    kernel = relaxkernels.step_terms(
        x, tets, patch["dmat"], patch["ddt"], patch["vol"], delta * delta, relaxer.kappa,
        EXACT_J, gslot, pair_slot, pair_diag, n, len(indices),
    )  # fmt: skip
    j = np.linalg.det(
        np.transpose(x[tets], (0, 2, 1)) @ patch["dmat"]
    )  # which path each tetrahedron took
    return (float(e.sum()), grad, data), kernel, (indptr, indices, diag), j, patch


@pytest.mark.parametrize(
    "case",
    ["fair", "noisy", "inverted", "collapsed", "flat", "rotated"],
)
def test_step_terms_equal_the_numpy_reference(case):
    relaxer = _box_relaxer()
    rest = relaxer.rest
    free = np.flatnonzero(~relaxer.fixed)
    x = rest.copy()
    rng = np.random.default_rng(1)
    if case == "fair":
        x[free] += 0.01 * rng.standard_normal((len(free), 3))
    elif case == "noisy":  # fair, degenerate and inverted tetrahedra mixed
        x[free] += 0.15 * rng.standard_normal((len(free), 3))
    elif case == "inverted":  # the free nodes mirrored through the centre: F = -I inside
        x[free] = 1.0 - rest[free]
    elif case == "collapsed":  # every free node on one point: rank-deficient F
        x[free] = 0.5
    elif case == "flat":  # the free nodes on the plane z = 0.5
        x[free, 2] = 0.5
    else:  # the interior turned rigidly: repeated singular values, J = 1 inside
        c, s = np.cos(0.3), np.sin(0.3)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        x[free] = (rest[free] - 0.5) @ rot.T + 0.5
    (e, grad, data), (e2, grad2, data2), _, j, _ = _reference(relaxer, x, free, 0.01)
    if case in ("noisy", "inverted", "collapsed", "flat"):
        assert (j <= EXACT_J).any()  # the degenerate path is exercised
    if case in ("fair", "rotated"):
        assert (j > EXACT_J).all()
    assert e2 == pytest.approx(e, rel=1e-12)
    scale = np.abs(grad).max()
    np.testing.assert_allclose(grad2, grad, rtol=0, atol=1e-11 * max(scale, 1e-300))
    np.testing.assert_allclose(data2, data, rtol=0, atol=1e-11 * np.abs(data).max())


def test_patch_energy_is_the_terms_energy():
    relaxer = _box_relaxer()
    free = np.flatnonzero(~relaxer.fixed)
    x = relaxer.rest.copy()
    x[free] += 0.15 * np.random.default_rng(2).standard_normal((len(free), 3))
    for delta in (1e-3, 1e-2, 0.3):
        (e, _, _), _, _, _, patch = _reference(relaxer, x, free, delta)
        got = relaxkernels.patch_energy(
            x, patch["tets"], patch["dmat"], patch["vol"], delta * delta, relaxer.kappa
        )
        assert got == pytest.approx(e, rel=1e-13)


def test_block_cg_solves_to_its_tolerance():
    relaxer = _box_relaxer()
    free = np.flatnonzero(~relaxer.fixed)
    x = relaxer.rest.copy()
    x[free] += 0.1 * np.random.default_rng(3).standard_normal((len(free), 3))
    (_, grad, data), _, (indptr, indices, diag), _, _ = _reference(relaxer, x, free, 0.01)
    n = len(grad)
    a = sp.csr_matrix((data, indices, indptr), shape=(n, n))
    exact = sp.linalg.spsolve(a.tocsc(), grad)
    for rtol in (_CG_RTOL, 1e-12):
        got = blockcg.block_cg(indptr, indices, data, diag, grad, rtol, 1000)
        assert np.linalg.norm(a @ got - grad) <= rtol * np.linalg.norm(grad)
    np.testing.assert_allclose(got, exact, rtol=0, atol=1e-9 * np.abs(exact).max())
    # one iteration: the preconditioned steepest-descent step from zero, no more
    one = blockcg.block_cg(indptr, indices, data, diag, grad, 1e-12, 1)
    blocks = np.linalg.inv(data[diag].reshape(-1, 3, 3))
    z = np.einsum("kij,kj->ki", blocks, grad.reshape(-1, 3)).ravel()
    np.testing.assert_allclose(one, (grad @ z) / (z @ (a @ z)) * z, rtol=1e-12)


def test_volumes_and_qualities_by_plain_algebra():
    rng = np.random.default_rng(4)
    points = rng.normal(size=(500, 3))
    tets = rng.integers(0, 500, size=(300, 4))
    a, b, c = (points[tets[:, k]] - points[tets[:, 0]] for k in (1, 2, 3))
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    edges = [a, b, c, b - a, c - a, c - b]
    lrms = np.sqrt(sum((e * e).sum(axis=1) for e in edges) / 6.0)
    np.testing.assert_allclose(tet_volumes(points, tets), vol, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(
        tet_quality(points, tets), 6.0 * np.sqrt(2.0) * vol / lrms**3, rtol=1e-12, atol=1e-15
    )
    regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    assert tet_quality(regular, [[0, 2, 1, 3]])[0] == pytest.approx(1.0, rel=1e-14)
    assert tet_quality(regular, [[0, 1, 2, 3]])[0] == pytest.approx(-1.0, rel=1e-14)


def test_volumes_refuse_bad_input():
    with pytest.raises(ValueError, match=r"\(N, 3\).*\(M, 4\)"):
        tet_volumes(np.zeros((4, 2)), [[0, 1, 2, 3]])
    with pytest.raises(ValueError, match=r"outside 0\.\.3"):
        tet_quality(np.zeros((4, 3)), [[0, 1, 2, 4]])


@pytest.mark.parametrize(("nodes", "m"), [(40, 200), (6, 3), (3000, 500)])
def test_block_pattern_is_the_pattern_of_the_assembled_matrix(nodes, m):
    """The node-pair pattern, spread to 3 x 3 blocks, assembles what scipy's COO sum does.

    Random tetrahedra with held nodes (-1); few cells on many nodes leave nodes in no
    tetrahedron (empty rows), as (6, 3) may leave some whole tetrahedra held.
    """
    rng = np.random.default_rng(1)
    lt = rng.integers(-1, nodes, (m, 4))
    indptr, indices, diag, pair_slot, pair_diag = blockcg.block_pattern(lt, nodes)
    slot = _entry_slots(pair_slot, pair_diag, len(indices))
    dof = (3 * lt[:, :, None] + np.arange(3)).reshape(-1, 12)
    dof[np.repeat(lt < 0, 3, axis=1)] = -1
    rows = np.broadcast_to(dof[:, :, None], (m, 12, 12)).ravel()
    cols = np.broadcast_to(dof[:, None, :], (m, 12, 12)).ravel()
    keep = (rows >= 0) & (cols >= 0)
    assert np.array_equal(slot == len(indices), ~keep)  # entries on a held node: dropped
    values = rng.normal(size=keep.sum())
    data = np.bincount(slot[keep], values, minlength=len(indices))
    got = sp.csr_matrix((data, indices, indptr), shape=(3 * nodes, 3 * nodes))
    assert got.has_sorted_indices
    n = 3 * nodes
    expect = sp.csr_matrix((values, (rows[keep], cols[keep])), shape=(n, n))
    assert abs(got - expect).max() <= 1e-12
    blocks = data[diag].reshape(-1, 3, 3)
    present = np.unique(lt[lt >= 0])
    for b, node in zip(blocks, present, strict=True):
        np.testing.assert_allclose(
            b, expect[3 * node : 3 * node + 3, 3 * node : 3 * node + 3].toarray()
        )
    # element matrices L x I3, assembled on the node pairs, as the 12 x 12 ones
    lap = rng.normal(size=(m, 4, 4))
    full = np.einsum("mab,ij->maibj", lap, np.eye(3)).reshape(-1)
    data = np.bincount(slot, full, minlength=len(indices) + 1)[:-1]
    pairs = np.bincount(pair_slot, lap.ravel(), minlength=len(pair_diag) + 1)[:-1]
    on_pairs = np.zeros(len(indices))
    on_pairs[pair_diag] += pairs[:, None]
    np.testing.assert_allclose(on_pairs, data, rtol=0.0, atol=1e-12)


def test_untangle_terms_by_volumes_and_finite_differences():
    """``sum V_rest max(0, t - J)^2`` from the volumes, its gradient by central differences."""
    relaxer = _box_relaxer()
    free = np.flatnonzero(~relaxer.fixed)
    x = relaxer.rest.copy()
    x[free] += 0.15 * np.random.default_rng(5).standard_normal((len(free), 3))
    cells = relaxer.mesh.cells(free)
    tets = relaxer.tets[cells]
    local = np.full(len(x), -1)
    local[free] = np.arange(len(free))
    vol, dmat = relaxer.mesh.vol[cells], relaxer.mesh.dmat[cells]
    target = 0.05

    def energy(y: np.ndarray) -> tuple[float, np.ndarray]:
        return relaxkernels.untangle_terms(y, tets, local[tets], dmat, vol, target, len(free))

    e, grad = energy(x)
    j = tet_volumes(x, tets) / vol
    assert (j < target).sum() >= 5  # some tetrahedra are short of the target
    assert e == pytest.approx(float(vol @ np.maximum(target - j, 0.0) ** 2), rel=1e-12)
    h = 1e-7
    moving = np.flatnonzero(grad)  # the DOFs of the tetrahedra short of the target
    assert moving.size >= 12
    for k in np.random.default_rng(6).choice(moving, 12, replace=False):
        y = x.copy()
        y[free[k // 3], k % 3] += h
        up = energy(y)[0]
        y[free[k // 3], k % 3] -= 2 * h
        down = energy(y)[0]
        fd = (up - down) / (2 * h)
        assert grad[k] == pytest.approx(fd, rel=1e-5, abs=1e-9 * np.abs(grad).max())


def test_block_cg_refuses_a_matrix_not_of_3x3_blocks():
    """The product by blocks reads one column index a block: a plain CSR matrix (here a
    tridiagonal one) is refused, not multiplied wrongly."""
    n = 6
    a = sp.diags([-1.0, 4.0, -1.0], [-1, 0, 1], shape=(n, n), format="csr")
    indptr, indices = a.indptr.astype(np.int64), a.indices.astype(np.int64)
    diag = np.arange(18)
    with pytest.raises(ValueError, match="3 x 3 blocks"):
        blockcg.block_cg(indptr, indices, a.data, diag, np.ones(n), 1e-8, 100)
    with pytest.raises(ValueError, match="3 rows a node"):
        blockcg.block_cg(indptr, indices, a.data, diag, np.ones(5), 1e-8, 100)
