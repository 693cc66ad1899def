"""Localisation of rest points for the JLD mapping: areas, weights, rounding and inflation.

Each point, assigned to a segment (:meth:`contact.hand.jldframes.JointFrames.assign`), gets
its ratio and thickness on the segment, the joint whose areas hold it, the fraction of that
joint's rotation it takes and its coefficients of joint rounding and muscle inflation
(Magnenat-Thalmann, Laperrière and Thalmann 1988, sections 4 to 6; see
:mod:`contact.hand.jld`). Distances to a bone's surface are measured on the rest nodes fixed
to it (:class:`BoneSurfaces`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .jldframes import EPS, JointFrames, muscle_profile, smoothstep

__all__ = ["BoneSurfaces", "localise"]


class BoneSurfaces:
    """Distances from points to the bones' surfaces, measured on rest nodes fixed to them.

    Parameters
    ----------
    frames : JointFrames
    points, bone_id : array_like
        Rest nodes fixed to bones (``bone_id >= 0``) and their bones; each bone's k-d tree
        is built on first use.
    """

    def __init__(self, frames: JointFrames, points: ArrayLike, bone_id: ArrayLike) -> None:
        self.frames = frames
        ref_x = np.asarray(points, dtype=np.float64)
        ref_id = np.asarray(bone_id, dtype=np.int64)
        nbones = len(frames.topology.names)
        order = np.argsort(ref_id, kind="stable")
        cut = np.searchsorted(ref_id[order], np.arange(nbones + 1))
        self.ref = {  # each bone's reference nodes
            b: ref_x[order[cut[b] : cut[b + 1]]] for b in range(nbones) if cut[b + 1] > cut[b]
        }
        self.trees: dict[int, cKDTree] = {}

    def tree(self, bone: int) -> cKDTree | None:
        """k-d tree of the reference nodes fixed to ``bone`` (None without any)."""
        if bone not in self.trees and bone in self.ref:
            self.trees[bone] = cKDTree(self.ref[bone])
        return self.trees.get(bone)

    def distance(self, x: NDArray, bones: NDArray) -> NDArray:
        """Distance from each point to the surface of the bone ``bones[i]`` (m).

        Measured to the nearest rest node fixed to that bone (the nodes that move rigidly
        with it); without such nodes, to the bone's axis less its mean shaft half-width.
        """
        out = np.empty(len(x))
        for b in np.unique(bones):
            at = bones == b
            tree = self.tree(int(b))
            if tree is not None:
                out[at] = tree.query(x[at])[0]
            else:
                d = self.frames.clamped_distance(x[at], np.array([b]))[:, 0]
                out[at] = np.maximum(d - self.frames.shaft[b], 0.0)
        return out


def localise(
    frames: JointFrames, surfaces: BoneSurfaces, x: NDArray, seg: NDArray
) -> dict[str, NDArray]:
    """Segment, zone joint, weight and rounding/inflation coefficients of points."""
    topo = frames.topology
    n = len(x)
    r = frames.ratio(x, seg)
    proj = topo.start[seg] + r[:, None] * (topo.end[seg] - topo.start[seg])
    off = x - proj
    thick = np.linalg.norm(off, axis=1)
    pj, dj = frames.bjoint[seg], frames.d_joint[seg]
    has_p = (pj >= 0) & (topo.parent[seg] >= 0)
    # several joints on the segment's far end (the carpus): the nearest one's areas
    many = np.isin(seg, frames.hubs) & (dj < 0)
    if many.any():
        kids = frames.hub_children
        dk = np.stack([surfaces.distance(x[many], np.full(many.sum(), c)) for c in kids])
        best = np.array(kids)[np.argmin(dk, axis=0)]
        ok = topo.parent[best] == seg[many]
        dj = dj.copy()
        dj[np.flatnonzero(many)[ok]] = frames.bjoint[best[ok]]
    has_d = dj >= 0
    # zone: the child side of the proximal joint, or the parent side of the distal one
    child_side = has_p & ((r < 0.5) | ~has_d)
    parent_side = has_d & ~child_side
    zone = np.full(n, -1, np.int64)
    zone[child_side] = pj[child_side]
    zone[parent_side] = dj[parent_side]
    zj = np.maximum(zone, 0)
    # the weight between the two bones of the joint: their surface distances
    inz = zone >= 0
    d_par = np.zeros(n)
    d_chi = np.zeros(n)
    d_par[inz] = surfaces.distance(x[inz], frames.jparent[zj[inz]])
    d_chi[inz] = surfaces.distance(x[inz], frames.jchild[zj[inz]])
    dp, dc = np.sqrt(d_par), np.sqrt(d_chi)
    between = dp / np.maximum(dp + dc, EPS)
    s = np.zeros(n)
    cs = child_side
    s[cs] = 1.0 - (1.0 - between[cs]) * (1.0 - smoothstep(r[cs] / frames.j_proximal[zj][cs]))
    # behind the plane of a child of several (a metacarpal's point on the carpus, as a
    # neighbouring ray sees it): the parent side's formula, on the parent's ratio
    back = cs & (r < 0.0) & ~frames.jtwo[zj]
    if back.any():
        rp = frames.ratio(x[back], frames.jparent[zj[back]])
        s[back] = between[back] * (1.0 - smoothstep((1.0 - rp) / frames.j_distal[zj[back]]))
    ps = parent_side
    s[ps] = between[ps] * (1.0 - smoothstep((1.0 - r[ps]) / frames.j_distal[zj][ps]))
    base = np.where(child_side, topo.parent[seg], seg)
    # rounding (dorsal, in the areas of two-sided joints) and muscle inflation (palmar)
    beyond = np.clip(surfaces.distance(x, seg) / np.maximum(thick, EPS), 0.0, 1.0)
    # at a joint: beyond the nearer of its two bones (the same on both sides)
    near_bone = np.where(inz, np.minimum(d_par, d_chi), 0.0)
    beyond_j = np.clip(near_bone / np.maximum(thick, EPS), 0.0, 1.0)
    round_j = np.full(n, -1, np.int64)
    round_k = np.zeros(n)
    near_p = has_p & frames.jtwo[np.maximum(pj, 0)]
    t_p = r / frames.j_proximal[np.maximum(pj, 0)]
    in_p = near_p & (t_p < 1.0)
    round_j[in_p] = pj[in_p]
    round_k[in_p] = (1.0 - np.clip(t_p[in_p], 0.0, 1.0)) ** 2
    d_two = (frames.d_joint[seg] >= 0) & frames.jtwo[np.maximum(frames.d_joint[seg], 0)]
    t_d = (1.0 - r) / frames.j_distal[np.maximum(frames.d_joint[seg], 0)]
    in_d = d_two & ~in_p & (t_d < 1.0)
    round_j[in_d] = frames.d_joint[seg][in_d]
    round_k[in_d] = (1.0 - np.clip(t_d[in_d], 0.0, 1.0)) ** 2
    rj = np.maximum(round_j, 0)
    cos_j = (off * frames.jn[rj]).sum(-1) / np.maximum(thick, EPS)
    round_k *= frames.j_rounding[rj] * np.clip(cos_j, 0.0, 1.0) * beyond_j
    round_k[round_j < 0] = 0.0
    musc_j = np.where(frames.b_finger[seg], pj, -1)
    mj = np.maximum(musc_j, 0)
    cos_b = (off * frames.b_normal[seg]).sum(-1) / np.maximum(thick, EPS)
    musc_k = (
        frames.j_muscle[mj]
        * muscle_profile(r, frames.j_muscle_peak[mj], frames.j_muscle_power[mj])
        * np.clip(-cos_b, 0.0, 1.0)
        * beyond
    )
    musc_k[musc_j < 0] = 0.0
    return {
        "seg": seg,
        "base": base,
        "zone": zone,
        "s": s,
        "offset": off,
        "ratio": r,
        "thickness": thick,
        "round_j": round_j,
        "round_k": round_k,
        "musc_j": musc_j,
        "musc_k": musc_k,
    }
