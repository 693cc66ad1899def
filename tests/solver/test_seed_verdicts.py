"""Verdicts that rest on solutions only: a diverged seed loop reports no force of its last
iterate, and a bone over its limit leaves a frame converged (and unrealistic)."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest

import fem
from contact.app.report import frame_line, parse_line
from contact.geometry.plane import Plane
from contact.grasp import main
from contact.output.summary import verdict
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.fields import held_verdict
from contact.solver.pairs import ContactPair

R = 0.02
E_PAD = 1.0e5
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "finger_press.toml"


@functools.cache
def scene(ratio):
    """A ball (E = ratio * E_PAD) pressed by a plate onto a pad held at its base."""
    ball = ElasticBody(
        "ball",
        fem.ball_mesh(R, divisions=6, layers=3, center=(0, 0, R)),
        fem.LinearElastic(ratio * E_PAD, 0.3),
    )
    side, h = 3 * R, R
    mesh = fem.box_mesh((side, side, h), (8, 8, 4), (-side / 2, -side / 2, -h))
    bottom = np.flatnonzero(np.isclose(mesh.points[:, 2], -h))
    pad = ElasticBody(
        "pad",
        mesh,
        fem.LinearElastic(E_PAD, 0.3),
        prescribed=fem.node_dofs(bottom),
        supports={"base": bottom},
    )
    plate = Plane([0, 0, 2 * R], [0, 0, -1], motion=[0, 0, -0.05 * R], name="plate")
    pairs = [ContactPair(ball, plate), ContactPair(ball, pad), ContactPair(pad, ball)]
    return [ball, pad], pairs, [plate]


def test_a_diverged_seed_loop_reports_what_diverged_and_no_force():
    # a ball 100 times stiffer than the pad, rows both ways, no relaxation: the
    # Dirichlet-Neumann loop diverges within a few iterations
    bodies, pairs, planes = scene(100.0)
    settings = ContactSettings(
        algorithm="seed", relaxation="none", max_iterations=30, support_limits={"base": 1e-6}
    )
    res = solve_frame(bodies, pairs, planes, settings)
    assert not res.converged
    assert res.stop_reason.startswith("diverged: iteration ")
    assert "of pad" in res.stop_reason and "extent" in res.stop_reason
    # the iteration's history keeps how it grew
    assert len(res.history) == res.iterations >= 1
    assert res.history[-1].max_change > 0.06
    # the record holds the bodies at rest: no displacement, no contact, no force
    for b in bodies:
        assert not np.any(res.displacement[b.name])
        assert not np.any(res.contact_force[b.name])
    assert not np.any(res.obstacle_forces["plate"])
    assert not np.any(res.support_forces["pad"]["base"])
    assert res.contacts["node"].size == 0
    # so that nothing blames a bone force of the diverged iterate, even under a tiny limit
    assert res.over_limit == {}
    v = verdict(res)
    assert not v["realistic"]
    assert v["reason"].startswith("not converged: diverged: ")
    assert res.held is None


@pytest.mark.parametrize("algorithm", ["contact-space", "seed"])
def test_a_bone_over_its_limit_leaves_the_frame_converged(algorithm):
    bodies, pairs, planes = scene(0.1)
    free = solve_frame(bodies, pairs, planes, ContactSettings(algorithm=algorithm))
    assert free.converged, free.stop_reason
    force = float(np.linalg.norm(free.support_forces["pad"]["base"]))
    limits = {"base": 0.5 * force}
    limited = solve_frame(
        bodies, pairs, planes, ContactSettings(algorithm=algorithm, support_limits=limits)
    )
    # the same solve as without the limit, converged, and over it
    assert limited.converged and limited.stop_reason == "converged"
    assert limited.iterations == free.iterations
    for b in bodies:
        assert np.array_equal(limited.displacement[b.name], free.displacement[b.name])
    assert limited.over_limit == {"base": (pytest.approx(force), 0.5 * force)}
    # every consumer: unrealistic, naming the bone; held as before; the report's status
    v = verdict(limited)
    assert not v["realistic"]
    assert v["reason"].startswith("bone base carries")
    assert held_verdict(bodies, limited.converged, limited.stop_reason) is True  # the free ball
    entry = {
        "index": 0,
        "time": 0.0,
        "converged": limited.converged,
        "stop_reason": limited.stop_reason,
        "held": True,
        "verdict": v,
        "iterations": limited.iterations,
        "contact_force": {},
        "bone_forces": {},
    }
    line = parse_line(frame_line(entry, 0.1))
    assert line["status"] == "converged" and line["verdict"] == "unrealistic"


def test_a_bone_over_its_limit_still_exits_1(tmp_path):
    """The finger_press example on a 6 mm ball, its first frame, the index bones limited
    to 1 mN: converged, unrealistic, exit status 1."""
    out = tmp_path / "results"
    text = EXAMPLE.read_text()
    text = text.replace("mesh_size = 0.004 ", "mesh_size = 0.006 ")
    text = text.replace(
        "bone_force_limits = { index_distal = 20.0, index_middle = 30.0 }",
        "bone_force_limits = { index_distal = 0.001, index_middle = 0.001 }",
    )
    cut = text.index("[[hand.auto_flexion]]       # then 1 mm")
    text = text[:cut] + text[text.index("[[plane]]") :]
    text = text.replace("times = [0.0, 0.5, 1.0]", "times = [0.5]")
    text = text.replace('directory = "results/finger_press"', f'directory = "{out.as_posix()}"')
    text += "pictures = false\n"
    scene_file = tmp_path / "press.toml"
    scene_file.write_text(text)
    assert main([str(scene_file), "--quiet"]) == 1
    frame = json.loads((out / "summary.json").read_text())["frames"][0]
    assert frame["converged"] and frame["stop_reason"] == "converged"
    assert frame["held"] is True
    assert not frame["verdict"]["realistic"]
    assert "index_distal" in frame["over_limit"]
    assert "bone index_distal carries" in frame["verdict"]["reason"]
