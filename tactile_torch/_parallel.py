"""Block parallelism for the eager feature paths: threads whose own torch ops run serially.

Used by :mod:`tactile_torch.signal` and :mod:`tactile_torch.image`. A block's dozens of short passes
cost less than one synchronisation of torch's intra-op pool (on a loaded 2-core machine a parallel
op on a small tensor stalls for milliseconds: a 3 x 800 ``rfft`` took 12-16 ms at two threads
against 0.02 ms at one), so the callers cut their input into blocks that fit the CPU cache and run
whole blocks on separate Python threads instead (torch releases the GIL inside its ops).

"Serially" is a setting of the *thread* that runs the ops, never of the process: torch's CPU ops
parallelise through OpenMP (and its FFTs through MKL), and both keep a per-thread thread count.
:func:`serial_torch_ops_in_this_thread` sets the calling thread's counts to one and restores them;
the value of ``torch.set_num_threads`` (global to the process) and every other thread are untouched,
so two threads may call the feature functions at once. Where a runtime is absent (torch built
without OpenMP or MKL) its setting is skipped: results are the same, only the speed may differ.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

import torch

Block = TypeVar("Block")
Result = TypeVar("Result")
Setter = Callable[[int], int]


@functools.cache
def _thread_count_setters() -> tuple[Setter, ...]:
    """Functions that set the calling thread's thread count of one runtime and return the previous.

    Found once per process (torch loaded its runtimes on import; the lookup scans the loaded
    libraries, a few milliseconds): every OpenMP runtime (``omp_set_num_threads`` is per thread),
    and MKL's per-thread setting where torch's library exports it.
    """
    from threadpoolctl import ThreadpoolController

    setters: list[Setter] = []
    for library in ThreadpoolController().select(user_api="openmp").lib_controllers:

        def set_openmp(count: int, library=library) -> int:
            before = library.get_num_threads()
            library.set_num_threads(count)
            return before

        setters.append(set_openmp)
    # MKL (linked into torch's CPU library) keeps its own per-thread count, which torch sets to its
    # thread count in every thread it runs in; 0 restores "not set".
    for name in ("libtorch_cpu.so", "libtorch_cpu.dylib", "torch_cpu.dll"):
        path = Path(torch.__file__).parent / "lib" / name
        if path.exists():
            mkl_local = getattr(ctypes.CDLL(str(path)), "MKL_Set_Num_Threads_Local", None)
            if mkl_local is not None:
                mkl_local.argtypes, mkl_local.restype = [ctypes.c_int], ctypes.c_int
                setters.append(mkl_local)
            break
    return tuple(setters)


def _limit_this_thread(count: int) -> list[int]:
    # torch sets a new thread's counts on the thread's first parallel op or thread query: query
    # first, so that torch does not overwrite the limit afterwards.
    torch.get_num_threads()
    return [setter(count) for setter in _thread_count_setters()]


@contextlib.contextmanager
def serial_torch_ops_in_this_thread() -> Iterator[None]:
    """Run the calling thread's torch ops on one thread inside the block; restore its counts after.

    Only the calling thread's OpenMP and MKL settings change (see the module notes); other threads
    and ``torch.get_num_threads()`` as seen from them are untouched.
    """
    before = _limit_this_thread(1)
    try:
        yield
    finally:
        for setter, count in zip(_thread_count_setters(), before, strict=True):
            setter(count)


def map_blocks(fn: Callable[[Block], Result], blocks: Sequence[Block], threads: int) -> list[Result]:
    """``[fn(b) for b in blocks]``, on up to ``threads`` worker threads whose torch ops run serially.

    With ``threads == 1`` or a single block, the blocks run in the caller's thread as it is (callers
    wrap the call in :func:`serial_torch_ops_in_this_thread`). Worker threads do not inherit the
    caller's grad mode: ``fn`` must set it if it matters. Results are in the order of ``blocks`` and
    do not depend on ``threads``.
    """
    if threads > 1 and len(blocks) > 1:
        # The worker threads end with the pool: their limit needs no restoring.
        with ThreadPoolExecutor(
            min(threads, len(blocks)), initializer=_limit_this_thread, initargs=(1,)
        ) as pool:
            return list(pool.map(fn, blocks))
    return [fn(block) for block in blocks]
