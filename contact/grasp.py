"""``python -m contact.grasp SCENE.toml``: pose the hand frame by frame and resolve the grasp.

For every frame of the scene (seed 000, Fig. 9):

1. position: the hand's joint angles from the keyframes (Kochanek-Bartels), closed further by
   automatic flexion where the scene asks for it, and every flesh node mapped by JLD; the
   ball placed (it may follow a joint); the planes moved;
2. to 5. the contact iteration (:func:`contact.solver.iteration.solve_frame`), contact space by
   default or the seed's literal loop;

then the frame's bodies, forces and pictures are written
(:class:`contact.output.writer.ResultsWriter`).
The ball is factored once per scene (again only when a joint turns it); the hand once per
pose. Exit status: 0 when every frame converged with every bone under its limit, 1 when a
frame did not converge or a bone passed its limit (everything is still written), 2 for bad
input (one line on stderr naming the file, key or element; nothing written).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np
from numpy.typing import NDArray

import fem

from .ball import LOCKING_NOTE, LOCKING_NU, Ball, make_ball
from .errors import ContactError, InputError
from .geometry.plane import Plane
from .hand.posing import Pose
from .scene.read import Scene
from .solver.body import ElasticBody
from .solver.iteration import solve_frame
from .solver.pairs import ContactPair
from .solver.results import FrameResult, IterationRecord

__all__ = ["GraspRun", "main", "run"]

log = logging.getLogger(__name__)


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("grasp-contact")
    except Exception:  # not installed as a distribution
        return "unknown"


@dataclass
class GraspRun:
    """A scene set up for solving: the bodies that last across frames.

    Parameters
    ----------
    scene : contact.scene.read.Scene
        The loaded scene.
    """

    scene: Scene
    ball: Ball = field(init=False)
    _ball_body: ElasticBody | None = field(default=None, init=False)
    _ball_key: bytes = field(default=b"", init=False)
    _hand_body: ElasticBody | None = field(default=None, init=False)
    _hand_key: bytes = field(default=b"", init=False)
    _pose: Pose | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        sc = self.scene
        self.ball = make_ball(sc.ball)
        self.hand = None
        self.poser = None
        self.nodal_pressure = False
        self.keyframes = None
        if sc.hand is not None:
            from .hand.keyframes import Keyframes
            from .hand.posing import HandPoser
            from .hand.shipped import load_hand

            hs = sc.hand
            self.hand = load_hand(hs.resolution, hs.directory)
            self.poser = HandPoser(self.hand)
            self.keyframes = Keyframes(self.hand.skeleton, list(hs.keyframes))
            self.flesh = fem.LinearElastic(hs.flesh.E, hs.flesh.nu, density=hs.flesh.density)
            # the flesh is linear tetrahedra: averaged nodal pressures where they would
            # lock, as for a tet ball
            nodal = hs.nodal_pressure
            self.nodal_pressure = hs.flesh.nu > LOCKING_NU if nodal is None else nodal
            if not self.nodal_pressure and hs.flesh.nu > LOCKING_NU:
                warnings.warn(
                    f"hand.flesh.nu = {hs.flesh.nu:g} on the flesh's linear tetrahedra with "
                    f"hand.nodal_pressure = false: {LOCKING_NOTE}; averaged nodal pressures "
                    "(the default) do not lock",
                    stacklevel=2,
                )
            names = self.hand.skeleton.bone_names
            self.bones = {n: self.hand.bone_nodes(n) for n in names if self.hand.bone_nodes(n).size}
            self.limits = hs.limits(list(self.bones))
        else:
            self.limits = {}

    # --- step 1: positioning -------------------------------------------------------

    def angles(self, t: float) -> dict[str, float]:
        """The hand's angles at time ``t``: keyframes, then automatic flexion.

        Each automatic flexion's outcome is kept in :attr:`auto_flexed` (joint to angle,
        the node that reached the ball, its distance, converged and why).
        """
        assert self.keyframes is not None and self.hand is not None
        angles = self.keyframes.pose(t)
        self.auto_flexed: dict[str, dict] = {}
        for af in self.scene.hand.auto_flexion:
            if af.times is not None and not any(abs(t - s) <= 1e-12 for s in af.times):
                continue
            from .hand.autoflex import auto_flex, sphere_distance

            res = auto_flex(
                self.hand,
                af.point,
                sphere_distance(self._ball_centre(t), self.ball.spec.radius),
                af.joint,
                angles=angles,
                press=af.press,
                epsilon=af.epsilon,
                first_contact=af.first_contact,
            )
            if not res.converged:
                log.warning("t = %g: automatic flexion of %s: %s", t, af.joint, res.reason)
            self.auto_flexed[af.joint] = {
                "angle": res.angle,
                "node": res.node,
                "distance": res.distance,
                "converged": res.converged,
                "reason": res.reason,
            }
            angles = dict(res.angles)
        return angles

    def ball_transform(self, t: float) -> NDArray[np.float64]:
        """Rigid placement of the ball at ``t`` from its scene position (4x4)."""
        follow = self.scene.follow
        if follow is None or self.hand is None:
            return np.eye(4)
        from .hand.objects import ObjectAssociation

        assoc = ObjectAssociation("ball", follow.joint, follow.start, follow.stop)
        return assoc.transform(self.hand.skeleton, self.keyframes.pose, t)  # type: ignore[union-attr]

    def _ball_centre(self, t: float) -> NDArray[np.float64]:
        tf = self.ball_transform(t)
        return tf[:3, :3] @ np.asarray(self.ball.spec.center, float) + tf[:3, 3]

    def ball_body(self, t: float) -> ElasticBody:
        """The ball placed for ``t``; refactored only when its placement turns it."""
        tf = self.ball_transform(t)
        key = np.round(tf[:3, :3], 12).tobytes()
        x = self.ball.mesh.points @ tf[:3, :3].T + tf[:3, 3]
        if self._ball_body is None or key != self._ball_key:
            mesh = self._placed_mesh(x)
            loads = self.ball.loads.reshape(-1, 3) @ tf[:3, :3].T
            g = self.scene.gravity
            if g is not None:
                loads = loads + fem.gravity_load(mesh, self.ball.material, g).reshape(-1, 3)
            self._ball_body = ElasticBody(
                "ball",
                mesh,
                self.ball.material,
                loads=loads.ravel(),
                contact_faces=self.ball.outer,
                backend=self.scene.solver.linear_solver,
                nodal_pressure=self.ball.nodal_pressure,
            )
            self._ball_key = key
            return self._ball_body
        # a translation: same stiffness, same factorisation, moved points
        return self._ball_body.translated(x)

    def _placed_mesh(self, x: NDArray[np.float64]) -> fem.Mesh:
        m = self.ball.mesh
        return fem.Mesh(x, m.cells, m.regions)

    def hand_body(self, angles: dict[str, float]) -> ElasticBody:
        """The hand posed for ``angles``, factored once per distinct pose."""
        assert self.poser is not None
        key = np.array(sorted(angles.items()), dtype=object).tobytes()
        if self._hand_body is not None and key == self._hand_key:
            return self._hand_body
        # the previous frame's pose warm-starts the flesh's relaxation (HandPoser.pose)
        pose = self.poser.pose(angles, start=self._pose)
        mesh = pose.mesh()
        prescribed = fem.node_dofs(self.hand.prescribed_nodes)  # type: ignore[union-attr]
        self._hand_body = ElasticBody(
            "hand",
            mesh,
            self.flesh,
            prescribed=prescribed,
            supports=self.bones,
            backend=self.scene.solver.linear_solver,
            contact_faces=self.hand.skin_faces,  # type: ignore[union-attr]
            nodal_pressure=self.nodal_pressure,
        )
        self._hand_key = key
        self._pose = pose
        return self._hand_body

    def check_bones(self, ball: ElasticBody, t: float) -> None:
        """Refuse a ball that starts inside a bone: its contact cannot be resolved."""
        from .geometry.surfacequery import TriangleSurface

        hand = self.hand
        assert hand is not None and self._pose is not None
        x = ball.mesh.points[ball.contact_nodes]
        for name, surf in hand.bones.items():
            tf = self._pose.transforms[name]
            pts = np.asarray(surf.points) @ tf[:3, :3].T + tf[:3, 3]
            tri = np.asarray(surf.faces).reshape(-1, 4)[:, 1:]
            s = TriangleSurface(pts, tri, name=f"bone {name}")
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            near = np.all((x >= lo) & (x <= hi), axis=1)
            if near.any() and (s.winding_number(x[near]) > 0.5).any():
                raise InputError(
                    f"frame t = {t:g}: the ball starts inside bone {name}: place the ball "
                    "or close the hand less"
                )

    # --- one frame -----------------------------------------------------------------

    def frame(
        self, t: float, callback: Callable[[IterationRecord], None] | None = None
    ) -> tuple[FrameResult, dict, list[Plane], list[ElasticBody]]:
        """Set up and solve the frame at time ``t``."""
        sc = self.scene
        t0 = time.perf_counter()
        ball = self.ball_body(t)
        bodies = [ball]
        pairs: list[ContactPair] = []
        extra: dict = {}
        if self.hand is not None:
            angles = self.angles(t)
            hand = self.hand_body(angles)
            self.check_bones(ball, t)
            bodies.append(hand)
            pairs += [ContactPair(ball, hand), ContactPair(hand, ball)]
            extra["angles"] = angles
            if self.auto_flexed:
                extra["auto_flexion"] = self.auto_flexed
            assert self._pose is not None
            extra["min_tet_quality"] = float(self._pose.min_quality)
        planes = [Plane(p.point, p.normal, motion=p.offset(t), name=p.name) for p in sc.planes]
        pairs = [ContactPair(ball, p) for p in planes] + pairs
        setup = time.perf_counter() - t0
        settings = sc.solver.settings(self.limits)
        result = solve_frame(bodies, pairs, planes, settings, callback=callback)
        result.timings["setup"] = setup
        return result, extra, planes, bodies


def run(
    scene_path: str | Path,
    *,
    out: str | Path | None = None,
    frames: Sequence[int] | None = None,
    pictures: bool | None = None,
    quiet: bool = False,
) -> int:
    """Run a scene; return the exit status (0 realistic, 1 not, 2 bad input)."""
    from .output.writer import BodyFrame, ResultsWriter, versions
    from .scene.read import load_scene

    try:
        scene = load_scene(scene_path)
    except (ContactError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    times = list(scene.frames)
    chosen = list(range(len(times))) if frames is None else list(frames)
    bad = [i for i in chosen if not 0 <= i < len(times)]
    if bad:
        print(
            f"error: --frames {bad[0]}: the scene has frames 0..{len(times) - 1}",
            file=sys.stderr,
        )
        return 2
    directory = Path(out) if out is not None else scene.output.directory
    show = scene.output.pictures if pictures is None else pictures
    try:
        writer = ResultsWriter(
            directory,
            pictures=show,
            gif=scene.output.gif and show,
            window_size=scene.output.window_size,
        )
    except (ContactError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    bar = _progress(len(chosen), quiet)
    status = 0
    try:
        run_ = GraspRun(scene)
        for i in chosen:
            t = times[i]
            bar.set_description(f"t = {t:g}")

            def tell(rec: IterationRecord) -> None:
                bar.set_postfix(
                    iteration=rec.iteration, change=f"{rec.max_change:.2e}", refresh=True
                )

            result, extra, planes, solved = run_.frame(t, tell)
            # the hand drawn half transparent, so that the ball's stress shows through
            bodies = {
                b.name: BodyFrame(
                    b.mesh,
                    b.materials,
                    opacity=0.5 if b.name == "hand" else 1.0,
                    bbar=b.bbar,
                    nodal_pressure=b.nodal_pressure,
                )
                for b in solved
            }
            entry = writer.add_frame(
                i,
                t,
                result,
                bodies,
                planes=[(p.name, p.point + p.motion, p.normal) for p in planes],
                extra=extra,
            )
            if not entry["verdict"]["realistic"]:
                status = 1
            log.info("t = %g: %s", t, entry["verdict"]["reason"])
            bar.update(1)
        writer.finish(scene.echo(), versions=versions())
    except (ContactError, ValueError, fem.FemError) as exc:
        writer.abort()
        bar.close()
        print(f"error: {scene.path}: {exc}", file=sys.stderr)
        return 2
    except BaseException:
        writer.abort()
        bar.close()
        raise
    bar.close()
    if not quiet:
        print(f"results in {directory}", file=sys.stderr)
    return status


def _progress(total: int, quiet: bool):
    from tqdm import tqdm

    return tqdm(
        total=total,
        unit="frame",
        disable=quiet or not sys.stderr.isatty(),
        file=sys.stderr,
        dynamic_ncols=True,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The command line; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m contact.grasp",
        description="Pose a hand by keyframes and resolve its contact with a deformable "
        "ball, frame by frame; write the displacements, stresses, contact and bone forces, "
        "pictures and a summary with the verdict (is the grasp realistic?).",
        epilog="Exit status: 0 every frame converged with every bone under its limit; 1 a "
        "frame did not converge or a bone passed its limit (results are still written); 2 "
        "bad input (nothing written). The scene keys are documented in docs/scene.md.",
    )
    ap.add_argument("scene", help="the scene file (TOML; see docs/scene.md)")
    ap.add_argument(
        "--out",
        metavar="DIR",
        help="results folder (default: the scene's output.directory); an existing folder "
        "is replaced only once the new results are complete",
    )
    ap.add_argument(
        "--frames",
        metavar="I",
        type=int,
        nargs="+",
        help="solve only these frames (0-based indices into the scene's frame times)",
    )
    ap.add_argument(
        "--no-pictures", action="store_true", help="write no PNG frames, GIF or stress pictures"
    )
    ap.add_argument(
        "--quiet", action="store_true", help="no progress bar and no log messages but errors"
    )
    ap.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    args = ap.parse_args(argv)
    logging.basicConfig(
        level=logging.ERROR if args.quiet else logging.WARNING,
        format="%(levelname)s: %(message)s",
    )
    # a warning (a mesh coarser than the wall, a pressure beyond small strains) is one
    # line on stderr like the log's, not a source line and a traceback-like location
    shown = warnings.showwarning
    warnings.showwarning = _warn_line
    try:
        return run(
            args.scene,
            out=args.out,
            frames=args.frames,
            pictures=False if args.no_pictures else None,
            quiet=args.quiet,
        )
    finally:
        warnings.showwarning = shown


def _warn_line(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """A warning as one log line (suppressed by ``--quiet`` as the log is)."""
    log.warning("%s", message)


if __name__ == "__main__":
    sys.exit(main())
