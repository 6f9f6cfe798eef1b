"""How :func:`~tactile_torch.image.exploration_features` runs: blocks of frames, threads, export.

The work is cut into blocks of explorations x frames of about :data:`CHUNK_PIXELS` pixels (whole
explorations share a block when they fit; the OR is accumulated across a long exploration's blocks),
so memory stays bounded whatever ``B`` and ``T``. The hard eager path runs the blocks on worker
threads whose torch ops are serial (:mod:`tactile_torch._parallel`); the soft path (autograd) runs in
the caller's thread, and so do the transforms that record the ops (ONNX export, ``torch.compile``,
``jit.trace``, ``vmap``: :func:`~tactile_torch.validation.values_unavailable`), on one block (no Python
arithmetic on a symbolic batch size, no worker thread outside vmap's thread-local levels).
"""

from __future__ import annotations

import contextlib
import functools
import warnings

import torch

from .._parallel import map_blocks, serial_torch_ops_in_this_thread
from ..validation import values_unavailable
from . import _export
from ._constants import CHUNK_PIXELS, relative_erosion
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
    edge_threshold: float | torch.Tensor,
    temperature: float | torch.Tensor | None,
    frames_per_chunk: int | None,
) -> torch.Tensor:
    """:func:`~tactile_torch.image.exploration_features` on validated arguments."""
    batch, n_frames, _, height, width = frames.shape
    if torch.jit.is_tracing():
        # A jit trace holds the frame size as constants (the batch and frame count stay free): an
        # expand to that size (a view) makes frames of another size fail in the traced graph instead
        # of giving wrong numbers.
        frames = frames.expand(-1, -1, -1, int(height), int(width))
    dtype = frames.dtype if frames.is_floating_point() else torch.float32
    soft = temperature is not None
    recorded = values_unavailable()
    if recorded:  # one block: no Python arithmetic on the symbolic batch size
        blocks, per_row = [(slice(None), slice(None))], 1
    else:
        blocks, per_row = _blocks(batch, n_frames, height * width, frames_per_chunk)
    # The hard eager path runs on serial threads; soft mode (autograd) and the transforms in the
    # caller's thread as it is.
    if soft or recorded:
        threads, serial = 1, contextlib.nullcontext()
    else:
        threads, serial = torch.get_num_threads(), serial_torch_ops_in_this_thread()
    with serial:
        if isinstance(threshold, str):  # "otsu": one threshold per exploration, over all its frames
            hists = map_blocks(lambda b: _level_histogram(_gray(frames[b], dtype)), blocks, threads)
            threshold = _otsu_from_histogram(torch.cat([sum(row) for row in _rows(hists, per_row)]))
        cut = None
        # torch.compile cannot run the NumPy search (torch.export runs Python as it is): the float
        # gray path gives the same mask there.
        compiling = torch.compiler.is_compiling() and not torch.compiler.is_exporting()
        if not soft and not compiling and frames.dtype == torch.uint8 and isinstance(threshold, float | int):
            cut = integer_cut(float32(threshold))  # pure (NumPy): the same eagerly and while tracing
        threshold = torch.as_tensor(threshold, dtype=dtype)
        if threshold.ndim == 1:
            threshold = threshold.expand(batch)
        step = functools.partial(
            _block_step,
            frames=frames,
            threshold=threshold,
            erosion=int(erosion),
            edge_threshold=edge_threshold
            if isinstance(edge_threshold, torch.Tensor)
            else float(edge_threshold),
            temperature=temperature,
            dtype=dtype,
            fuse=fuse,
            cut=cut,
        )
        rows = _rows(map_blocks(step, blocks, threads), per_row)
        if not fuse:
            features = torch.cat([torch.cat(row, dim=1) for row in rows]).reshape(batch, -1)
        else:
            fused = torch.cat(
                [functools.reduce(functools.partial(_or_merge, soft=soft), row) for row in rows]
            )
            fused = _or_finish(fused[:, 1:-1, 1:-1], soft).to(dtype)
            if threads == 1:
                features = _image_features(fused, soft)
            else:
                features = torch.cat(map_blocks(_image_features, fused.split(-(-batch // threads)), threads))
        if not soft and not recorded and erosion > 1:
            _warn_if_eroded_away(features, frames, threshold, dtype, cut, int(erosion))
    return features


def largest_surviving_erosion(mask: torch.Tensor, limit: int) -> int:
    """The largest erosion ``k <= limit`` that leaves a pressed pixel in a {0, 1} ``mask`` (0: nothing
    pressed).

    Surviving an erosion by ``k`` means holding a ``k x k`` square of pressed pixels (the border
    counting as pressed), so survival is monotone in ``k``: a bisection.
    """
    if not bool(mask.any()):
        return 0
    low, high = 1, limit  # low survives, the answer is in [low, high]
    while low < high:
        middle = (low + high + 1) // 2
        if bool(_erode(mask, middle, None).any()):
            low = middle
        else:
            high = middle - 1
    return low


def _warn_if_eroded_away(
    features: torch.Tensor,
    frames: torch.Tensor,
    threshold: torch.Tensor,
    dtype: torch.dtype,
    cut: int | None,
    erosion: int,
) -> None:
    """Warn when the erosion removed every pressed pixel of at least half of the explorations that
    have one, so that their features are all 0 (a blank exploration's zeros are the documented
    result, and a few lost light touches are the study's own setting at work)."""
    zero = torch.nonzero(features.abs().amax(1) == 0).flatten().tolist()
    if not zero:
        return
    largest = [
        largest_surviving_erosion(
            pressed(
                frames[b : b + 1], threshold[b : b + 1] if threshold.ndim else threshold, dtype, None, cut
            ),
            erosion,
        )
        for b in zero
    ]
    lost = [k for k in largest if 0 < k < erosion]
    with_contact = features.shape[0] - len(zero) + sum(k > 0 for k in largest)
    if lost and 2 * len(lost) >= with_contact:
        _, _, _, height, width = frames.shape
        warnings.warn(
            f"erosion={erosion} removed every pressed region of {len(lost)} of the {with_contact} "
            f"exploration(s) with one ({height} x {width} frames), so their features are all 0: try "
            f"erosion <= {min(lost)}, the largest that keeps a contact in each (erosion is in pixels: the "
            f"study's 10 suits its 96 x 96 frames; relative_erosion({height}, {width}) = "
            f"{relative_erosion(height, width)} scales it to these)",
            UserWarning,
            stacklevel=5,  # the caller of exploration_features (under its quiet_jit_trace wrapper)
        )


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
    temperature: float | torch.Tensor | None,
    cut: int | None = None,
) -> torch.Tensor:
    """Pressed region of (B, t, 3, H, W) frames: int8 {0, 1} (hard) or ``dtype`` (soft).

    ``threshold``: shape () or (B,), ``dtype``. Hard on uint8 frames the gray level is never formed:
    eagerly :func:`~._integer_cut.pressed_uint8` gives the same mask from integers; while exporting,
    the threshold's integer ``cut`` (if it has one) does the same in the graph (and under the other
    transforms that record the ops).
    """
    if temperature is None and frames.dtype == torch.uint8:
        if not values_unavailable():
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
    edge_threshold: float | torch.Tensor,
    temperature: float | torch.Tensor | None,
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
    return _image_features(edges.to(dtype), temperature is not None)
