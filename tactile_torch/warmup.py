"""Compile the package's numba kernels ahead of their first use and cache them on disk.

``make install`` runs ``python -m tactile_torch.warmup`` once, so that a user's first fit does not
wait for the compiler. The kernels are compiled eagerly (explicit signatures, ``cache=True``) when
their module is imported: importing them here compiles them, or loads them from the cache.
"""

from __future__ import annotations

import importlib
import sys
import time

COMPILED_MODULES = (
    "tactile_torch.mixture._gibbs",
    "tactile_torch.mixture._partition",
    "tactile_torch.svm._smo",
    "tactile_torch.svm.tree",
)
"""Modules whose import compiles (or loads from the on-disk cache) numba kernels."""


def warm_up(modules: tuple[str, ...] = COMPILED_MODULES) -> dict[str, float]:
    """Import every module of ``modules``; return the seconds each import took."""
    seconds = {}
    for name in modules:
        start = time.perf_counter()
        importlib.import_module(name)
        seconds[name] = time.perf_counter() - start
    return seconds


def main() -> int:
    for name, s in warm_up().items():
        print(f"compiled {name} in {s:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
