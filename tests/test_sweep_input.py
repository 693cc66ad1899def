"""The sweep's command line on bad or huge input, interrupts and internal errors: one line on
stderr, the promised exit status, in seconds, nothing written; and its table's ``held`` and
plot. No run is solved: the cluster and the runs are stubbed where a sweep gets that far."""

from __future__ import annotations

import os
import signal
import socket
import tempfile
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

import contact.sweep.cluster
import contact.sweep.command
from contact.sweep.command import EXIT_STATUS, main
from contact.sweep.spec import MAX_RUNS
from contact.sweep.table import _figure, columns, figures, write_table

PADS = Path(__file__).resolve().parents[1] / "examples" / "pads.toml"


def _files(tmp: Path, vary: str) -> Path:
    (tmp / "pads.toml").write_text(PADS.read_text())
    path = tmp / "sweep.toml"
    path.write_text(f'[sweep]\nscene = "pads.toml"\n\n[vary]\n{vary}\n')
    return path


def one_line(err: str) -> str:
    err = err.strip()
    assert err and "\n" not in err and "Traceback" not in err, err
    return err


class FakeClient:
    """Stands for a Dask client: the stubbed runs never reach it."""

    closed = False

    def close(self) -> None:
        self.closed = True


def _stub_cluster(monkeypatch, submit=None) -> list:
    """Stub the cluster (its calls recorded) and the runs (each done, or ``submit``)."""
    calls: list = []

    def client(scheduler, workers, threads):
        calls.append((scheduler, workers, threads, FakeClient()))
        return calls[-1][3], None

    def done(client, todo, sw, threads, rows, quiet):
        summary = {"all_converged": True, "all_realistic": True,
                   "frames": [{"held": True, "grip_force": 1.0, "iterations": 3}]}  # fmt: skip
        for r, _ in todo:
            rows[r.index] = {"run": r.name, **r.values, **figures(summary), "status": "done"}

    monkeypatch.setattr(contact.sweep.command, "client", client)
    monkeypatch.setattr(contact.sweep.command, "_submit", submit or done)
    return calls


def test_the_epilog_lists_every_exit_status():
    for code in ("0 every", "1 a run", "2 bad input", "3 an internal", "130", "143"):
        assert code in EXIT_STATUS


def test_a_thousand_workers_are_held_to_the_cores_and_the_runs(tmp_path, monkeypatch, caplog):
    calls = _stub_cluster(monkeypatch)
    sw = _files(tmp_path, '"plane[0].friction" = [0.4, 0.5, 0.6]')
    out = tmp_path / "out"
    assert main([str(sw), "--out", str(out), "--workers", "1000", "--threads", "9999"]) == 0
    ((scheduler, workers, threads, _),) = calls
    cores = os.cpu_count() or 1
    assert scheduler is None and workers == min(cores, 3) and threads == cores
    said = " ".join(r.getMessage() for r in caplog.records if r.levelname == "WARNING")
    assert f"--workers 1000: held to {workers}" in said and "--threads 9999: held to" in said
    assert (out / "sweep.csv").is_file()


def test_a_range_of_a_billion_runs_is_refused_at_once(tmp_path, capsys):
    sw = _files(tmp_path, '"ball.material.E" = { start = 5e5, stop = 1e6, num = 1000000000 }')
    out = tmp_path / "out"
    t0 = time.perf_counter()
    assert main([str(sw), "--out", str(out), "--quiet"]) == 2
    assert time.perf_counter() - t0 < 2.0
    err = one_line(capsys.readouterr().err)
    assert "vary.ball.material.E.num = 1000000000" in err and f"{MAX_RUNS:,} runs" in err
    assert not out.exists()


def test_a_product_past_the_bound_is_refused_with_its_count(tmp_path, capsys, monkeypatch):
    _stub_cluster(monkeypatch)  # were it not refused, nothing would run
    values = "[" + ", ".join(str(0.3 + i / 100) for i in range(25)) + "]"
    sw = _files(tmp_path, "\n".join(f'"{k}" = {values}' for k in
                                    ("plane[0].friction", "plane[1].friction", "ball.friction")))
    out = tmp_path / "out"
    t0 = time.perf_counter()
    assert main([str(sw), "--out", str(out), "--quiet"]) == 2
    assert time.perf_counter() - t0 < 2.0
    err = one_line(capsys.readouterr().err)
    assert "15,625 runs (25 x 25 x 25)" in err and f"bound of {MAX_RUNS:,} runs" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "address",
    ["not a url", "", "tcp://", "tcp://host:0", "tcp://host:99999", "http://host:8786",
     "tcp://a b:8786", "host"],
)  # fmt: skip
def test_a_bad_scheduler_address_exits_2_before_anything(tmp_path, capsys, address):
    sw = _files(tmp_path, '"plane[0].friction" = [0.5]')
    out = tmp_path / "out"
    assert main([str(sw), "--out", str(out), "--quiet", "--scheduler", address]) == 2
    err = one_line(capsys.readouterr().err)
    assert err.startswith(f"error: --scheduler {address!r}: not a scheduler address")
    assert not out.exists()


