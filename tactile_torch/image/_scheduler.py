"""How :func:`~tactile_torch.image.exploration_features` runs: blocks of frames, threads, export.

The work is cut into blocks of explorations x frames of about :data:`CHUNK_PIXELS` pixels (whole
explorations share a block when they fit; the OR is accumulated across a long exploration's blocks),
so memory stays bounded whatever ``B`` and ``T``. The hard eager path runs the blocks on worker
threads whose torch ops are serial (:mod:`tactile_torch._parallel`); the soft path (autograd) and
the export trace run in the caller's thread, the trace on one block (no Python arithmetic on the
symbolic batch size).
"""

from __future__ import annotations

import contextlib
import functools

import torch

from .._parallel import map_blocks, serial_torch_ops_in_this_thread
from . import _export
from ._constants import CHUNK_PIXELS
from ._integer_cut import GRAY_INTEGER, float32, integer_cut, pressed_uint8
from ._kernels import (
    _edges,
    _erode,
    _gray,
    _image_features,
    _level_histogram,
    _or_accumulate,
    _or_finish,
    _or_merge,
    _otsu_from_histogram,
    _pressure,
    _threshold_tensor,
)
from ._validation import Threshold


def run_exploration_features(
    frames: torch.Tensor,
    *,
    fuse: bool,
    threshold: Threshold,
    erosion: int,
    edge_threshold: float,
    temperature: float | None,
    frames_per_chunk: int | None,
) -> torch.Tensor:
    """:func:`~tactile_torch.image.exploration_features` on validated arguments."""
    batch, n_frames, _, height, width = frames.shape
    dtype = frames.dtype if frames.is_floating_point() else torch.float32
    soft = temperature is not None
    if torch.compiler.is_exporting():  # one block: no Python arithmetic on the symbolic batch size
        blocks, per_row = [(slice(None), slice(None))], 1
    else:
        blocks, per_row = _blocks(batch, n_frames, height * width, frames_per_chunk)
    # The hard eager path runs on serial threads; soft mode (autograd) and the trace in the caller's
    # thread as it is.
    if soft or torch.compiler.is_exporting():
        threads, serial = 1, contextlib.nullcontext()
    else:
        threads, serial = torch.get_num_threads(), serial_torch_ops_in_this_thread()
    with serial:
        if isinstance(threshold, str):  # "otsu": one threshold per exploration, over all its frames
            hists = map_blocks(lambda b: _level_histogram(_gray(frames[b], dtype)), blocks, threads)
            threshold = _otsu_from_histogram(torch.cat([sum(row) for row in _rows(hists, per_row)]))
        cut = None
        if not soft and frames.dtype == torch.uint8 and isinstance(threshold, float | int):
            cut = integer_cut(float32(threshold))  # pure (NumPy): the same eagerly and while tracing
        threshold = torch.as_tensor(threshold, dtype=dtype)
        if threshold.ndim == 1:
            threshold = threshold.expand(batch)
        step = functools.partial(
            _block_step,
            frames=frames,
            threshold=threshold,
            erosion=int(erosion),
            edge_threshold=float(edge_threshold),
            temperature=temperature,
            dtype=dtype,
            fuse=fuse,
            cut=cut,
        )
        rows = _rows(map_blocks(step, blocks, threads), per_row)
        if not fuse:
            return torch.cat([torch.cat(row, dim=1) for row in rows]).reshape(batch, -1)
        fused = torch.cat([functools.reduce(functools.partial(_or_merge, soft=soft), row) for row in rows])
        fused = _or_finish(fused[:, 1:-1, 1:-1], soft).to(dtype)
        if threads == 1:
            return _image_features(fused)
        return torch.cat(map_blocks(_image_features, fused.split(-(-batch // threads)), threads))


def _blocks(
    batch: int, n_frames: int, frame_pixels: int, frames_per_chunk: int | None
) -> tuple[list[tuple[slice, slice]], int]:
    """Blocks ``(explorations, frames)`` of about :data:`CHUNK_PIXELS` pixels, exploration-major, and
    the number of blocks per row of explorations (whole explorations share a block when they fit)."""
    n_t = min(n_frames, frames_per_chunk or max(1, CHUNK_PIXELS // frame_pixels))
    n_b = max(1, CHUNK_PIXELS // (n_frames * frame_pixels)) if n_t == n_frames else 1
    times = [slice(s, s + n_t) for s in range(0, n_frames, n_t)]
    return [(slice(b, b + n_b), t) for b in range(0, batch, n_b) for t in times], len(times)


def _rows(results: list, per_row: int) -> list[list]:
    return [results[i : i + per_row] for i in range(0, len(results), per_row)]


def pressed(
    frames: torch.Tensor,
    threshold: torch.Tensor,
    dtype: torch.dtype,
    temperature: float | None,
    cut: int | None = None,
) -> torch.Tensor:
    """Pressed region of (B, t, 3, H, W) frames: int8 {0, 1} (hard) or ``dtype`` (soft).

    ``threshold``: shape () or (B,), ``dtype``. Hard on uint8 frames the gray level is never formed:
    eagerly :func:`~._integer_cut.pressed_uint8` gives the same mask from integers; while exporting,
    the threshold's integer ``cut`` (if it has one) does the same in the graph.
    """
    if temperature is None and frames.dtype == torch.uint8:
        if not torch.compiler.is_exporting():
            return pressed_uint8(frames, threshold)
        if cut is not None:
            return _export.pressed_below_cut(frames, cut, GRAY_INTEGER)
    gray = _gray(frames, dtype)
    return _pressure(gray, _threshold_tensor(threshold, gray), temperature)


def _block_step(
    block: tuple[slice, slice],
    *,
    frames: torch.Tensor,
    threshold: torch.Tensor,
    erosion: int,
    edge_threshold: float,
    temperature: float | None,
    dtype: torch.dtype,
    fuse: bool,
    cut: int | None,
) -> torch.Tensor:
    """One block: the partial OR (b, H + 2, W + 2) of its frames (the image inside a junk ring, see
    :func:`~._kernels._unflat`) if ``fuse``, else the features (b, t, 12) of each frame."""
    explorations, _ = block
    mask = pressed(
        frames[block], threshold[explorations] if threshold.ndim else threshold, dtype, temperature, cut
    )
    edges = _edges(_erode(mask, erosion, temperature), edge_threshold, temperature, ring=fuse)
    if fuse:
        return _or_accumulate(None, edges, temperature is not None)
    return _image_features(edges.to(dtype))
