"""Timing, thread pinning and peak-memory helpers shared by the benchmark modules.

Every benchmark runs its reference (SciPy/NumPy/scikit-learn) in the same process and the same run,
at one thread (fair comparison) and at the default thread count, and reports the ratio.
"""

from __future__ import annotations

import contextlib
import gc
import os
import statistics
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import torch
from threadpoolctl import threadpool_limits

DEFAULT_THREADS = torch.get_num_threads()


@contextlib.contextmanager
def threads(n: int | None) -> Iterator[int]:
    """Limit torch and the BLAS/OpenMP pools of numpy and scipy to ``n`` threads (``None``: default)."""
    n = DEFAULT_THREADS if n is None else n
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        with threadpool_limits(limits=n):
            yield n
    finally:
        torch.set_num_threads(before)


def time_call(fn: Callable[[], object], *, repeat: int = 5, warmup: int = 1, min_time: float = 0.0) -> dict:
    """Time ``fn()``: ``warmup`` untimed calls, then ``repeat`` timed ones (more until ``min_time`` s).

    Returns the median, minimum and 99th-percentile-ish maximum in seconds and the number of calls.
    """
    for _ in range(warmup):
        fn()
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < repeat or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    times.sort()
    p99 = times[min(len(times) - 1, int(0.99 * len(times)))]
    return {"median_s": statistics.median(times), "min_s": times[0], "p99_s": p99, "calls": len(times)}


def time_threads_alternately(
    fn: Callable[[], object], *, repeat: int = 5, warmup: int = 1, counts: tuple[int, ...] | None = None
) -> dict[int, float]:
    """Fastest time of ``fn()`` in seconds at each thread count, the counts taking turns call by call.

    One call at one thread, one at the default count, and so on ``repeat`` times (after ``warmup``
    untimed calls at each): on a shared machine the load changes over seconds, and alternating puts
    it on both counts alike, so their ratio carries where two separate timings would not.
    """
    counts = counts or tuple(sorted({1, DEFAULT_THREADS}))
    best = dict.fromkeys(counts, float("inf"))
    for n in counts:
        with threads(n):
            for _ in range(warmup):
                fn()
    for _ in range(repeat):
        for n in counts:
            with threads(n):
                start = time.perf_counter()
                fn()
                best[n] = min(best[n], time.perf_counter() - start)
    return best


def _status_kib(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"{field} not found in /proc/self/status")


def peak_memory_mib(fn: Callable[[], object]) -> float:
    """Return the peak resident memory that ``fn()`` adds above the current resident size, in MiB.

    Resets the kernel's high-water mark (``/proc/self/clear_refs``), runs ``fn`` once and reads
    ``VmHWM``; Linux only. Returns NaN where the mark cannot be reset.
    """
    gc.collect()
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        return float("nan")
    base = _status_kib("VmRSS")
    fn()
    return (_status_kib("VmHWM") - base) / 1024.0


def source_at(revision: str, path: str) -> str:
    """The text of ``path`` (relative to the repository's root) at git ``revision``."""
    root = Path(__file__).resolve().parents[1]
    return subprocess.run(
        ["git", "show", f"{revision}:{path}"], cwd=root, check=True, capture_output=True, text=True
    ).stdout


def machine() -> dict:
    """Describe the machine the numbers come from."""
    import platform

    return {
        "python": platform.python_version(),
        "torch": torch.__version__,
        "cpu_count": os.cpu_count(),
        "default_threads": DEFAULT_THREADS,
        "processor": platform.processor() or platform.machine(),
    }
