"""Compressible neo-Hookean elasticity at finite strain: energy, internal forces, tangent.

The law is FEBio's "neo-Hookean" (Bonet and Wood's compressible form)::

    W(F) = mu / 2 (I1 - 3) - mu ln J + lambda / 2 (ln J)^2,   I1 = tr(F^T F),  J = det F

with ``lambda, mu`` the Lame parameters of ``E, nu``: at small strain it is the linear
model. Total Lagrangian: everything is integrated on the reference configuration with
``F = I + grad_X u``, so a rigid rotation of any angle carries no stress.

Without locking near ``nu = 1/2``: the volumetric energy ``kappa / 2 (ln J)^2``
(``kappa = lambda + 2 mu / 3``) is taken from a volume average of ``J`` instead of the
pointwise one, as the linear elements take their dilatation (:mod:`fem.assembly`,
:mod:`fem.nodalpressure`)::

    Pi = sum_q w_q W_c(F_q) + sum_g V_g kappa / 2 (ln Jbar_g)^2,   Jbar_g = v_g / V_g

``W_c = W - kappa / 2 (ln J)^2`` is the law less its pointwise volumetric part (the same
formula with ``lambda - kappa = -2 mu / 3`` for ``lambda``), and the groups ``g`` are
the bricks and wedges themselves (the finite-strain mean dilatation) and, for the
tetrahedra, the nodes (``v_n = sum_e v_e / 4``: Bonet and Burton's average nodal
volume). Where ``J`` is uniform the averages are ``J`` and the law is exact; at small
strain the energy is the linear B-bar and nodal-pressure elements' to second order. The
energy is one function of the nodes, so its tangent is symmetric.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .assembly import assemble_blocks
from .dofs import element_dofs
from .eigen3 import eigh3
from .elements import ELEMENTS
from .errors import MaterialError
from .mapping import det3, gradients, inv3
from .material import LinearElastic, lame_fields
from .mesh import Mesh

__all__ = [
    "FiniteStrain",
    "cauchy_stress",
    "finite_strain",
    "jacobian_less_one",
    "log_strain",
    "neo_hookean",
]


def neo_hookean(
    h: NDArray[np.float64], lam: ArrayLike, mu: ArrayLike, *, tangent: bool = True
) -> tuple[NDArray, NDArray, NDArray | None]:
    """Energy density, first Piola-Kirchhoff stress and its derivative at ``F = I + H``.

    Written in the displacement gradient ``H`` so that a small strain keeps its digits:
    ``I1 - 3 = 2 tr H + H : H``, ``J - 1`` from the invariants of ``H`` and
    ``F - F^-T = H + (F^-1 H)^T``.

    Parameters
    ----------
    h : ndarray, shape (..., 3, 3)
        Displacement gradients ``H = grad_X u``, ``det(I + H) > 0``.
    lam, mu : array_like, broadcastable to ``h.shape[:-2]``
        Lame parameters (Pa).
    tangent : bool
        Compute ``a`` too (None otherwise).

    Returns
    -------
    w : ndarray, shape (...)
        ``W(F)`` (J/m^3).
    p : ndarray, shape (..., 3, 3)
        ``P = mu (F - F^-T) + lambda ln J F^-T`` (Pa).
    a : ndarray, shape (..., 3, 3, 3, 3)
        ``A_ijkl = d P_ij / d F_kl = mu d_ik d_jl + (mu - lambda ln J) Fi_li Fi_jk
        + lambda Fi_ji Fi_lk`` with ``Fi = F^-1``.
    """
    lam = np.asarray(lam, dtype=np.float64)
    mu = np.asarray(mu, dtype=np.float64)
    f = np.eye(3) + h
    jm1 = jacobian_less_one(h)
    fi = inv3(f, 1.0 + jm1)
    fit = np.swapaxes(fi, -1, -2)
    ln = np.log1p(jm1)
    i1m3 = 2.0 * np.einsum("...ii->...", h) + np.einsum("...ij,...ij->...", h, h)
    w = mu / 2 * i1m3 - mu * ln + lam / 2 * ln**2
    f_less_fit = h + np.swapaxes(fi @ h, -1, -2)
    p = mu[..., None, None] * f_less_fit + (lam * ln)[..., None, None] * fit
    if not tangent:
        return w, p, None
    eye = np.eye(3)
    a = mu[..., None, None, None, None] * np.einsum("ik,jl->ijkl", eye, eye)
    cross = (mu - lam * ln)[..., None, None, None, None]
    a = a + cross * np.einsum("...li,...jk->...ijkl", fi, fi)
    a = a + lam[..., None, None, None, None] * np.einsum("...ji,...lk->...ijkl", fi, fi)
    return w, p, a


def jacobian_less_one(h: NDArray[np.float64]) -> NDArray[np.float64]:
    """``det(I + H) - 1 = tr H + (tr^2 H - tr H^2) / 2 + det H``, to full relative precision."""
    tr = np.einsum("...ii->...", h)
    tr2 = np.einsum("...ij,...ji->...", h, h)
    return tr + (tr * tr - tr2) / 2 + det3(h)


@dataclass(frozen=True)
class FiniteStrain:
    """A body's neo-Hookean state at displacements ``u``.

    Attributes
    ----------
    energy : float
        Stored energy (J).
    force : ndarray, shape (3N,)
        Internal forces ``d Pi / d u`` (N): what the loads and reactions balance.
    stiffness : scipy.sparse.csr_matrix, shape (3N, 3N)
        The tangent ``d^2 Pi / d u^2``, symmetric.
    """

    energy: float
    force: NDArray[np.float64]
    stiffness: sp.csr_matrix


def _law_blocks(
    g: NDArray, wdet: NDArray, fi: NDArray, p: NDArray, jm1: NDArray,
    lam: NDArray, mu: NDArray, material: bool,
) -> NDArray:
    """The law's tangent as node-pair blocks ``(M, n, n, 3, 3)``: ``int G_a A G_b``.

    With ``A_ijkl = mu d_ik d_jl + (mu - lam ln J) Fi_li Fi_jk + lam Fi_ji Fi_lk``
    (:func:`neo_hookean`) and ``h_a = F^-T G_a``, the block is ``mu (G_a . G_b) d_ik +
    (mu - lam ln J) h_b,i h_a,k + lam h_a,i h_b,k``, and ``material`` takes off the
    initial stress ``(G_a . S G_b) d_ik``, ``S = F^-1 P``.
    """
    ln = np.log1p(jm1)
    h = np.einsum("eqji,eqaj->eqai", fi, g)
    c1 = wdet * (mu[:, None] - lam[:, None] * ln)
    c2 = wdet * lam[:, None]
    out = _pair_sum(c2, h)
    out += _pair_sum(c1, h).swapaxes(-1, -2)
    gg = np.einsum("eq,eqaj,eqbj->eab", wdet * mu[:, None], g, g, optimize=True)
    if material:
        sg = np.einsum("eqjl,eqbl->eqbj", fi @ p, g)
        gg -= np.einsum("eq,eqaj,eqbj->eab", wdet, g, sg, optimize=True)
    for i in range(3):
        out[..., i, i] += gg
    return out


def _volume_terms(
    g: NDArray, wdet: NDArray, j: NDArray, fi: NDArray, hessian: bool
) -> tuple[NDArray, NDArray | None]:
    """Gradient ``(M, n, 3)`` and Hessian ``(M, n, n, 3, 3)`` of each element's volume.

    ``v = sum_q w_q det J0_q J_q``; ``dv / dx_ai = sum_q w det J0 J Fi_ji G_aj`` and
    ``d^2 v / dx_ai dx_bk = sum_q w det J0 J (Fi_ji Fi_lk - Fi_li Fi_jk) G_aj G_bl``
    (None unless ``hessian``).
    """
    wj = wdet * j
    fig = np.einsum("eqji,eqaj->eqai", fi, g)  # G_a . F^-1 per component i
    dv = np.einsum("eq,eqai->eai", wj, fig)
    if not hessian:
        return dv, None
    h = _pair_sum(wj, fig)
    return dv, h - h.swapaxes(-1, -2)


def _pair_sum(c: NDArray, v: NDArray) -> NDArray:
    """``sum_q c_q v_q,a,i v_q,b,k`` as blocks ``(M, n, n, 3, 3)``, by batched products.

    ``c (M, q)``, ``v (M, q, n, 3)``; no temporary larger than the result.
    """
    m, q, n, _ = v.shape
    flat = v.reshape(m, q, 3 * n)
    out = np.matmul(flat.swapaxes(1, 2), c[:, :, None] * flat)  # (M, (a,i), (b,k))
    return out.reshape(m, n, 3, n, 3).transpose(0, 1, 3, 2, 4)


def finite_strain(
    mesh: Mesh,
    materials: LinearElastic | Mapping[int, LinearElastic],
    u: ArrayLike,
    *,
    stiffness: bool = True,
    tangent: str = "full",
) -> FiniteStrain:
    """The neo-Hookean energy, internal forces and tangent of ``mesh`` at ``u`` (see module).

    Parameters
    ----------
    mesh : Mesh
    materials : LinearElastic or mapping of int to LinearElastic
        ``E, nu`` per region (as for :func:`fem.assemble_stiffness`).
    u : array_like, shape (3N,) or (N, 3)
        Displacements from the mesh's points (m).
    stiffness : bool
        Assemble the tangent too (False: an empty matrix, for line searches).
    tangent : {"full", "material"}
        ``"material"`` leaves out the initial-stress terms (the stress's own ``G S G^T``
        and the averaged volumes' curvature): positive semidefinite, with the six rigid
        modes of the current placement exactly as its null space, as a free body's
        solver needs; not Newton's exact tangent.

    Raises
    ------
    MaterialError
        If an element is inverted or flattened at ``u`` (``det F <= 0`` at a Gauss point).
    """
    fields = lame_fields(mesh, materials)
    ua = np.asarray(u, dtype=np.float64).reshape(-1, 3)
    n = mesh.n_points
    force = np.zeros((n, 3))
    energy = 0.0
    blocks: dict[str, list[NDArray]] = {}
    # the averaged volumetric groups: (rows of D, dv/dx entries, kappa V, v)
    d_rows, d_cols, d_vals = [], [], []
    group_v, group_vol, group_kv = [], [], []
    n_groups = 0
    tet_share: tuple | None = None
    for kind, conn in mesh.cells.items():
        lam, mu = fields[kind]
        kappa = lam + 2.0 * mu / 3.0
        g, wdet, hg, jm1 = _kinematics(mesh, kind, ua)
        j = 1.0 + jm1
        if not (j > 0).all():
            bad = int(np.flatnonzero((j <= 0).any(axis=1))[0])
            raise MaterialError(
                f"{kind} cell {bad} is inverted at this displacement (det F = "
                f"{float(j[bad].min()):.3g}): finite strain needs det F > 0"
            )
        fi = inv3(np.eye(3) + hg, j)
        w, p, _ = neo_hookean(hg, (lam - kappa)[:, None], mu[:, None], tangent=False)
        energy += float((w * wdet).sum())
        np.add.at(force, conn, np.einsum("eq,eqij,eqaj->eai", wdet, p, g))
        vol0 = wdet.sum(axis=1)
        dv, h = _volume_terms(g, wdet, j, fi, stiffness and tangent != "material")
        dvol = (wdet * jm1).sum(axis=1)  # v - V, kept apart from V for its digits
        dofs = element_dofs(conn)
        if kind == "tetra":
            # nodal groups: each node takes a quarter of its tetrahedra's volumes
            tet_share = (conn, dv, h, dvol, vol0, kappa, dofs)
            kb = 0.0
        else:
            # the element is its own group: the mean dilatation
            m = len(conn)
            d_rows.append(np.repeat(n_groups + np.arange(m), dofs.shape[1]))
            d_cols.append(dofs.ravel())
            d_vals.append(dv.reshape(m, -1).ravel())
            group_v.append(dvol)
            group_vol.append(vol0)
            group_kv.append(kappa * vol0)
            n_groups += m
            kb = 0.0
            if h is not None:
                kb = _group_slope(dvol, vol0, kappa)[:, None, None, None, None] * h
        if stiffness:
            kb = kb + _law_blocks(g, wdet, fi, p, jm1, lam - kappa, mu, tangent == "material")
            blocks.setdefault(kind, []).append(kb)
    if tet_share is not None:
        conn, dv, h, dvol, vol0, kappa, dofs = tet_share
        vn, vol_n, kv_n, on = _nodal_groups(conn, dvol, vol0, kappa, n)
        node_group = np.full(n, -1, np.int64)
        node_group[on] = n_groups + np.arange(int(on.sum()))
        # D row of node c: sum over its tetrahedra of dv_e / 4
        m = len(conn)
        d_rows.append(np.repeat(node_group[conn].ravel(), dofs.shape[1]))
        d_cols.append(np.repeat(dofs, 4, axis=0).ravel())
        d_vals.append(np.repeat(dv.reshape(m, 1, -1) / 4.0, 4, axis=1).ravel())
        group_v.append(vn[on])
        group_vol.append(vol_n[on])
        group_kv.append(kv_n[on])
        n_groups += int(on.sum())
        if h is not None:
            slope = _group_slope(vn[on], vol_n[on], kv_n[on] / vol_n[on])
            node_slope = np.zeros(n)
            node_slope[on] = slope
            ce = node_slope[conn].sum(axis=1) / 4.0
            blocks.setdefault("tetra", []).append(ce[:, None, None, None, None] * h)
    flat = force.ravel()
    size = mesh.n_dofs
    k = sp.csr_matrix((size, size))
    if n_groups:
        dmat = sp.csr_matrix(
            (np.concatenate(d_vals), (np.concatenate(d_rows), np.concatenate(d_cols))),
            shape=(n_groups, size),
        )
        gv, gvol, gkv = (np.concatenate(x) for x in (group_v, group_vol, group_kv))
        gk = gkv / gvol  # each group's bulk modulus
        ln = np.log1p(gv / gvol)  # the groups' ln Jbar (gv: v - V)
        energy += float((gkv * ln**2 / 2).sum())
        slope = _group_slope(gv, gvol, gk)  # dU/dv of U = kappa V / 2 (ln v / V)^2
        flat = flat + dmat.T @ slope
        if stiffness:
            curve = gk * gvol * (1.0 - ln) / (gvol + gv) ** 2  # d^2U / dv^2
            k = (dmat.T @ sp.diags(curve) @ dmat).tocsr()
    if stiffness and blocks:
        k = (k + assemble_blocks(mesh, blocks)).tocsr()
        k.sum_duplicates()
    return FiniteStrain(energy, flat, k)


def _group_slope(dv: NDArray, vol0: NDArray, kappa: NDArray) -> NDArray:
    """``dU / dv = kappa V ln(v / V) / v`` of ``U = kappa V / 2 (ln(v / V))^2``, ``dv = v - V``."""
    return kappa * vol0 * np.log1p(dv / vol0) / (vol0 + dv)


def cauchy_stress(
    mesh: Mesh,
    materials: LinearElastic | Mapping[int, LinearElastic],
    u: ArrayLike,
) -> dict[str, NDArray[np.float64]]:
    """Cauchy stress ``(M, q, 3, 3)`` per cell block at its Gauss points (Pa).

    ``sigma = P_c F^T / J + p I`` with ``P_c`` the stress of the law less its pointwise
    volumetric part and ``p = kappa ln Jbar / Jbar`` the averaged group's pressure (the
    element's for bricks and wedges, the mean of its nodes' for tetrahedra): where ``J``
    is uniform this is the law's ``sigma = mu (b - I) / J + lambda ln J I / J``.
    """
    fields = lame_fields(mesh, materials)
    ua = np.asarray(u, dtype=np.float64).reshape(-1, 3)
    n = mesh.n_points
    out = {}
    for kind, conn in mesh.cells.items():
        lam, mu = fields[kind]
        kappa = lam + 2.0 * mu / 3.0
        _, wdet, hg, jm1 = _kinematics(mesh, kind, ua)
        _, p, _ = neo_hookean(hg, (lam - kappa)[:, None], mu[:, None], tangent=False)
        sigma = np.einsum("eqij,eqkj->eqik", p, np.eye(3) + hg) / (1.0 + jm1)[..., None, None]
        vol0 = wdet.sum(axis=1)
        dvol = (wdet * jm1).sum(axis=1)
        if kind == "tetra":
            dv_n, vol_n, kv_n, on = _nodal_groups(conn, dvol, vol0, kappa, n)
            pn = np.zeros(n)
            pn[on] = _group_slope(dv_n[on], vol_n[on], kv_n[on] / vol_n[on])
            pressure = pn[conn].mean(axis=1)
        else:
            pressure = _group_slope(dvol, vol0, kappa)
        sigma += pressure[:, None, None, None] * np.eye(3)
        out[kind] = sigma
    return out


def log_strain(mesh: Mesh, u: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Principal logarithmic strains ``ln(lambda_i)`` ``(M, q, 3)``, ascending, per cell block.

    ``lambda_i`` the principal stretches (square roots of the eigenvalues of
    ``C = F^T F``): the finite-strain measure a ">10 % strain" reads, 0 for a rigid turn
    of any angle. ``log1p`` of ``(C - I)``'s eigenvalues keeps a small strain's digits.
    """
    ua = np.asarray(u, dtype=np.float64).reshape(-1, 3)
    out = {}
    for kind in mesh.cells:
        _, _, hg, _ = _kinematics(mesh, kind, ua)
        e2 = hg + np.swapaxes(hg, -1, -2) + np.swapaxes(hg, -1, -2) @ hg  # C - I
        w = eigh3(e2.reshape(-1, 3, 3))[0].reshape(*hg.shape[:2], 3)
        out[kind] = 0.5 * np.log1p(w)
    return out


