"""``python -m contact.sweep SWEEP.toml``: many scenes run on a Dask cluster.

The command (:mod:`.command`), the sweep file (:mod:`.spec`), the table of runs
(:mod:`.table`) and the cluster (:mod:`.cluster`); ``docs/sweep.md``.
"""

from __future__ import annotations

from .command import EXIT_STATUS, main, run_one, sweep

__all__ = ["EXIT_STATUS", "main", "run_one", "sweep"]
