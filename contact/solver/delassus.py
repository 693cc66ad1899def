"""The contact forces of a fixed contact set, solved in contact space.

For a fixed set of contact rows (:class:`contact.solver.rows.ContactRows`), the fixed point
of steps 3 to 5 of Gourret, Magnenat-Thalmann and Thalmann (1989) (every contact closed,
every body in equilibrium under the contact forces) solves a small dense system on the
contact forces ``lambda``::

    W lambda + G a = -(g0 + sum_b E_b u0_b)       (every gap closed)
    G^T lambda     = -Phi^T f                     (every free body in balance)

``W = sum_b E_b C_b E_b^T`` is the Delassus operator (each body's compliance ``C_b``
seen from the contact rows: ``K11^-1``, or the pseudo-inverse of a free body), ``u0_b =
C_b f_b`` each body's answer to its own loads, and ``G = [E_b Phi_b]`` the rigid modes
``Phi_b`` of the free bodies with their amplitudes ``a``. A finite-strain body's
linearisation placed by all six modes has a stiffness that its turns change: its rows
keep the linear body's compliance, bordered by eighteen columns and their stiffness ``H_b``
(:meth:`fem.TurningInverse.extended`), and the balance reads ``G^T lambda - H a = c``.
The compliance of a row is computed once by back-solves with the body's one factorisation
and kept (:meth:`fem.StaticSolver.compliance`): a contact set that changes by ``k`` rows costs
``k`` back-solves per body.

A force-driven plane (:attr:`contact.geometry.plane.Plane.force`) is one more column of
``G``: a rigid body whose one mode is its translation along its normal, loaded by its
force, so that its rows' forces sum to that force and its translation is found with them.

Where the contacts cannot balance a free body's loads (a ball on a tilted frictionless
table, or with nothing under it) the system has no solution; :meth:`ContactSpace.solve_held`
then gives the contacts' answer with the body held by a soft spring, and the load that
the spring, not the contacts, carries: the frame's "not held" result.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import NDArray

import fem
from fem.saddle import RANK_TOL, solve_saddle

from ..errors import ContactError
from .body import ElasticBody
from .contactsystem import BodyState, ContactSystem
from .lcp import LcpResult, solve_lcp

__all__ = ["SPRING", "TOUCHING", "BodyState", "ContactSpace", "ContactSystem", "held_by_springs"]

#: The stiffness of the spring that holds a free body the contacts do not
#: (:meth:`ContactSpace.solve_held`) over the contacts' (the mean diagonal of the Delassus
#: operator): soft enough that the contacts carry what they can.
SPRING = 1e-5
#: The force (over the free bodies' loads) a touching row starts from where the rows that
#: penetrate cannot hold a free body: the active set then starts with it closed.
TOUCHING = 1e-9


class ContactSpace:
    """Solve the contact forces of a fixed contact set for several bodies at once.

    Parameters
    ----------
    bodies : sequence of ElasticBody
        Every body of the scene, each factored once.
    rotations : bool
        Place free bodies by all six rigid modes, their rotations included (with
        friction, whose tangential rows hold them); otherwise by their placing modes
        (:attr:`fem.StaticSolver.placing_modes`).
    planes : sequence of Plane
        Force-driven planes: rigid bodies of one mode (a translation along the normal)
        loaded by their force, placed with the free bodies (after them in ``a``); their
        parts of the rows are ``e[plane.name]`` (:meth:`FrameState.matrices`).
    prox : mapping of str to float, optional
        Springs on some free bodies' modes, in the contacts' stiffness seen there
        (:attr:`ContactSystem.prox`): a Newton step's damping, whose amplitudes are a step.
    """

    def __init__(
        self,
        bodies: Sequence[ElasticBody],
        rotations: bool = False,
        planes: Sequence = (),
        prox: Mapping[str, float] | None = None,
    ) -> None:
        self.bodies = list(bodies)
        self.rotations = rotations
        self.planes = list(planes)
        self.prox = dict(prox or {})
        self._u0: dict[str, NDArray[np.float64]] = {}

    def placing(self, body: ElasticBody) -> NDArray[np.float64]:
        """The rigid modes that place a free body in this space."""
        return body.solver.modes if self.rotations else body.solver.placing_modes

    def turning(self, body: ElasticBody) -> fem.TurningInverse | None:
        """A free body's border where its turns change its stiffness and it may turn."""
        return body.turning if self.rotations else None

    def width(self, body: ElasticBody) -> int:
        """A free body's amplitudes: its placing modes', or its border's."""
        t = self.turning(body)
        return self.placing(body).shape[1] if t is None else t.width

    def border(
        self, body: ElasticBody, eb: sp.csr_matrix | None, m: int
    ) -> tuple[NDArray, NDArray, NDArray]:
        """A free body's ``G`` columns, modes' stiffness and ``c`` for its rows ``eb``."""
        t = self.turning(body)
        if t is not None:
            return t.extended(sp.csr_matrix((m, body.mesh.n_dofs)) if eb is None else eb,
                              body.loads)  # fmt: skip
        phi = self.placing(body)
        g = eb @ phi if eb is not None else np.zeros((m, phi.shape[1]))
        return np.asarray(g), np.zeros((phi.shape[1],) * 2), -(phi.T @ body.loads)

    def free_response(self, body: ElasticBody, f: NDArray[np.float64]) -> NDArray[np.float64]:
        """``C f``: the body's displacement under loads ``f`` (a free body: rigid part removed)."""
        s = body.solver
        u = np.zeros(s.n)
        ff = f[s.free]
        if ff.any():  # no loads (a body held by its supports, or floating): no solve
            u[s.free] = s.apply_inverse(ff)
        return u

    def own_response(self, body: ElasticBody) -> NDArray[np.float64]:
        """The body's answer to its own loads, computed once."""
        if body.name not in self._u0:
            self._u0[body.name] = self.free_response(body, body.loads)
        return self._u0[body.name]

    def state(self, body: ElasticBody, forces: NDArray[np.float64], rigid: NDArray) -> BodyState:
        """Displacement and support reactions of a body under its loads plus ``forces``."""
        s = body.solver
        f = body.loads + forces
        t = self.turning(body)
        if t is not None:  # rigid: the border's amplitudes
            u, rigid = t.displacement(f, rigid), np.asarray(rigid)[:6]
        else:
            u = self.own_response(body) + self.free_response(body, forces)
        if s.free_body and t is None:
            u = u + s.modes @ rigid
        reactions = np.zeros(s.n)
        if s.prescribed.size:
            reactions[s.prescribed] = s.prescribed_rows @ u - f[s.prescribed]
        return BodyState(u, reactions, np.asarray(rigid, dtype=np.float64))

    def system(self, e: dict[str, sp.csr_matrix], g0: NDArray[np.float64]) -> ContactSystem:
        """The contact-space system of rows ``e`` with reference gaps ``g0``.

        Parameters
        ----------
        e : dict of str to sparse matrix
            Each body's part ``E_b`` (m x n_dofs_b) of the rows.
        g0 : ndarray, shape (m,)
            Reference gaps of the rows.
        """
        m = g0.size
        w = np.zeros((m, m))
        rhs = -np.asarray(g0, dtype=np.float64).copy()
        balance: list[NDArray] = []
        free: list[ElasticBody] = []
        stiff: list[NDArray] = []
        aux: list[NDArray] = []
        prox: list[NDArray] = []
        cols: list[NDArray] = []
        for body in self.bodies:
            eb = e.get(body.name)
            s = body.solver
            if eb is not None and m:
                w += s.compliance(eb)
                rhs -= eb @ self.own_response(body)
            if s.free_body:
                free.append(body)
                g, h, c = self.border(body, eb, m)
                cols.append(g)
                balance.append(c)
                stiff.append(h)
                aux.append((np.arange(c.size) >= 6) & (self.turning(body) is not None))
                prox.append(np.where(aux[-1], 0.0, self.prox.get(body.name, 0.0)))
        cols += self._plane_columns(e, m)
        balance += [np.array([-float(pl.force)]) for pl in self.planes]
        stiff += [np.zeros((1, 1)) for _ in self.planes]
        aux += [np.zeros(1, bool) for _ in self.planes]
        prox += [np.zeros(1) for _ in self.planes]
        scales = [float(np.linalg.norm(b.loads)) for b in free]
        return ContactSystem(
            w=w,
            g=np.hstack(cols) if cols else np.zeros((m, 0)),
            rhs=rhs,
            c=np.concatenate(balance) if balance else np.zeros(0),
            free=tuple(b.name for b in free) + tuple(pl.name for pl in self.planes),
            load_scale=max(scales + [float(pl.force) for pl in self.planes], default=0.0),
            h=sla.block_diag(*stiff) if stiff else np.zeros((0, 0)),
            aux=np.concatenate(aux) if aux else np.zeros(0, bool),
            prox=np.concatenate(prox) if self.prox and prox else None,
        )

    def states(
        self,
        e: dict[str, sp.csr_matrix],
        lam: NDArray[np.float64],
        a: NDArray[np.float64],
        bound: NDArray[np.bool_] | None = None,
        g: NDArray[np.float64] | None = None,
        held: NDArray[np.float64] | None = None,
    ) -> dict[str, BodyState]:
        """Every body's state under contact forces ``lam`` and rigid-mode amplitudes ``a``.

        The amplitudes are first taken least along the modes no binding row sees
        (:meth:`gauged`, with ``bound``); ``g`` is the system's ``G`` where it was built
        (:attr:`ContactSystem.g`), else it is built again; ``held`` its
        :attr:`ContactSystem.mode_rows`.
        """
        m = lam.size
        a = self.gauged(e, lam, a, bound, g, held)
        states = {}
        k = 0
        for body in self.bodies:
            eb = e.get(body.name)
            forces = eb.T @ lam if eb is not None and m else np.zeros(body.mesh.n_dofs)
            rigid = np.zeros(0)
            if body.solver.free_body:
                r = self.width(body)
                rigid = np.zeros(max(6, r))
                rigid[:r] = a[k : k + r]
                k += r
            states[body.name] = self.state(body, forces, rigid)
        for pl in self.planes:  # a force-driven plane's translation along its normal
            s = a[k : k + 1]
            k += 1
            states[pl.name] = BodyState(pl.normal * float(s[0]), np.zeros(3), s.copy())
        return states

    def gauged(
        self,
        e: dict[str, sp.csr_matrix],
        lam: NDArray[np.float64],
        a: NDArray[np.float64],
        bound: NDArray[np.bool_] | None = None,
        g: NDArray[np.float64] | None = None,
        held: NDArray[np.float64] | None = None,
    ) -> NDArray:
        """``a`` less its part along the modes that move no row that binds.

        ``bound``: the rows that bind (every normal row, open ones too: they must stay
        open; a closed contact's tangential rows); default every row. ``g``: the
        system's ``G``, ``held`` its modes' stiffness as rows, as for :meth:`states`: a
        mode its own stiffness holds is not gauged.

        A ball squeezed by two force-driven pads moves with them along their normals
        without changing a gap, and a ball held by friction at two points turns freely
        about the line through them: such motions are not determined by the contacts, and
        the least one (the bodies and planes where the frame started) is taken: the
        least rigid part of the displacement (a bordered body's is not its amplitudes',
        :meth:`fem.TurningInverse.rigid_part`). Only with all six modes (friction) or
        force-driven planes: the frictionless placing modes' free slides are how a body
        that is not held shows.
        """
        m = lam.size
        act = np.ones(m, dtype=bool) if bound is None else np.asarray(bound, dtype=bool)
        if not (self.planes or self.rotations) or not a.size or not act.any():
            return a
        g = (self.system_modes(e, m) if g is None else g)[act]
        if held is not None:
            g = np.vstack([g, held])
        _, sv, vt = np.linalg.svd(g, full_matrices=True)
        rank = int((sv > RANK_TOL * sv.max()).sum()) if sv.size and sv.max() > 0 else 0
        null = vt[rank:]
        if not null.size:
            return a
        # each body's rigid part q = q0 + D a, in its amplitudes' place: for a bordered
        # body Phi^T u (D = Phi^T Psi), else its amplitudes. Its least along the null
        # modes; a Newton step's bodies (bordered or not) move by a step, its planes to
        # where they are: the step's least is its bodies', the planes left out
        q, d = a.copy(), np.eye(a.size)
        weight = np.ones(a.size)
        k = 0
        for body in self.bodies:
            if body.solver.free_body:
                t = self.turning(body)
                if t is not None:
                    eb = e.get(body.name)
                    f = body.loads + (eb.T @ lam if eb is not None and m else 0.0)
                    q[k : k + 6] = t.rigid_part(f, a[k : k + 6])
                    d[k : k + 6, k : k + 6] = t.phi_psi
                k += self.width(body)
        if any(b.turns_freely and b.free for b in self.bodies):
            weight[k:] = 0.0
        dv = (d @ null.T) * weight[:, None]
        s = np.linalg.lstsq(dv, -(q * weight), rcond=None)[0]
        return a + null.T @ s

    def _plane_columns(self, e: dict[str, sp.csr_matrix], m: int) -> list[NDArray[np.float64]]:
        """The force-driven planes' columns of ``G``: their rows' values of their translations."""
        cols = []
        for pl in self.planes:
            ep = e.get(pl.name)
            col = ep @ pl.normal if ep is not None else np.zeros(m)
            cols.append(np.asarray(col, dtype=np.float64).reshape(m, 1))
        return cols

    def solve(
        self, e: dict[str, sp.csr_matrix], g0: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], dict[str, BodyState]]:
        """Contact forces closing every row, and every body's state under them.

        Parameters
        ----------
        e : dict of str to sparse matrix
            Each body's part ``E_b`` (m x n_dofs_b) of the rows.
        g0 : ndarray, shape (m,)
            Reference gaps of the rows.

        Returns
        -------
        lam : ndarray, shape (m,)
            Normal contact forces (N), positive pushing the bodies apart.
        states : dict of str to BodyState
            Every body's displacement and reactions.

        Raises
        ------
        ContactError
            When the contacts do not hold a free body whose loads are out of balance.
        """
        with fem.dense_threads(g0.size):
            sys_ = self.system(e, g0)
            lam, a = _saddle(sys_.w, sys_.g, sys_.rhs, sys_.c, list(sys_.free), sys_.load_scale)
        return lam, self.states(e, lam, a, g=sys_.g)

    def solve_unilateral(
        self,
        e: dict[str, sp.csr_matrix],
        g0: NDArray[np.float64],
        tol: NDArray[np.float64],
        start: NDArray[np.float64] | None = None,
    ) -> tuple[LcpResult, dict[str, BodyState]]:
        """Contact forces of candidate rows that may open: the frictionless LCP.

        Each row either closes with a force pushing the bodies apart or stays open with
        a linearised gap of at least ``-tol`` (:func:`contact.solver.lcp.solve_lcp`).

        Parameters
        ----------
        e, g0
            As for :meth:`solve`.
        tol : ndarray, shape (m,)
            Gap tolerance of each row (m).
        start : ndarray, shape (m,), optional
            Forces to start from (the last ones of a set that grew).

        Returns
        -------
        result : LcpResult
        states : dict of str to BodyState

        Raises
        ------
        fem.LoadError
            When the contacts do not hold a free body whose loads are out of balance
            (:meth:`solve_held` answers then).
        """
        with fem.dense_threads(g0.size):  # small dense work: one BLAS thread
            sys_ = self.system(e, g0)
        # solve_lcp limits its own threads
        try:
            res = solve_lcp(
                sys_.w, sys_.g, sys_.rhs, sys_.c, tol=tol, start=start,
                load_scale=sys_.load_scale,
            )
        except fem.LoadError:
            # the rows the active set started from hold too little (a ball that rests
            # on a table it only touches): start again with the touching rows closed
            touching = -sys_.rhs <= tol
            again = np.zeros(g0.size) if start is None else np.array(start, dtype=float)
            if not (touching & (again <= 0)).any():
                raise
            again[touching & (again <= 0)] = TOUCHING * max(sys_.load_scale, 1e-300)
            res = solve_lcp(
                sys_.w, sys_.g, sys_.rhs, sys_.c, tol=tol, start=again,
                load_scale=sys_.load_scale,
            )
        return res, self.states(e, res.lam, res.a, g=sys_.g)

    def net_forces(self, modal: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Each free body's net force ``(3,)`` (N) from forces ``modal`` in its placing modes."""
        return {name: f for name, (f, _) in self.net_wrenches(modal).items()}

    def net_wrenches(
        self, modal: NDArray[np.float64]
    ) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
        """Each free body's net force (N) and moment about its centroid (N m), each ``(3,)``.

        ``modal`` holds forces in the bodies' placing modes (in order); each is spread on
        the nodes by its modes (an orthonormal basis) and summed.
        """
        net = {}
        k = 0
        for body in self.bodies:
            if body.solver.free_body:
                phi = self.placing(body)
                r = phi.shape[1]  # a border's first amplitudes are its modes'
                f = (phi @ modal[k : k + r]).reshape(-1, 3)
                x = body.mesh.points - body.mesh.points.mean(axis=0)
                net[body.name] = (f.sum(axis=0), np.cross(x, f).sum(axis=0))
                k += self.width(body)
        return net

    def solve_held(
        self, e: dict[str, sp.csr_matrix], g0: NDArray[np.float64], tol: NDArray[np.float64]
    ) -> tuple[LcpResult, dict[str, BodyState], dict[str, NDArray[np.float64]]]:
        """The frictionless LCP with every free body also held by a soft spring.

        For rows whose contacts cannot balance a free body's loads
        (:meth:`solve_unilateral` raises): the spring (:data:`SPRING`) makes the problem
        solvable, the contacts carry what they can and the spring the rest. The body is
        left where its pushing rows place it: the spring's stretch along the modes no
        pushing row holds, which only says that the body goes away, is dropped.

        Parameters
        ----------
        e, g0, tol
            As for :meth:`solve_unilateral`.

        Returns
        -------
        result : LcpResult
            The rows' forces and the free bodies' mode amplitudes.
        states : dict of str to BodyState
        net : dict of str to ndarray, shape (3,)
            Each free body's net force, loads and contact forces together (N): the part
            of its loads that no contact carries.
        """
        m = g0.size
        with fem.dense_threads(m):
            sys_ = self.system(e, g0)
            g, c = sys_.g, sys_.c
            w, rhs, soft = held_by_springs(sys_)
            res = solve_lcp(
                w, np.zeros((m, 0)), rhs, np.zeros(0), tol=tol, load_scale=sys_.load_scale
            )
            carried = g.T @ res.lam - c  # what the springs hold, in the modes
            push = g[res.lam > 0]
            _, sv, vt = np.linalg.svd(push, full_matrices=False)
            big = sv > RANK_TOL * sv.max() if sv.size and sv.max() > 0 else np.zeros(0, bool)
            held = vt[big]  # the modes the pushing rows hold
            a = held.T @ (held @ (carried / soft))
        net = self.net_forces(carried)
        out = LcpResult(res.lam, a, res.gap, res.steps, res.solved)
        return out, self.states(e, res.lam, a, g=g), net


def held_by_springs(sys_: ContactSystem) -> tuple[NDArray, NDArray, float]:
    """The system with every free body held by a soft spring in its modes (:data:`SPRING`).

    No balance equation is left: ``W + G G^T / k`` and ``rhs + G c / k`` on the forces
    alone, ``k`` the spring's stiffness in the modes' units. A problem that always has a
    solution; the springs carry ``G^T lambda - c``, what the contacts do not.
    """
    w, g, c = sys_.w, sys_.g, sys_.c
    m = w.shape[0]
    dw = float(np.mean(np.diag(w))) if m else 1.0
    dg = float(np.mean(np.einsum("ij,ij->i", g, g))) if m else 0.0
    soft = SPRING * (dg if dg > 0 else 1.0) / max(dw, 1e-300)
    return w + g @ g.T / soft, sys_.rhs + g @ c / soft, soft


def _saddle(
    w: NDArray, g: NDArray, rhs: NDArray, c: NDArray, free: list[str], load_scale: float
) -> tuple[NDArray, NDArray]:
    """Solve ``[[W, G], [G^T, 0]] [lam; a] = [rhs; c]`` (see :func:`fem.saddle.solve_saddle`)."""
    try:
        return solve_saddle(w, g, rhs, c, load_scale)
    except fem.LoadError:
        raise ContactError(_unheld(free)) from None


def _unheld(free: list[str]) -> str:
    return (
        f"nothing holds {', '.join(free)}: the contacts do not hold it in every "
        "direction and its loads are out of balance in the free ones"
    )
