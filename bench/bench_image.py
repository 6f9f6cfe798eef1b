"""Method-1 features (tactile_torch.image.exploration_features) against the per-frame SciPy pipeline.

Explorations of 100 frames (96 x 96 and 192 x 192, uint8 RGB from the synthetic generator); ours on a
batch, the reference (``tests/reference_image.py``: a loop over explorations and frames with
``scipy.ndimage``, in float64 as a researcher would write it) on fewer explorations; both reported per
exploration, at one thread and at the default thread count, in the same run. Also the peak memory that
one call adds for a batch of 32 explorations of 100 x 192 x 192.
"""

from __future__ import annotations

import ctypes
import gc

import numpy as np
import torch

from bench.common import DEFAULT_THREADS, peak_memory_mib, threads, time_call, time_threads_alternately
from tactile_torch.data.images import make_explorations
from tactile_torch.image import exploration_features
from tests import reference_image as reference

TITLE = "Tactile-image features (method 1): torch vs per-frame SciPy"


def _release_freed_memory() -> None:
    """Return the heap memory freed so far to the OS, so that the resident size before the measured call
    is what is live (otherwise the call reuses freed, still resident pages and the peak reads low)."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def run(quick: bool) -> dict:
    n_frames = 20 if quick else 100
    n_ours, n_ref = (2, 1) if quick else (8, 2)
    rows = []
    for size in (96, 192):
        data = make_explorations(2, n_frames=n_frames, frame_size=size, random_state=0).frames
        frames = data[torch.arange(n_ours) % len(data)].contiguous()
        ref_frames = frames[:n_ref].numpy()
        ours = exploration_features(frames[:n_ref]).double().numpy()
        want = reference.exploration_features(ref_frames)
        scale = np.maximum(np.abs(want), 1.0)
        max_diff = float(np.max(np.abs(ours - want) / scale))
        # Ours at one thread and at the default count take turns (the fastest of each is kept: the
        # machine is shared, and contention only ever adds time), so their ratio carries.
        t_ours = time_threads_alternately(lambda f=frames: exploration_features(f), repeat=7, warmup=1)
        for n_threads in sorted(t_ours):
            with threads(n_threads):
                t_ref = time_call(
                    lambda f=ref_frames: reference.exploration_features(f), repeat=1 if quick else 3, warmup=0
                )
            ours_ms = 1e3 * t_ours[n_threads] / n_ours
            ref_ms = 1e3 * t_ref["min_s"] / n_ref
            rows.append(
                {
                    "op": "exploration_features (fused)",
                    "frames": f"{n_frames} x {size} x {size}",
                    "threads": n_threads,
                    "ours ms/exploration": round(ours_ms, 2),
                    "scipy ms/exploration": round(ref_ms, 2),
                    "speed-up": round(ref_ms / ours_ms, 1),
                    "ours 1 thread / this": round(t_ours[1] / t_ours[n_threads], 2),
                    "max rel. diff": f"{max_diff:.1e}",
                }
            )
    batch, size = (4, 96) if quick else (32, 192)
    one = make_explorations(1, n_frames=n_frames, frame_size=size, random_state=1).frames
    big = one.repeat(batch // len(one), 1, 1, 1, 1)
    input_mib = big.numel() / 2**20
    _release_freed_memory()
    with threads(None):
        peak = peak_memory_mib(lambda: exploration_features(big))
    rows.append(
        {
            "op": "peak memory added by one call",
            "frames": f"{batch} x {n_frames} x {size} x {size} (uint8 input {input_mib:.0f} MiB)",
            "threads": DEFAULT_THREADS,
            "ours MiB": round(peak, 1),
        }
    )
    notes = [
        "Times are the fastest of 7 (ours, one thread and the default count taking turns; 'ours 1 thread / this' > 1: the default is faster) and 3 (scipy) repeats, per exploration. ours: one call on a batch; scipy: tests/reference_image.py, a Python loop over explorations and "
        "frames (scipy.ndimage.binary_erosion with a 10 x 10 square, scipy.ndimage.sobel, float64), "
        "timed on fewer explorations; both per exploration.",
        "max rel. diff: largest |ours - scipy| / max(|scipy|, 1) over the 12 features of the timed "
        "explorations (ours in float32 from uint8, scipy in float64).",
        "Ours works on blocks of explorations x frames (tactile_torch.image.CHUNK_PIXELS pixels) and "
        "accumulates the OR, so the memory does not grow with the number of frames; at the default "
        "thread count the blocks run on that many Python threads, each running its torch ops on one "
        "thread (a per-thread setting, tactile_torch._parallel). The uint8 input itself is not "
        "counted in the peak (it exists before the call).",
    ]
    return {"rows": rows, "notes": notes}
