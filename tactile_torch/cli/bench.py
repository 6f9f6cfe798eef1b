"""``tactile-torch bench``: run the benchmarks of the source checkout (``bench/run.py``) into ``--out``."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from ._codes import NOT_BUILT_EXIT


def register(sub) -> None:
    """Add the ``bench`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "bench", help="run the benchmarks and write their results to --out (make bench: bench/results)"
    )
    p.add_argument("--quick", action="store_true", help="small sizes, for a smoke test")
    p.add_argument("--only", default="", help="comma-separated benchmark names (default: all)")
    p.add_argument(
        "--out",
        default="runs/bench",
        help="directory for the results (default: runs/bench; `make bench` writes bench/results)",
    )
    p.set_defaults(handler=run_bench)


def run_bench(args: argparse.Namespace) -> int:
    """Run ``bench/run.py`` in a child process; return its exit status."""
    runner = Path(__file__).resolve().parents[2] / "bench" / "run.py"
    if not runner.exists():
        print(
            "tactile-torch bench: the benchmarks live in the source checkout (bench/run.py), "
            f"which was not found at {runner.parent}",
            file=sys.stderr,
        )
        return NOT_BUILT_EXIT
    cmd = [
        sys.executable,
        str(runner),
        *(["--quick"] if args.quick else []),
        *(["--only", args.only] if args.only else []),
        "--out",
        str(Path(args.out).resolve()),
    ]
    print(f"tactile-torch bench: results go to {args.out}", file=sys.stderr)
    return subprocess.call(cmd)
