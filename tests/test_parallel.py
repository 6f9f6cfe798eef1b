"""Tests of tactile_torch._parallel: the threads that run blocks run their torch ops serially, and
nothing process-wide changes, also with two callers at once."""

from __future__ import annotations

import threading

import torch

from tactile_torch._parallel import _thread_count_setters, map_blocks, serial_torch_ops_in_this_thread
from tactile_torch.data.images import make_explorations
from tactile_torch.image import exploration_features
from tactile_torch.signal import window_features


def _this_thread_counts() -> list[int]:
    """The calling thread's OpenMP (and MKL) thread counts, read without changing them."""
    counts = [setter(1) for setter in _thread_count_setters()]
    for setter, count in zip(_thread_count_setters(), counts, strict=True):
        setter(count)
    return counts


def test_serial_threads_change_only_their_own_setting():
    assert _thread_count_setters(), "torch's OpenMP runtime was not found"
    before, caller = torch.get_num_threads(), _this_thread_counts()
    seen = map_blocks(lambda _: _this_thread_counts(), range(4), threads=2)
    assert all(counts == [1] * len(caller) for counts in seen)  # the worker threads
    with serial_torch_ops_in_this_thread():
        assert _this_thread_counts() == [1] * len(caller)
    assert _this_thread_counts() == caller and torch.get_num_threads() == before
    assert map_blocks(lambda b: b * b, [3, 1, 2], threads=2) == [9, 1, 4]  # in the order of the blocks


def test_two_concurrent_callers_get_the_serial_results_and_change_no_thread_count():
    frames = make_explorations(1, n_frames=12, frame_size=48, sensels=12, random_state=0).frames
    windows = torch.randn(300, 3, 400, generator=torch.Generator().manual_seed(0))
    want = (exploration_features(frames, frames_per_chunk=2), window_features(windows))
    before, caller = torch.get_num_threads(), _this_thread_counts()
    results, errors = {}, []

    def call(name, fn):
        try:
            results[name] = [fn() for _ in range(3)]
        except Exception as err:  # re-raised in the main thread below
            errors.append(err)

    callers = [
        threading.Thread(
            target=call, args=("image", lambda: exploration_features(frames, frames_per_chunk=2))
        ),
        threading.Thread(target=call, args=("signal", lambda: window_features(windows))),
    ]
    for thread in callers:
        thread.start()
    seen = set()
    while any(thread.is_alive() for thread in callers):
        seen.add((torch.get_num_threads(), tuple(_this_thread_counts())))
    for thread in callers:
        thread.join()
    assert not errors, errors
    assert seen <= {(before, tuple(caller))}  # the main thread's view never changed during the calls
    assert all(torch.equal(r, want[0]) for r in results["image"])
    assert all(torch.equal(r, want[1]) for r in results["signal"])
