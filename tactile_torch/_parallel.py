"""Block parallelism for the eager feature paths: Python threads over blocks, torch ops single-threaded.

Used by :mod:`tactile_torch.signal` and :mod:`tactile_torch.image`. A block's dozens of short passes
cost less than one synchronisation of torch's intra-op pool (on a loaded 2-core machine a parallel
elementwise op on a small tensor stalls for milliseconds), so the callers cut their input into blocks
that fit the CPU cache and run whole blocks on separate Python threads instead (torch releases the
GIL inside its ops).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import torch

Block = TypeVar("Block")
Result = TypeVar("Result")


@contextlib.contextmanager
def serial_torch_ops() -> Iterator[int]:
    """Run torch ops on one intra-op thread inside the block; yield the thread count it had before.

    The setting (``torch.set_num_threads``) is global to the process and is restored on exit, also
    when the block raises.
    """
    threads = torch.get_num_threads()
    if threads > 1:
        torch.set_num_threads(1)
    try:
        yield threads
    finally:
        if threads > 1:
            torch.set_num_threads(threads)


def map_blocks(fn: Callable[[Block], Result], blocks: Sequence[Block], threads: int) -> list[Result]:
    """``[fn(b) for b in blocks]``, on up to ``threads`` Python threads when there are several blocks.

    Worker threads do not inherit the caller's grad mode: ``fn`` must set it if it matters.
    """
    if threads > 1 and len(blocks) > 1:
        with ThreadPoolExecutor(min(threads, len(blocks))) as pool:
            return list(pool.map(fn, blocks))
    return [fn(block) for block in blocks]
