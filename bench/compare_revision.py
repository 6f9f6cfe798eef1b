"""The feature paths of this checkout against an earlier revision, in one process, interleaved.

    python bench/compare_revision.py --before 5ca0f8c [--rounds 6]

Loads ``tactile_torch/{_checks,_parallel,image,signal}.py`` of ``--before`` (``git show``; a revision
from before ``image`` and ``signal`` became packages) as a package of their own, next to the current
code, and times both on the same inputs, alternating the order every round so that the load of a
shared machine falls on both alike: wall time (median and minimum over the rounds) at one thread and at
the default thread count, and the CPU time of a call at one thread (the work itself, whatever the load).
Inputs: 8 explorations of 100 frames of 96 x 96 and one exploration (``exploration_features``), 4096,
20 and 1 windows of 800 samples (``window_features``). Checks that both give equal results. Prints a
Markdown table; docs/performance quotes its output. Not part of ``make bench`` (it needs git).
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.common import DEFAULT_THREADS, source_at, threads  # noqa: E402
from tactile_torch import image, signal  # noqa: E402
from tactile_torch.data.images import make_explorations  # noqa: E402
from tactile_torch.data.stylus import make_vibration_dataset  # noqa: E402

MODULES = ("_checks", "_parallel", "image", "signal")


def _load(revision: str):
    """The modules of ``revision`` as the package ``tactile_torch_before``; returns (image, signal)."""
    package = Path(tempfile.mkdtemp()) / "tactile_torch_before"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for name in MODULES:
        (package / f"{name}.py").write_text(source_at(revision, f"tactile_torch/{name}.py"))
    sys.path.insert(0, str(package.parent))
    return (importlib.import_module(f"tactile_torch_before.{name}") for name in ("image", "signal"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="5ca0f8c", help="git revision to compare with")
    parser.add_argument("--rounds", type=int, default=6)
    args = parser.parse_args()
    before_image, before_signal = _load(args.before)
    explorations = make_explorations(2, n_frames=100, frame_size=96, random_state=0).frames
    frames = explorations[torch.arange(8) % len(explorations)].contiguous()
    windows = make_vibration_dataset(28, windows_per_surface=147, window_size=800, random_state=0).windows
    windows = windows[:4096].contiguous()
    cases = {
        "exploration_features, 8 x 100 x 96 x 96": (image, before_image, "exploration_features", frames),
        "exploration_features, 1 x 100 x 96 x 96": (image, before_image, "exploration_features", frames[:1]),
        "window_features, 4096 x 800": (signal, before_signal, "window_features", windows),
        "window_features, 20 x 800": (signal, before_signal, "window_features", windows[:20]),
        "window_features, 1 x 800": (signal, before_signal, "window_features", windows[:1]),
    }
    for name, (after, before, fn, x) in cases.items():
        assert torch.equal(getattr(after, fn)(x), getattr(before, fn)(x)), f"{name}: results differ"
    wall: dict[tuple, list[float]] = {}
    cpu: dict[tuple, list[float]] = {}
    loads = []
    for rnd in range(args.rounds):
        order = (("before", 1), ("after", 0)) if rnd % 2 else (("after", 0), ("before", 1))
        for n in sorted({1, DEFAULT_THREADS}):
            with threads(n):
                for name, case in cases.items():
                    repeat = 3 if "4096" in name or "8 x" in name else 20
                    for label, k in order:
                        module = case[k]
                        fn = getattr(module, case[2])
                        fn(case[3])
                        for _ in range(repeat):
                            start, start_cpu = time.perf_counter(), time.process_time()
                            fn(case[3])
                            wall.setdefault((name, n, label), []).append(time.perf_counter() - start)
                            if n == 1:
                                cpu.setdefault((name, label), []).append(time.process_time() - start_cpu)
        loads.append(os.getloadavg()[0])
    print(
        f"{args.rounds} rounds, load average {min(loads):.1f}-{max(loads):.1f}; ms per call, before / after"
    )
    print()
    print("| call | threads | wall median | wall min | CPU median (1 thread) |")
    print("|---|---|---|---|---|")
    for name in cases:
        for n in sorted({1, DEFAULT_THREADS}):
            b, a = wall[(name, n, "before")], wall[(name, n, "after")]
            cells = [
                f"{1e3 * statistics.median(b):.2f} / {1e3 * statistics.median(a):.2f}",
                f"{1e3 * min(b):.2f} / {1e3 * min(a):.2f}",
            ]
            if n == 1:
                cb, ca = cpu[(name, "before")], cpu[(name, "after")]
                cells.append(f"{1e3 * statistics.median(cb):.2f} / {1e3 * statistics.median(ca):.2f}")
            else:
                cells.append("")
            print(f"| {name} | {n} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
