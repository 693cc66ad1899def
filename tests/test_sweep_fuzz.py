"""200 mutated sweep files through the sweep's command line: never a traceback, never exit 3.

Each case mutates a valid sweep file (keys deleted, wrong types, huge, negative and NaN
numbers, unknown keys, ranges, sizes past the bound, broken TOML) and its command line
(scheduler addresses, worker and thread counts), then runs ``contact.sweep.main`` in its own
folder. The cluster and the runs are stubbed (a scheduler never answers, each run is done at
once), so the cases that pass validation write their table and plot in milliseconds. A case
exits 0, 1 or 2; exit 2 is one line on stderr and leaves nothing written.
"""

from __future__ import annotations

import copy
import datetime
import math
import random
from pathlib import Path

import pytest

pytest.importorskip("distributed")

import contact.sweep.command
from contact.sweep.command import main
from contact.sweep.spec import dump_toml
from contact.sweep.table import figures

PADS = Path(__file__).resolve().parents[1] / "examples" / "pads.toml"
CASES = 200
#: The cases run as this many tests, each a few seconds at most.
CHUNKS = 4

BASE = {
    "sweep": {"scene": "pads.toml", "mode": "product", "pictures": False,
              "least_grip": False, "directory": "swept"},
    "vary": {"plane[0].friction": [0.5, 0.6],
             "ball.material.E": {"start": 5e5, "stop": 1e6, "num": 2}},
    "plot": {"y": "grip_force"},
}  # fmt: skip
ODD = [
    "x", "", "\x00", "sub/dir", 0, 1, -1, 3, 10**9, -(10**18), 2**63 - 1, 1e308, -1e308,
    math.nan, math.inf, -math.inf, 0.5, -0.5, True, False, [], [1, "a"], [[0.1, 0.2]], [math.nan],
    [1e308], {}, {"start": 1}, {"start": 0.1, "stop": 0.9, "num": 10**9},
    {"start": math.nan, "stop": 1.0, "num": 3}, {"start": 0.1, "stop": 0.9, "num": -4},
    {"start": 0.1, "stop": 0.9, "num": 2.5}, {"a": {"b": 1}}, datetime.date(2020, 1, 1),
    datetime.time(7, 32),
]  # fmt: skip
KEYS = [
    "ball.colour", "plane[9].friction", "plane[0]", "scene", "ball", "ball.radius.x", "a..b",
    "[0]", "hand.friction", "frames.times", "output.directory", "ball.radius",
    "ball.material.nu", "plane[1].force", "solver.max_iterations", "x[99999999999999999999]",
    "plane[1].friction", "ball.friction", "scene.gravity",
]  # fmt: skip
SCHEDULERS = [
    "", "not a url", "tcp://", "tcp://127.0.0.1:0", "tcp://127.0.0.1:70000", "http://h:1",
    "tcp://127.0.0.1:8786", "[::1]:8786", "tcp://[::1]:8786", "a b:1", "x" * 5000,
    "tcp://h:1\n2", "tls://h:-1", "inproc://x", "tcp://h:8786/path",
]  # fmt: skip
COUNTS = ["1000", "0", "-3", "1e9", "nan", "two", "99999999999999999999", "1", "2", " 3"]


def _tables(doc: dict) -> list[dict]:
    out = [doc]
    for v in doc.values():
        if isinstance(v, dict):
            out.extend(_tables(v))
    return out


def _mutate(rng: random.Random, doc: dict) -> None:
    """One mutation of a parsed sweep file, in place."""
    kind = rng.choice(["delete", "retype", "unknown", "key", "range", "size", "mode"])
    tables = [t for t in _tables(doc) if t]
    if kind == "delete" and tables:
        t = rng.choice(tables)
        del t[rng.choice(list(t))]
    elif kind == "retype" and tables:
        t = rng.choice(tables)
        t[rng.choice(list(t))] = copy.deepcopy(rng.choice(ODD))
    elif kind == "unknown":
        rng.choice(_tables(doc))[rng.choice(["zzz", "Scene", "vary", "y"])] = rng.choice(ODD)
    elif kind == "key":
        value = rng.choice([[0.4, 0.5], [0.45], copy.deepcopy(rng.choice(ODD))])
        doc.setdefault("vary", {})[rng.choice(KEYS)] = value
    elif kind == "range":
        num = rng.choice([10**9, 10_001, -1, 0, 3, math.nan, 2.5, "3", 10**18])
        start = rng.choice([0.3, -1e308, 1e308, math.nan, math.inf, "a"])
        doc.setdefault("vary", {})[rng.choice(KEYS)] = {"start": start, "stop": 0.6, "num": num}
    elif kind == "size":
        n = rng.choice([30, 101, 10_001])
        doc["vary"] = {k: [0.3 + i * 1e-6 for i in range(n)] for k in rng.sample(KEYS, 3)}
    else:
        doc.setdefault("sweep", {})["mode"] = rng.choice(["zip", "product", "cartesian", 1])


