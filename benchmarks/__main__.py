"""Command line: ``python -m benchmarks NAME [NAME ...] [--quick] [--out DIR]`` (or ``all``)."""

from __future__ import annotations

import argparse
import importlib
import time

from . import BENCHMARKS


def main(argv: list[str] | None = None) -> None:
    """Parse the command line and run the chosen benchmarks."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Benchmarks and convergence studies of fem and contact: CSV, markdown "
        "and PNG results with the machine, the versions and the date.",
    )
    ap.add_argument("name", nargs="+", choices=[*BENCHMARKS, "all"], help="which studies")
    ap.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test of seconds")
    ap.add_argument(
        "--out",
        help="results folder (default benchmarks/results, or benchmarks/results/quick "
        "with --quick)",
    )
    args = ap.parse_args(argv)
    names = BENCHMARKS if "all" in args.name else tuple(dict.fromkeys(args.name))
    t0 = time.perf_counter()
    for name in names:
        module = importlib.import_module(f"{__package__}.{name}")
        module.run(quick=args.quick, out=args.out)
    print(f"[benchmarks] {', '.join(names)} done in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
