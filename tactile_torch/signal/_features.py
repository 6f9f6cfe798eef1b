"""Window features of accelerometer recordings: :func:`sliding_windows`, :func:`window_features` and its
module form (definitions in the package docstring, :mod:`tactile_torch.signal`)."""

from __future__ import annotations

import functools

import numpy as np
import torch
from torch import nn

from .._parallel import map_blocks, serial_torch_ops_in_this_thread
from ..exceptions import InputTypeError
from ..validation import check_finite, check_positive, check_shape, check_tensor

AXES = ("x", "y", "z")
AXIS_FEATURES = ("var", "skew", "kurt", "m5", "tv", "cross", "hf")
FEATURE_NAMES = tuple(f"{axis}_{name}" for axis in AXES for name in AXIS_FEATURES)
N_THRESHOLDS = 20
# The study's unsupervised path keeps these per-axis features: sqrt(var), log tv, log cross, log hf.
CLUSTERING_FEATURE_NAMES = tuple(
    f"{axis}_{name}" for axis in AXES for name in ("sqrt_var", "log_tv", "log_cross", "log_hf")
)

# Eager mode processes the windows in blocks of about this many samples, so that the dozen
# intermediate arrays of a block stay in the CPU cache instead of streaming the whole batch through
# memory a dozen times (3-4x faster at W = 800 on one thread); the result does not depend on it.
_BLOCK_SAMPLES = 1 << 16
# Thresholds are found by a floor() estimate corrected by one comparison each way. The estimate is
# off by less than one threshold index unless the window's range is tiny relative to its magnitude
# (rounding of the thresholds then matters); such windows fall back to an exact bisection.
_ESTIMATE_SAFE_RANGE = 512


def _check_windows(windows: object) -> torch.Tensor:
    check_tensor(windows, "windows")
    check_shape(windows, "windows", ["*", 3, "W"])
    if windows.dtype not in (torch.float32, torch.float64):
        raise InputTypeError(f"windows must have dtype float32 or float64, got {windows.dtype}")
    if windows.shape[-1] < 2:
        raise ValueError(
            f"windows must have at least 2 samples per axis (W >= 2), got shape {tuple(windows.shape)}"
        )
    return windows


def sliding_windows(recording: torch.Tensor, size: int, step: int | None = None) -> torch.Tensor:
    """Return the windows of ``size`` samples, every ``step`` samples, of triaxial recordings.

    Parameters
    ----------
    recording : Tensor, shape ``(n, 3)`` or ``(B, n, 3)``
        One recording or a batch of equally long recordings (samples along ``n``, axes x, y, z last).
    size : int
        Window length ``W >= 2`` in samples.
    step : int, optional
        Hop between window starts (``>= 1``); default ``size`` (non-overlapping windows).

    Returns
    -------
    Tensor, shape ``(N, 3, W)`` or ``(B, N, 3, W)``
        ``N = (n - size) // step + 1`` windows, in time order; window ``i`` holds samples
        ``i * step ... i * step + size - 1``. Trailing samples that do not fill a window are dropped.
        The result is a view of ``recording`` (no copy; overlapping windows share memory), with the
        recording's dtype and device.

    Raises
    ------
    TypeError
        If ``recording`` is not a tensor, or ``size``/``step`` are not integers.
    ValueError
        If ``recording`` is not ``(n, 3)``/``(B, n, 3)``, ``size < 2``, ``step < 1`` or ``n < size``.

    Examples
    --------
    >>> sliding_windows(torch.zeros(1000, 3), 200, 100).shape
    torch.Size([9, 3, 200])
    """
    check_tensor(recording, "recording")
    if recording.ndim not in (2, 3) or recording.shape[-1] != 3:
        raise ValueError(f"recording must have shape (n, 3) or (B, n, 3), got {tuple(recording.shape)}")
    check_positive(size, "size", integer=True)
    step = size if step is None else step
    check_positive(step, "step", integer=True)
    if size < 2:
        raise ValueError(f"size must be >= 2 samples, got {size}")
    n = recording.shape[-2]
    if n < size:
        raise ValueError(
            f"recording must have at least size={size} samples, got {n} (shape {tuple(recording.shape)})"
        )
    # unfold along the sample axis appends the window axis last: (..., N, 3, size), a strided view.
    return recording.unfold(-2, int(size), int(step))


