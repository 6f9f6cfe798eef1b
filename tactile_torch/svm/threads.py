"""Threads for the compiled kernels: how many, and a work loop the calling thread shares.

The compiled solver and decision kernels release the GIL, so Python threads run them on several
cores. On a machine whose cores are busy with other work, a second thread may wait for a core for a
scheduler time slice or more: :func:`run_blocks` therefore makes the calling thread take blocks from
the same queue as its workers, so that a waiting worker delays the call by at most the block it
holds, and a call is never much slower than on one thread. Nothing here changes torch's (or any
library's) process-wide thread count.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from typing import TypeVar

import torch

Block = TypeVar("Block")
Result = TypeVar("Result")


def resolve_threads(n_jobs: int | None) -> int:
    """Threads for ``n_jobs``: ``None`` -> ``torch.get_num_threads()`` (the library's thread budget,
    which the caller may set), ``-1`` -> every core, else ``n_jobs``."""
    if n_jobs is None:
        return max(1, torch.get_num_threads())
    if n_jobs == -1:
        return os.cpu_count() or 1
    return int(n_jobs)


def run_blocks(fn: Callable[[Block], Result], blocks: Sequence[Block], threads: int) -> list[Result]:
    """``[fn(b) for b in blocks]``, the blocks taken in order by the caller and ``threads - 1`` workers.

    The caller takes the first block (callers put the largest first) and returns as soon as every
    block is done: a worker that has not started yet finds the queue empty later and ends on its
    own, so only blocks already running elsewhere can make the caller wait. The first exception
    raised by ``fn`` is raised again here.
    """
    results: list = [None] * len(blocks)
    workers = min(threads, len(blocks)) - 1
    if workers <= 0:
        return [fn(block) for block in blocks]
    queue = iter(range(len(blocks)))
    state = threading.Condition()
    done: list[int] = []
    errors: list[BaseException] = []

    def run(k: int) -> None:
        try:
            results[k] = fn(blocks[k])
        except BaseException as err:  # re-raised in the caller
            errors.append(err)
        with state:
            done.append(k)
            state.notify_all()

    def work() -> None:
        while not errors:
            with state:
                k = next(queue, None)
            if k is None:
                return
            run(k)

    with state:
        first = next(queue)
    for _ in range(workers):
        threading.Thread(target=work, daemon=True).start()
    run(first)
    work()
    with state:
        state.wait_for(lambda: len(done) == len(blocks) or bool(errors))
    if errors:
        raise errors[0]
    return results


__all__ = ["resolve_threads", "run_blocks"]
