"""The report of the convergence study: its plot and its notes.

Used by :func:`benchmarks.convergence.run` to write ``convergence.{md,png}``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .convergence_cases import LAME_LEVELS, LAME_NU
from .convergence_rates import HERTZ_ERRORS, LAME_ERRORS

__all__: list[str] = []

# --- report ---------------------------------------------------------------------------------


def _plot(path: Path, rows: Sequence[dict], rates: Sequence[dict]) -> None:
    """Four log-log panels of error against h, the fitted slopes in the legends."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rate_of = {(r["study"], r["series"], r["error"]): r["rate"] for r in rates}

    def legend(study: str, series: str, label: str, name: str) -> str:
        rate = rate_of[(study, series, label)]
        return f"{name}: " + ("no rate" if math.isnan(rate) else f"slope {rate:.2f}")

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = "osD^vP*X<>"
    lame = [r for r in rows if r["study"] == "lame"]
    labels = {key: label for key, label, _, _ in LAME_ERRORS}
    panels = (
        (axes[0, 0], ("max_ur", "l2_u"), (0.3,), "Lame, nu 0.3: displacement"),
        (axes[0, 1], ("l2_sigma", "hoop_mid"), (0.3,), "Lame, nu 0.3: stress"),
        (axes[1, 0], ("l2_u", "l2_sigma"), LAME_NU, "Lame: nu 0.3 (solid), 0.45 (dashed)"),
    )
    for ax, keys, nus, title in panels:
        for i, (element, key) in enumerate((e, k) for e in LAME_LEVELS[False] for k in keys):
            for nu in nus:
                series = sorted(
                    (r for r in lame if r["element"] == element and r["nu"] == nu),
                    key=lambda r: r["h"],
                )
                if not series:
                    continue
                sname = f"{element}, nu {nu:g}"
                name = f"{sname} {labels[key]}" if len(nus) > 1 else f"{element} {labels[key]}"
                ax.loglog(
                    [r["h"] for r in series],
                    [r[key] for r in series],
                    color=colors[i % len(colors)],
                    marker=markers[i % len(markers)],
                    linestyle="-" if nu == LAME_NU[0] else "--",
                    label=legend("lame", sname, labels[key], name),
                )
        ax.set_title(title)
        ax.set_ylabel("relative error")
    ax = axes[1, 1]
    hertz = sorted((r for r in rows if r["study"] == "hertz"), key=lambda r: r["h"])
    for i, (key, label, _, _) in enumerate(HERTZ_ERRORS):
        h = np.array([r["h"] for r in hertz])
        e = np.array([r[key] for r in hertz])
        ax.loglog(
            h,
            np.abs(e),
            color=colors[i],
            marker=markers[i],
            label=legend("hertz", "hex8 octant", label, f"|{label} err|"),
        )
        neg = e < 0
        ax.loglog(h[neg], -e[neg], linestyle="none", marker=markers[i], color="white", ms=3)
    ax.set_title("Hertz ball (octant): |relative error| (open marker: negative)")
    ax.set_ylabel("|relative error|")
    for ax in axes.ravel():
        ax.set_xlabel("h (m)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
    fig.suptitle("Mesh convergence (slopes: least squares of log |error| on log h)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _notes(rows: Sequence[dict], seconds: float) -> str:
    """The notes section: locking, what each error measures, and the run time."""
    lame = [r for r in rows if r["study"] == "lame"]
    lines = []

    def finest(element: str, nu: float) -> dict | None:
        series = [r for r in lame if r["element"] == element and r["nu"] == nu]
        return min(series, key=lambda r: r["h"]) if series else None

    for element in LAME_LEVELS[False]:
        lo, hi = finest(element, LAME_NU[0]), finest(element, LAME_NU[-1])
        if lo is not None and hi is not None and lo is not hi and lo["level"] == hi["level"]:
            lines.append(
                f"- {element} at nu {hi['nu']:g} against {lo['nu']:g} on the finest mesh "
                f"(k = {lo['level']}): L2 u error x{hi['l2_u'] / lo['l2_u']:.2f}, L2 sigma "
                f"x{hi['l2_sigma'] / lo['l2_sigma']:.2f}, max u_r "
                f"x{hi['max_ur'] / lo['max_ur']:.2f}."
            )
    lines += [
        "- Volumetric locking: fully integrated bricks ('hex8 full', 2x2x2 Gauss) constrain "
        "the volumetric strain at every Gauss point, and their error constant grows with "
        "lambda / mu (without bound as nu tends to 0.5). fem's bricks take the element's "
        "mean dilatation instead (B-bar, 'hex8', the default of fem.assemble_stiffness): "
        "their errors at nu 0.45 stay those at 0.3. The 24-tetrahedron split feels "
        "locking much less here; that is a property of this crossed split, and says "
        "nothing about unstructured tet4 meshes, which are not run.",
        "- The displacement errors include the geometric one (the faceted sphere, with the "
        "pressure on the faceted inner surface), also O(h^2). max u_r is the worst node, "
        "near the corners of the cubed sphere where the cells are most distorted; its rate "
        "rises towards 2 on the finer meshes.",
        "- hoop mid is pointwise, at the centroids of the cells that reach the mid-wall "
        "sphere. Brick centroids are superconvergent points (about 2 on each parity of k), "
        "but odd k put the centroids on the mid-wall sphere and even k half a layer to "
        "either side, two sequences with different constants: the slope of the last two "
        "meshes mixes them, the fit over all is the one to read. The tetrahedra's centroids "
        "are not such points.",
        "- Hertz: the radius and the peak pressure are compared with Hertz for the "
        "solver's own force, as in the hertz study. The total force is compared with "
        "Hertz's force for the plates' advance (the approach of the ball's centre): "
        "half-space theory leaves out that the ball is finite (in a half-space the point at "
        "the centre's depth still moves, by O(a/R) of the approach), so the force error "
        "tends to a model error of a few percent, not to zero, and it has no rate.",
        "- An error that changes sign over the meshes crosses zero somewhere between them: "
        "its magnitude on log axes says nothing about a rate, and none is fitted.",
        f"- Whole run: {seconds:.0f} s wall clock on a shared machine (see the load).",
    ]
    hertz = sorted((r for r in rows if r["study"] == "hertz"), key=lambda r: -r["h"])
    pressure = [r["pressure_err"] for r in hertz]
    if any(e > 0 for e in pressure) and any(e < 0 for e in pressure):
        lines.insert(
            -1,
            f"- The Hertz peak pressure error changes sign ({pressure[0]:+.2%} at the coarsest "
            f"mesh, {pressure[-1]:+.2%} at the finest): it settles near a small limit (the "
            "hertz study finds -0.2 % down to h = 0.006) of the model or of the fitted "
            "estimator, not a discretisation error that still decreases.",
        )
    return "\n".join(lines)
