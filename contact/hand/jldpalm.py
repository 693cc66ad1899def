"""The two-segment covering of the palm for the JLD mapping.

Magnenat-Thalmann, Laperrière and Thalmann (1988), sections 4 and 5.2, Figs. 5 and 7: a
free point of a metacarpal or a proximal phalanx is also localised on the neighbouring rays
(the chains of bones on the carpus) and its mapping blends theirs; the virtual segment
between two rays gives the scale factor that thickens the palm (see :mod:`contact.hand.jld`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .jldframes import EPS, JointFrames, smoothstep
from .jldlocalise import BoneSurfaces, localise

__all__ = ["palm_covering"]

#: Along a proximal phalanx, the blend with the neighbouring finger fades out between these
#: ratios (the web between the fingers ends about mid-phalanx in the shipped hand).
_WEB = (0.55, 0.8)


def palm_covering(
    frames: JointFrames,
    surfaces: BoneSurfaces,
    main: dict[str, NDArray],
    x: NDArray,
    seg: NDArray,
    bid: NDArray,
    palm_proximity: float,
) -> tuple[list[str], dict[str, NDArray] | None, dict[str, NDArray] | None]:
    """Covering of the palm by neighbouring rays (metacarpals and proximal phalanges).

    The rays are the chains of bones hanging on the carpus (one per metacarpal), in
    order across the hand (by the x of the metacarpal's end). A free point of a
    metacarpal or a proximal phalanx is mapped by every such bone near it: its own
    and its neighbours', each single-segment mapping weighted by the inverse cube of
    the point's distance to that bone's surface (normalised). For two bones the
    weight of the neighbour is ``t^3 / (t^3 + (1 - t)^3)`` with ``t`` the point's
    ratio on the virtual segment between the two bone surfaces: 0 on its own bone,
    1/2 midway (the in-between area of Fig. 7), and the areas along each segment
    (``t < palm_proximity``) are mapped by that segment alone. Every palm point uses
    the same bones and formula, so the mapping is continuous across the palm. Along a
    proximal phalanx the neighbours fade out past the web (:data:`_WEB`), where the
    fingers part. The nearest neighbour's virtual segment gives the scale factor F.
    """
    topo = frames.topology
    nbones = len(topo.names)
    carpal = [
        b
        for b in range(nbones)
        if topo.parent[b] >= 0 and not topo.chained[b] and topo.child[b] >= 0
    ]
    carpal.sort(key=lambda b: topo.end[b][0])  # radial to ulnar
    palm_bones = [topo.names[b] for b in carpal]
    depth = np.full(nbones, -1, np.int64)
    ray = np.full(nbones, -1, np.int64)
    for k, b in enumerate(carpal):
        d, c = 0, b
        while c >= 0:
            depth[c], ray[c] = d, k
            c, d = topo.child[c], d + 1
    cand = np.flatnonzero((depth >= 0) & (depth <= 1))
    # the hub's points in the areas of its joints (the carpus near the metacarpals)
    zone = main["zone"]
    hub_pt = np.isin(seg, frames.hubs) & (zone >= 0)
    hub_pt &= ~frames.jtwo[np.maximum(zone, 0)] & (frames.jparent[np.maximum(zone, 0)] == seg)
    idx = np.flatnonzero((np.isin(seg, cand) | hub_pt) & (bid < 0))
    pairs = extra = None
    if len(idx) == 0 or len(carpal) < 2:
        return palm_bones, pairs, extra
    xp, sp = x[idx], seg[idx]
    hub = hub_pt[idx]
    nray = len(carpal)
    members = [np.flatnonzero((ray == k) & (depth >= 0) & (depth <= 1)) for k in range(nray)]
    dist = np.stack(
        [
            np.min([surfaces.distance(xp, np.full(len(idx), b)) for b in mem], axis=0)
            for mem in members
        ],
        1,
    )
    dist = np.maximum(dist, EPS)
    own_ray = np.where(hub, np.argmin(dist, axis=1), ray[sp])
    own = np.arange(nray)[None, :] == own_ray[:, None]
    t0 = palm_proximity
    d_own = dist[own]
    # the area along the own ray: neighbours act only beyond palm_proximity
    tt = d_own[:, None] / (d_own[:, None] + dist)
    infl = np.where(own, 1.0, smoothstep(tt / max(t0, EPS)) * (tt / (1.0 - tt)) ** 3)
    r = main["ratio"][idx]
    deep = (depth[sp] >= 1) & ~hub
    fade = np.where(deep, 1.0 - smoothstep((r - _WEB[0]) / (_WEB[1] - _WEB[0])), 1.0)
    infl[~own] *= np.repeat(fade, nray - 1)
    w = infl / infl.sum(1, keepdims=True)
    # drop the negligible weights continuously (a cut at 1e-4 jumps by 1e-4 of the
    # difference between two rays' mappings, microns where they differ by centimetres)
    w = np.maximum(w - 1e-4 * w.max(axis=1, keepdims=True), 0.0)
    w /= w.sum(1, keepdims=True)
    # a hub point is mapped by the rays only (its own ray too); others add neighbours
    rows, cols = np.nonzero(w * (~own | hub[:, None]))
    pidx = idx[rows]
    pb = np.empty(len(rows), np.int64)
    for k in range(nray):
        at = cols == k
        pb[at] = frames.assign_in(x[pidx[at]], members[k])
    pairs = {
        "idx": pidx,
        "w": w[rows, cols],
        "loc": localise(frames, surfaces, x[pidx], pb),
        "own_w": np.bincount(pidx, w[rows, cols], minlength=len(x)),
    }
    nbone = np.full(w.shape, -1, np.int64)
    nbone[rows, cols] = pb
    prow = np.full(w.shape, -1, np.int64)
    prow[rows, cols] = np.arange(len(rows))
    ploc = pairs["loc"]
    rr = np.arange(len(idx))
    # the own segment's localisation: the main one, or for a hub point its own ray's
    if len(rows) == 0:
        return palm_bones, pairs, extra
    own_col = np.argmax(own, axis=1)
    pr = np.maximum(prow[rr, own_col], 0)  # a pair only for hub points (where used)
    own_seg = np.where(hub, ploc["seg"][pr], sp)
    own_off = np.where(hub[:, None], ploc["offset"][pr], main["offset"][idx])
    own_r = np.where(hub, ploc["ratio"][pr], main["ratio"][idx])
    # the scale factor F of the nearest neighbour's virtual segment thickens the palm
    other = np.where(own, -1.0, w)
    order = np.argsort(-other, axis=1)
    top, second = order[:, 0], order[:, 1]
    w_own, w_nb = w[own], other[rr, top]
    d_rays = np.minimum(dist[own], dist[rr, top])
    # 1 midway between two rays; 0 where the nearest neighbour changes (continuous)
    low = np.minimum(w_own, w_nb)
    lead = np.clip(low - np.maximum(other[rr, second], 0.0), 0.0, None) / np.maximum(low, EPS)
    lead *= 4.0 * w_own * w_nb / np.maximum((w_own + w_nb) ** 2, EPS)
    # none on the carpus: it fades in along the metacarpals' first fifth, by the mean
    # ratio on the two segments (the same seen from either ray: continuous where the
    # proximal assignment switches from one metacarpal to the other)
    nb_r = ploc["ratio"][np.maximum(prow[rr, top], 0)]
    r_pair = np.where(prow[rr, top] >= 0, 0.5 * (own_r + nb_r), own_r)
    lead *= np.where(depth[own_seg] == 0, smoothstep(r_pair / 0.2), 1.0)
    has = (w_nb > 0.0) & (lead > 0.0)
    nb_row = prow[has, top[has]]
    idx, sp, lead, d_rays = idx[has], own_seg[has], lead[has], d_rays[has]
    if len(idx) == 0:
        return palm_bones, pairs, extra
    # the virtual segment joins the projections on the two segments (at their ratios)
    ps = x[idx] - own_off[has]
    pn = x[idx] - ploc["offset"][nb_row]
    nb = ploc["seg"][nb_row]
    v = pn - ps
    t = ((x[idx] - ps) * v).sum(-1) / np.maximum((v * v).sum(-1), EPS)
    ov = x[idx] - (ps + t[:, None] * v)
    ev = np.linalg.norm(ov, axis=1)
    beyond = np.clip(d_rays / np.maximum(ev, EPS), 0.0, 1.0)
    extra = {
        "idx": idx,
        "own": sp,
        "neighbour": nb,
        "ps": ps,
        "pn": pn,
        "bulge": (lead * beyond)[:, None] * ov,
    }
    return palm_bones, pairs, extra
