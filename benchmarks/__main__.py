"""Command line: ``python -m benchmarks {assembly,linear_solve,all} [--quick] [--out DIR]``."""

from __future__ import annotations

import argparse
import importlib
import time

from . import BENCHMARKS


def main(argv: list[str] | None = None) -> None:
    """Parse the command line and run the chosen benchmarks."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Benchmarks of fem: stiffness assembly against scikit-fem and the "
        "sparse direct solvers against scipy's spsolve.",
    )
    ap.add_argument("name", choices=[*BENCHMARKS, "all"], help="which benchmark")
    ap.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test of seconds")
    ap.add_argument(
        "--out",
        help="results folder (default benchmarks/results, or benchmarks/results/quick "
        "with --quick)",
    )
    args = ap.parse_args(argv)
    names = BENCHMARKS if args.name == "all" else (args.name,)
    t0 = time.perf_counter()
    for name in names:
        module = importlib.import_module(f"{__package__}.{name}")
        module.run(quick=args.quick, out=args.out)
    print(f"[benchmarks] {', '.join(names)} done in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