def _nodal_groups(
    conn: NDArray[np.int64], dvol: NDArray, vol0: NDArray, kappa: NDArray, n: int
) -> tuple[NDArray, NDArray, NDArray, NDArray[np.bool_]]:
    """The tetrahedra's nodal groups: each node's ``v - V``, ``V``, ``kappa V``, and has one.

    A node takes a quarter of each of its tetrahedra's volumes.
    """
    nodes = conn.ravel()
    dv_n = np.bincount(nodes, np.repeat(dvol / 4.0, 4), minlength=n)
    vol_n = np.bincount(nodes, np.repeat(vol0 / 4.0, 4), minlength=n)
    kv_n = np.bincount(nodes, np.repeat(kappa * vol0 / 4.0, 4), minlength=n)
    return dv_n, vol_n, kv_n, vol_n > 0


def _kinematics(mesh: Mesh, kind: str, ua: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """A cell block's gradients ``G``, weights ``w det J0``, ``H = grad u`` and ``J - 1``."""
    conn = mesh.cells[kind]
    elem = ELEMENTS[kind]
    g, detj = gradients(mesh.points[conn], elem)
    hg = np.einsum("eai,eqaj->eqij", ua[conn], g)
    return g, detj * elem.weights, hg, jacobian_less_one(hg)