def window_features(windows: torch.Tensor) -> torch.Tensor:
    """Return the 21 vibration features of every window, 7 per axis in axis-major order.

    Parameters
    ----------
    windows : Tensor, shape ``(B, 3, W)`` (or ``(..., 3, W)``)
        float32 or float64 windows, axes x, y, z, ``W >= 2`` finite samples each (any unit; the
        library's data are in g). Leading dimensions are passed through.

    Returns
    -------
    Tensor, shape ``(B, 21)`` (or ``(..., 21)``)
        ``[x_var, x_skew, x_kurt, x_m5, x_tv, x_cross, x_hf, y_var, ..., z_hf]`` (see
        :data:`FEATURE_NAMES` and the module docstring for the exact definitions and conventions),
        in the windows' dtype. ``cross`` holds integer counts.

    Raises
    ------
    TypeError
        If ``windows`` is not a float32/float64 tensor.
    ValueError
        If ``windows`` is not ``(..., 3, W)``, has ``W < 2``, or holds NaN or inf.

    Notes
    -----
    Differentiable (float64 gradcheck) in every feature but ``cross``, whose gradient is zero. In
    eager mode the spectrum uses ``torch.fft.rfft`` and the crossings a floor-and-correct
    formulation (``O(W)``, not ``O(20 W)``); when traced for export (``torch.export``, ONNX) the
    spectrum becomes a MatMul with a precomputed cos/sin basis of the upper-half bins only and the
    crossings an elementwise bisection, both exportable and equal to the eager results (tested).

    The eager path works on blocks of windows small enough to stay in the CPU cache and runs them
    on ``torch.get_num_threads()`` threads, each running its torch ops on one thread (a setting of
    that thread only: ``torch.set_num_threads``, global to the process, is never called); results do
    not depend on the thread count. Memory: a few MiB beyond the output, whatever the batch.

    Examples
    --------
    >>> window_features(torch.randn(4, 3, 800)).shape
    torch.Size([4, 21])
    """
    if torch.compiler.is_exporting():  # traced: one graph, no validation (it cannot raise)
        width = windows.shape[-1]
        stats = _row_statistics(windows.reshape(-1, width), exact=True)
        features = _features_from_statistics(stats, width).to(windows.dtype)
        return features.reshape(*windows.shape[:-2], len(FEATURE_NAMES))
    _check_windows(windows)
    lead, width = windows.shape[:-2], windows.shape[-1]
    rows = windows.reshape(-1, width)  # (B * 3, W): every feature is a function of one row
    size = max(3, _BLOCK_SAMPLES // width)
    blocks = [rows[i : i + size] for i in range(0, len(rows), size)]  # blocks of windows, not windows
    statistics = functools.partial(_row_statistics, exact=False, grad=torch.is_grad_enabled())
    threads = torch.get_num_threads()
    with serial_torch_ops_in_this_thread():
        if blocks:
            stats = torch.cat(map_blocks(statistics, blocks, threads))
        else:  # no window
            stats = rows.new_zeros((0, 9), dtype=torch.float64)
        # A window holds NaN or inf iff its range does (min and max propagate them): the check is free.
        if not bool(torch.isfinite(stats[:, 0]).all()):
            check_finite(windows, "windows")  # raises, saying where
        features = _features_from_statistics(stats, width)
    return features.to(windows.dtype).reshape(*lead, len(FEATURE_NAMES))


def _row_statistics(a: torch.Tensor, *, exact: bool, grad: bool = True) -> torch.Tensor:
    """The sums every feature is made of, for rows ``(R, W)`` → float64 ``(R, 9)``; inputs validated.

    Columns: range, offset, sums of the powers 2..5 of the scaled deviations, total variation,
    crossings and upper-half amplitude sum (see :func:`_features_from_statistics`). ``grad`` is the
    caller's grad mode, which worker threads do not inherit.

    The moments use the deviations ``d = (a - mean(a)) / range`` in float64 whatever the input dtype:
    dividing by the range keeps ``d**5`` from overflowing and makes the standardised moments
    offset- and scale-free, and float64 because the fifth moment of a heavy-tailed window is a small
    difference of large terms (float32 deviations alone cost up to 4e-5 of it). Total variation,
    crossings and spectrum stay in the input dtype (their float32 error is ~1e-7).
    """
    if grad != torch.is_grad_enabled():
        with torch.set_grad_enabled(grad):
            return _row_statistics(a, exact=exact, grad=grad)
    lo, hi = a.amin(-1, keepdim=True), a.amax(-1, keepdim=True)  # 10x faster than aminmax on CPU
    spread = hi - lo
    wide = a.to(torch.float64)
    range64 = spread.to(torch.float64)
    d = (wide - wide.mean(-1, keepdim=True)) / torch.where(range64 == 0, torch.ones_like(range64), range64)
    # The rounded mean leaves mean(d) = offset, about 1e-16 * |mean(a)| / range; instead of a second
    # centring pass, the moments are corrected for it exactly (binomial expansion).
    offset = d.mean(-1)
    d2 = d * d
    d3 = d2 * d
    raw = [torch.linalg.vecdot(d, d), torch.linalg.vecdot(d2, d), torch.linalg.vecdot(d2, d2)]
    raw.append(torch.linalg.vecdot(d3, d2))
    tv = (a[:, 1:] - a[:, :-1]).abs().sum(-1)
    with torch.no_grad():  # piecewise constant: zero gradient
        cross = _crossings(a.detach(), lo.detach(), spread.detach(), exact=exact)
    # Minus the first sample: the DC bin is not summed, and the FFT's rounding scales with the signal's
    # magnitude, which a 1 g gravity offset would otherwise dominate.
    hf = _upper_half_amplitude_sum(a - a[:, :1], basis=exact)
    others = torch.stack([tv, cross, hf], dim=-1).to(torch.float64)
    return torch.cat([torch.stack([range64[:, 0], offset, *raw], dim=-1), others], dim=-1)


def _features_from_statistics(stats: torch.Tensor, width: int) -> torch.Tensor:
    """``(R, 9)`` statistics of :func:`_row_statistics` → ``(R, 7)`` features."""
    spread, o1, s2, s3, s4, s5, tv, cross, hf = stats.unbind(-1)
    raw2, raw3, raw4, raw5 = s2 / width, s3 / width, s4 / width, s5 / width
    o2 = o1 * o1
    m2 = raw2 - o2
    m3 = raw3 - 3 * o1 * raw2 + 2 * o1 * o2
    m4 = raw4 - 4 * o1 * raw3 + 6 * o2 * raw2 - 3 * o2 * o2
    m5 = raw5 - 5 * o1 * raw4 + 10 * o2 * raw3 - 10 * o1 * o2 * raw2 + 4 * o2 * o2 * o1
    flat = spread == 0
    m2_safe = torch.where(flat, torch.ones_like(m2), m2)  # keeps 0/0 (and its gradient) out
    zero = torch.zeros_like(m2)
    var = torch.where(flat, zero, m2 * spread**2 * (width / (width - 1)))
    skew = torch.where(flat, zero, m3 / m2_safe**1.5)
    kurt = torch.where(flat, zero, m4 / m2_safe**2)
    fifth = torch.where(flat, zero, m5 / m2_safe**2.5)
    return torch.stack([var, skew, kurt, fifth, tv, cross, hf], dim=-1)


def _threshold(lo: torch.Tensor, spread: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
    # The one formula of the thresholds; every comparison goes through it, in the input dtype.
    return lo + k * spread / (N_THRESHOLDS + 1)


def _crossings(a: torch.Tensor, lo: torch.Tensor, spread: torch.Tensor, *, exact: bool) -> torch.Tensor:
    """Threshold crossings of rows ``(R, W)`` given their ``(R, 1)`` minimum and range → ``(R,)``.

    Uses the level of every sample, ``c(v) = #{k : th_k < v}``: the thresholds crossed between two
    consecutive samples are exactly those below one sample and not below the other, so the count is
    ``sum_t |c(a[t+1]) - c(a[t])|``: O(W) work and memory instead of O(20 W).
    """
    level = _level_bisect(a, lo, spread) if exact else _level_estimate(a, lo, spread)
    return (level[:, 1:] - level[:, :-1]).abs_().sum(-1)


def _level_bisect(a: torch.Tensor, lo: torch.Tensor, spread: torch.Tensor) -> torch.Tensor:
    """``#{k in 1..20 : th_k < a}`` by a 5-step bisection over k; exact for any window.

    Exact because the computed thresholds are non-decreasing in k (every rounded operation of
    :func:`_threshold` is monotone). Elementwise only, hence exportable.
    """
    level = torch.zeros_like(a)
    for step in (16, 8, 4, 2, 1):  # the binary digits of the answer (0..20 < 32), not thresholds
        candidate = level + step
        below = (candidate <= N_THRESHOLDS) & (_threshold(lo, spread, candidate) < a)
        level = torch.where(below, candidate, level)
    return level


def _level_estimate(a: torch.Tensor, lo: torch.Tensor, spread: torch.Tensor) -> torch.Tensor:
    """``#{k in 1..20 : th_k < a}`` from a rounded position and one exact comparison.

    With ``p = (a - min) * 21 / range`` the position of ``a`` in threshold units, the exact level is
    ``ceil(p) - 1`` up to the rounding of the thresholds, which moves each by ``delta`` threshold
    units. With ``u = floor(p + 1/2)`` (clamped to 1..20), the level is ``u`` or ``u - 1`` whenever
    ``delta`` plus the rounding of ``p`` stays below 1/2, and comparing ``a`` with the actual
    threshold ``th_u`` decides which. ``delta <= 5 eps/2 * 21 * max|a| / range``, so this holds
    when ``range > 512 eps max|a|`` (``delta < 0.11``); rows below that bound (not constant ones,
    whose level is 0 either way) are recomputed exactly by :func:`_level_bisect`.
    """
    flat = spread == 0
    scale = (N_THRESHOLDS + 1) / torch.where(flat, torch.ones_like(spread), spread)
    upper = ((a - lo) * scale).add_(0.5).floor_().clamp_(1, N_THRESHOLDS)
    level = upper - (_threshold(lo, spread, upper) >= a).to(a.dtype)
    magnitude = torch.maximum(lo.abs(), (lo + spread).abs())
    risky = (~flat & (spread <= _ESTIMATE_SAFE_RANGE * torch.finfo(a.dtype).eps * magnitude))[:, 0]
    if bool(risky.any()):
        level[risky] = _level_bisect(a[risky], lo[risky], spread[risky])
    return level


@functools.lru_cache(maxsize=16)
def _upper_half_basis_array(width: int) -> np.ndarray:
    k = np.arange(width // 4 + 1, width // 2 + 1)
    t = np.arange(width)
    # Reduce k * t modulo W in integers first, so the angles are exact to float64 rounding for any W.
    angle = (2 * np.pi / width) * (np.outer(t, k) % width)
    return np.concatenate([np.cos(angle), np.sin(angle)], axis=1)


def _upper_half_basis(width: int, dtype: torch.dtype) -> torch.Tensor:
    """``(W, 2K)`` cos and sin of the K upper-half DFT bins (``W // 4 < k <= W // 2``), float64-accurate.

    Only the NumPy array is cached: a tensor made while tracing for export belongs to that trace, and
    handing it to a second export in the same process breaks the second graph.
    """
    return torch.from_numpy(_upper_half_basis_array(width)).to(dtype)


def _upper_half_amplitude_sum(d: torch.Tensor, *, basis: bool) -> torch.Tensor:
    """``sum_{W//4 < k <= W//2} |rfft(d)[k]|`` of rows ``(R, W)`` → ``(R,)``.

    ``basis=True`` computes the needed bins only, as one MatMul with a cos/sin basis (exportable,
    no DFT operator); otherwise ``torch.fft.rfft`` (faster in eager mode for large W).
    """
    width = d.shape[-1]
    if not basis:
        return torch.fft.rfft(d, dim=-1)[:, width // 4 + 1 :].abs().sum(-1)
    proj = d @ _upper_half_basis(width, d.dtype)
    n_bins = proj.shape[-1] // 2
    return torch.sqrt(proj[:, :n_bins] ** 2 + proj[:, n_bins:] ** 2).sum(-1)


class WindowFeatures(nn.Module):
    """Module form of :func:`window_features`: ``(B, 3, W)`` → ``(B, 21)``.

    Parameters
    ----------
    window_size : int, optional
        If given, inputs must have exactly this ``W`` (checked in eager mode); recorded for exports.

    Examples
    --------
    >>> WindowFeatures(800)(torch.randn(2, 3, 800)).shape
    torch.Size([2, 21])
    """

    def __init__(self, window_size: int | None = None) -> None:
        super().__init__()
        if window_size is not None:
            check_positive(window_size, "window_size", integer=True)
        self.window_size = window_size

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        if self.window_size is not None and not torch.compiler.is_exporting():
            check_shape(check_tensor(windows, "windows"), "windows", ["*", 3, self.window_size])
        return window_features(windows)

    def extra_repr(self) -> str:
        return f"window_size={self.window_size}"
