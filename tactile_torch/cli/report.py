"""``tactile-torch report``: run every study on the bundled data and write the report (``make run``)."""

from __future__ import annotations

import argparse

from ._options import SEED


def register(sub) -> None:
    """Add the ``report`` command to the subparsers ``sub``."""
    p = sub.add_parser("report", help="run every pipeline on the bundled data and write a report (make run)")
    p.add_argument("--out", default="runs/latest", help="output directory (default: runs/latest)")
    p.add_argument("--seed", type=SEED, default=0, help="random seed of the whole run (default: 0)")
    size = p.add_mutually_exclusive_group()
    size.add_argument(
        "--quick", action="store_true", help="smaller data and fewer iterations, for a smoke test"
    )
    size.add_argument(
        "--full", action="store_true", help="also the study-size experiments (minutes, not seconds)"
    )
    p.add_argument("--only", default="", help="comma-separated study names to run (default: all)")
    p.set_defaults(handler=run_report)


def run_report(args: argparse.Namespace) -> int:
    """Write the report; return the exit status."""
    from ..studies import run_report as write_report

    only = [s for s in args.only.split(",") if s] if args.only else None
    path = write_report(args.out, random_state=args.seed, quick=args.quick, full=args.full, only=only)
    print(f"report written to {path}")
    return 0