def test_a_scheduler_that_accepts_and_never_answers_exits_2_in_time(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(contact.sweep.cluster, "SCHEDULER_TIMEOUT", 1.0)
    server = socket.create_server(("127.0.0.1", 0))
    held = []
    threading.Thread(target=lambda: held.append(server.accept()), daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    sw = _files(tmp_path, '"plane[0].friction" = [0.5]')
    out = tmp_path / "out"
    got: list[int] = []
    # in a thread: a sweep that hangs fails the test instead of holding it
    worker = threading.Thread(target=lambda: got.append(main(
        [str(sw), "--out", str(out), "--quiet", "--scheduler", address])), daemon=True)
    t0 = time.perf_counter()
    worker.start()
    worker.join(timeout=8.0)
    server.close()
    assert got == [2] and time.perf_counter() - t0 < 8.0
    err = one_line(capsys.readouterr().err)
    assert address in err and "does not answer within 1 s" in err
    assert not out.exists()  # no runs/0000 left behind


def test_a_generated_scene_that_does_not_load_leaves_nothing(tmp_path, capsys):
    sw = _files(tmp_path, '"ball.material.nu" = [0.3, 0.7]')
    out = tmp_path / "out"
    assert main([str(sw), "--out", str(out), "--quiet"]) == 2
    err = one_line(capsys.readouterr().err)
    assert err.startswith("error: run 0001 (ball.material.nu = 0.7): ")
    assert str(out / "runs" / "0001" / "scene.toml") in err and not out.exists()


def test_ctrl_c_is_one_line_and_exit_130_and_the_cluster_is_closed(tmp_path, capsys, monkeypatch):
    def interrupted(*args):
        raise KeyboardInterrupt

    calls = _stub_cluster(monkeypatch, interrupted)
    sw = _files(tmp_path, '"plane[0].friction" = [0.5]')
    assert main([str(sw), "--out", str(tmp_path / "out"), "--quiet"]) == 130
    assert one_line(capsys.readouterr().err).startswith("interrupted; the runs done are kept")
    assert calls[0][3].closed


def test_sigterm_is_one_line_and_exit_143(tmp_path, capsys, monkeypatch):
    class Unhandled(Exception):
        """What SIGTERM raises here unless the sweep's own handler takes it."""

    def unhandled(signum, frame):
        raise Unhandled

    def terminated(*args):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler's exception lands here

    before = signal.signal(signal.SIGTERM, unhandled)
    try:
        calls = _stub_cluster(monkeypatch, terminated)
        sw = _files(tmp_path, '"plane[0].friction" = [0.5]')
        assert main([str(sw), "--out", str(tmp_path / "out"), "--quiet"]) == 143
        assert signal.getsignal(signal.SIGTERM) is unhandled  # put back
    finally:
        signal.signal(signal.SIGTERM, before)
    assert one_line(capsys.readouterr().err).startswith("interrupted; the runs done are kept")
    assert calls[0][3].closed


def test_an_internal_error_is_exit_3_with_one_line_and_a_log_file(tmp_path, capsys, monkeypatch):
    def broken(path):
        raise RuntimeError("a bug\nin two lines")

    monkeypatch.setattr(contact.sweep.command, "load_sweep", broken)
    sw = _files(tmp_path, '"plane[0].friction" = [0.5]')
    assert main([str(sw), "--out", str(tmp_path / "out"), "--quiet"]) == 3
    err = one_line(capsys.readouterr().err)
    assert err.startswith("error: internal error: RuntimeError: a bug; traceback in ")
    log = Path(err.split("traceback in ")[1].split(";")[0])
    try:
        assert log.parent == Path(tempfile.gettempdir())
        text = log.read_text()
        assert "Traceback" in text and "in two lines" in text and "broken" in text
    finally:
        log.unlink(missing_ok=True)


@pytest.mark.parametrize(
    ("helds", "want"),
    [([True, True], True), ([True, None], None), ([None], None), ([True, False, None], False),
     ([], None)],
)  # fmt: skip
def test_held_is_yes_only_when_every_frame_held(tmp_path, helds, want):
    summary = {"all_converged": False, "frames": [{"held": h} for h in helds]}
    row = {"run": "0000", "k": 1.0, **figures(summary), "status": "done"}
    assert row["held"] is want
    write_table([row], columns(["k"], least=False), tmp_path)
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    header, cells = lines[0].split(","), lines[1].split(",")
    assert cells[header.index("held")] == {True: "True", False: "False", None: ""}[want]


def test_the_plot_marks_runs_that_did_not_converge_and_has_units():
    import matplotlib.pyplot as plt

    def row(i, e, converged, status="done"):
        return {"run": f"{i:04d}", "ball.material.E": e, "status": status,
                "converged": converged, "grip_force": 1.0 + i}  # fmt: skip

    rows = [row(0, 5e5, True), row(1, 7.5e5, False), row(2, 1e6, True),
            row(3, 1.25e6, None, "failed: ValueError: x")]  # fmt: skip
    fig = _figure(rows, ["ball.material.E"], "grip_force")
    try:
        ax = fig.axes[0]
        assert ax.get_xlabel() == "ball.material.E (Pa)" and ax.get_ylabel() == "grip_force (N)"
        marks = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
        hollow = [ln for ln in marks if ln.get_markerfacecolor() == "none"]
        filled = [ln for ln in marks if ln.get_markerfacecolor() != "none"]
        assert [list(ln.get_xdata()) for ln in hollow] == [[7.5e5]]
        assert sorted(x for ln in filled for x in ln.get_xdata()) == [5e5, 1e6]
        legend = ax.get_legend()
        assert legend is not None and "did not converge" in [t.get_text() for t in legend.texts]
    finally:
        plt.close(fig)