def _case(rng: random.Random) -> tuple[str, list[str]]:
    """A mutated sweep file's text and the command line's options."""
    doc = copy.deepcopy(BASE)
    for _ in range(rng.choice([0, 1, 1, 2, 3])):
        _mutate(rng, doc)
    text = dump_toml(doc)
    if rng.random() < 0.05:  # broken TOML
        text = text[: rng.randrange(len(text))] + rng.choice(["", "[[", "= =", "\x00", '"'])
    argv = ["--quiet"]
    if rng.random() < 0.8:
        argv.append("--out=out")
    if rng.random() < 0.3:
        argv.append(f"--scheduler={rng.choice(SCHEDULERS)}")
    for flag in ("--workers", "--threads"):
        if rng.random() < 0.2:
            argv.append(f"{flag}={rng.choice(COUNTS)}")
    return text, argv


def _stub(monkeypatch, rng: random.Random) -> None:
    """No cluster and no solve: a scheduler never answers, a run is done (or not) at once."""

    class Client:
        def close(self) -> None:
            pass

    def client(scheduler, workers, threads):
        if scheduler is not None:
            raise OSError("stubbed: no scheduler here")
        return Client(), None

    def submit(client, todo, sw, threads, rows, quiet):
        for r, _ in todo:
            ok = rng.random() < 0.8
            summary = {"all_converged": ok, "all_realistic": ok,
                       "frames": [{"held": rng.choice([True, False, None]),
                                   "grip_force": rng.random(), "iterations": 3}]}  # fmt: skip
            res = {**figures(summary), "status": "done"} if rng.random() < 0.9 else {
                "status": "failed: ValueError: stubbed", "exit_status": 3}  # fmt: skip
            rows[r.index] = {"run": r.name, **r.values, **res}

    monkeypatch.setattr(contact.sweep.command, "client", client)
    monkeypatch.setattr(contact.sweep.command, "_submit", submit)


@pytest.mark.parametrize("chunk", range(CHUNKS))
def test_mutated_sweep_files_never_raise(tmp_path, monkeypatch, capsys, chunk):
    rng = random.Random(45 + chunk)
    _stub(monkeypatch, rng)
    pads = PADS.read_text()
    seen = {0: 0, 1: 0, 2: 0}
    for i in range(CASES // CHUNKS):
        text, argv = _case(rng)
        case = tmp_path / f"{i:03d}"
        case.mkdir()
        (case / "pads.toml").write_text(pads)
        (case / "sweep.toml").write_text(text)
        monkeypatch.chdir(case)  # sweep.directory and --out are relative to it
        try:
            rc = main(["sweep.toml", *argv])
        except SystemExit as exc:  # argparse: its usage and one error line
            rc = exc.code
            assert rc == 2, (i, argv)
            capsys.readouterr()
            continue
        out, err = capsys.readouterr()
        where = f"case {i}: {argv}\n{text}\n{err}"
        assert rc in seen, where
        assert "Traceback" not in out + err, where
        seen[rc] += 1
        if rc == 2:
            assert err.startswith("error: ") and err.count("\n") == 1, where
            assert sorted(p.name for p in case.iterdir()) == ["pads.toml", "sweep.toml"], where
        else:
            assert err == "", where
            assert any(case.glob("*/sweep.csv")) and any(case.glob("*/sweep.png")), where
    assert seen[2] > CASES // CHUNKS // 2 and seen[0] + seen[1] > 0, seen  # both paths taken
