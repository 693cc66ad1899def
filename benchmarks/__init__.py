"""Benchmarks of the ``fem`` library against reference implementations.

Run them with ``python -m benchmarks NAME [NAME ...] [--quick]`` where ``NAME`` is one
of :data:`BENCHMARKS` or ``all``. Full runs write CSV, markdown and PNG results into
``benchmarks/results/``; ``--quick`` runs tiny sizes in seconds (a smoke test) and writes
into ``benchmarks/results/quick/`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

__all__ = ["BENCHMARKS"]

#: Benchmark names runnable from the command line, in the order ``all`` runs them.
BENCHMARKS = (
    "assembly",
    "linear_solve",
    "scaling",
    "queries",
    "convergence",
    "hertz",
    "hertz_bodies",
    "iteration",
    "lcp",
    "frame",
    "patch",
    "patch_gaps",
    "plates",
    "flexion",
    "friction",
    "holding",
    "finite",
    "sweep",
    "posing",
    "sfepy_hertz",
    "sfepy_patch",
)
