"""Vibration features of accelerometer windows (method 2 of DESIGN.md), as batched torch ops.

A triaxial recording ``(n, 3)`` is cut into windows ``(B, 3, W)`` by :func:`sliding_windows`;
:func:`window_features` summarises every window by 21 numbers, 7 per axis in axis-major order
(:data:`FEATURE_NAMES`)::

    [x_var, x_skew, x_kurt, x_m5, x_tv, x_cross, x_hf, y_var, ..., z_hf]

:class:`FeatureScaler` scales them to unit standard deviation (the supervised path, an RBF SVM
follows); :class:`ClusteringTransform` is the unsupervised path's transform (``sqrt`` / ``log`` of
the scale features, standardisation, PCA to 3 components; a Pitman-Yor mixture follows). Both are
small ``nn.Module`` s whose fitted values are buffers, so that the whole inference path (raw window →
features → scaler or transform) exports to one ONNX graph.

Definitions (every choice a reference could disagree on)
--------------------------------------------------------
For one axis ``a`` of a window, ``a[0], ..., a[W-1]``, ``W >= 2``, with biased central moments
``m_p = mean((a - mean(a))**p)``:

``var``
    ``m_2 * W / (W - 1)``: the unbiased variance (``ddof=1``, ``numpy.var(a, ddof=1)``).
``skew``
    ``m_3 / m_2**1.5``: the biased (population) skewness, ``scipy.stats.skew(a)``.
``kurt``
    ``m_4 / m_2**2``: the biased Pearson kurtosis (3 for a normal),
    ``scipy.stats.kurtosis(a, fisher=False)``.
``m5``
    ``m_5 / m_2**2.5``: the fifth standardised moment with biased central moments,
    ``scipy.stats.moment(a, 5) / numpy.var(a)**2.5``.
``tv``
    ``sum(|a[t+1] - a[t]|)``: the total variation, in the units of ``a``.
``cross``
    The number of crossings of the 20 thresholds ``th_k = min + (k * (max - min)) / 21``,
    ``k = 1, ..., 20``, evenly spaced strictly between the window's minimum and maximum and computed
    in the window's dtype with exactly that order of operations. A sample is *above* a threshold when
    ``a[t] > th_k``; a sample equal to the threshold counts as not above it. A crossing is a change
    of that state between consecutive samples, so a signal that touches a threshold and turns back
    does not cross it, and ``0, th, 1`` crosses it once. The count is summed over the 20 thresholds:
    ``sum_k sum_t [a[t] > th_k] != [a[t+1] > th_k]``. It equals the explicit loop over thresholds
    bit for bit, ties included (tested on quantised signals and on signals lying on the thresholds).
``hf``
    ``sum_k |rfft(a)[k]|`` over the bins whose frequency lies strictly above a quarter of the sample
    rate, ``W // 4 < k <= W // 2`` (``k > W / 4``), with the unnormalised DFT of ``numpy.fft.rfft``.
    The DC bin is never included; the Nyquist bin (even ``W``) is. For ``W = 800`` these are the
    200 bins ``201 .. 400``; for odd ``W = 201``, the 50 bins ``51 .. 100``. ``hf`` grows with ``W``
    (about as ``W**1.5`` for broadband noise).

Degenerate and extreme windows
------------------------------
- A constant window (a stylus at rest) has ``var = tv = cross = hf = 0``, and its standardised
  moments, undefined (``0 / 0``), are **defined as 0** (``skew = kurt = m5 = 0``); scipy returns NaN.
- The moments are computed in float64 from the deviations divided by the window's range, whatever
  the input dtype, and the spectrum from the window minus its first sample: the features are finite
  and accurate for any scale and offset (a 1 g gravity offset costs no float32 accuracy, values of
  1e30 do not overflow ``m_5``), as long as the variance itself fits in the dtype.
- A spike or clipped (saturated) samples need no special case: every feature stays finite.
- NaN or inf samples raise ``ValueError`` (in eager mode; an exported ONNX graph cannot raise, its
  outputs are then non-finite, so check the input before running it).

Examples
--------
>>> rec = torch.randn(8000, 3)                  # 10 s of a triaxial recording at 800 Hz
>>> window_features(sliding_windows(rec, 800, 400)).shape
torch.Size([19, 21])
"""

from __future__ import annotations

import functools

import numpy as np
import torch
from torch import nn

from ._checks import check_finite, check_floating, check_positive, check_shape, check_tensor
from ._parallel import map_blocks, serial_torch_ops_in_this_thread

AXES = ("x", "y", "z")
AXIS_FEATURES = ("var", "skew", "kurt", "m5", "tv", "cross", "hf")
FEATURE_NAMES = tuple(f"{axis}_{name}" for axis in AXES for name in AXIS_FEATURES)
N_THRESHOLDS = 20
# The unsupervised path keeps these per-axis features (DESIGN.md): sqrt(var), log tv, log cross, log hf.
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
        raise TypeError(f"windows must have dtype float32 or float64, got {windows.dtype}")
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


def _not_fitted(module: nn.Module) -> Exception:
    from sklearn.exceptions import NotFittedError

    return NotFittedError(f"this {type(module).__name__} is not fitted yet: call fit(features) first")


def _check_features(
    features: object, name: str, n_features: int | None, *, min_rows: int = 0
) -> torch.Tensor:
    check_tensor(features, name)
    check_shape(features, name, ["B", "F" if n_features is None else n_features])
    check_floating(features, name)
    check_finite(features, name)
    if features.shape[0] < min_rows:
        raise ValueError(
            f"{name} must have at least {min_rows} rows to fit, got shape {tuple(features.shape)}"
        )
    return features


class _FittedBuffers(nn.Module):
    """Base of the fitted modules: buffers start as ``None`` and are created by ``fit`` or by loading."""

    _fitted_buffers: tuple[str, ...] = ()

    def __init__(self) -> None:
        super().__init__()
        for name in self._fitted_buffers:
            self.register_buffer(name, None)

    @property
    def fitted(self) -> bool:
        """Whether ``fit`` was called (or a fitted state dict was loaded)."""
        return all(getattr(self, name) is not None for name in self._fitted_buffers)

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs):
        # Let an unfitted module load a fitted state dict: create the buffers it will fill.
        for name in self._fitted_buffers:
            if getattr(self, name) is None and prefix + name in state_dict:
                setattr(self, name, torch.empty_like(state_dict[prefix + name]))
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)

    def fit_transform(self, features: torch.Tensor) -> torch.Tensor:
        """``fit(features)`` then return ``self(features)``."""
        return self.fit(features)(features)


class FeatureScaler(_FittedBuffers):
    """Scales each feature to unit standard deviation, with the scale fitted on training features.

    ``forward(x) = (x - mean_) / scale_``; ``scale_`` is the per-feature standard deviation of the
    training features (``ddof=1``), ``mean_`` their mean if ``center=True`` else 0 (DESIGN.md scales
    without centring; an RBF kernel does not care). A feature that is constant in the training data
    gets ``scale_ = 1`` (as scikit-learn's ``StandardScaler``), so nothing is divided by zero.

    Parameters
    ----------
    center : bool, default False
        Also subtract the training mean.

    Attributes
    ----------
    scale_ : Tensor, shape ``(F,)``
        Buffer; the fitted standard deviations (1 for constant features).
    mean_ : Tensor, shape ``(F,)``
        Buffer; the fitted means, or zeros.

    Examples
    --------
    >>> scaler = FeatureScaler().fit(torch.randn(100, 21) * 5)
    >>> scaler(torch.randn(4, 21)).shape
    torch.Size([4, 21])
    """

    _fitted_buffers = ("scale_", "mean_")

    def __init__(self, center: bool = False) -> None:
        super().__init__()
        self.center = center

    def fit(self, features: torch.Tensor) -> FeatureScaler:
        """Fit the scale on ``features`` ``(n, F)``, ``n >= 2`` finite rows; return ``self``."""
        _check_features(features, "features", None, min_rows=2)
        std = features.std(dim=0, correction=1)
        self.scale_ = torch.where(std > 0, std, torch.ones_like(std)).detach().clone()
        self.mean_ = features.mean(0).detach().clone() if self.center else torch.zeros_like(std)
        return self

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        """Return ``(features - mean_) / scale_``, shape ``(B, F)``, in the features' dtype."""
        if not self.fitted:
            raise _not_fitted(self)
        if not torch.compiler.is_exporting():
            _check_features(features, "features", self.scale_.shape[0])
        return (features - self.mean_.to(features.dtype)) / self.scale_.to(features.dtype)

    transform = forward

    def extra_repr(self) -> str:
        return f"center={self.center}"


def clustering_features(features: torch.Tensor, *, eps: float = 1e-6) -> torch.Tensor:
    """Return the 12 per-axis features of the unsupervised path from the 21 window features.

    Per axis: ``sqrt(var)``, ``log(tv + eps)``, ``log1p(cross)``, ``log(hf + eps)``
    (:data:`CLUSTERING_FEATURE_NAMES`); skewness, kurtosis and the fifth moment are dropped
    (DESIGN.md). The offsets keep a constant window (``var = tv = cross = hf = 0``) finite:
    ``log(0 + eps)`` for ``tv`` and ``hf`` (``eps`` in the signal's unit, default 1e-6 g, far below
    the 3.9 mg resolution of the sensor, so ``log(x + eps) = log(x)`` to within 3e-4 for every
    non-constant quantised window), and ``log1p`` for the integer crossing count (``log1p(0) = 0``;
    ``log1p(n) - log(n) < 1/n``, under 0.01 for the hundreds of crossings of real windows). All four
    maps are strictly increasing.

    Parameters
    ----------
    features : Tensor, shape ``(B, 21)``
        Output of :func:`window_features` (unscaled); the var, tv, cross and hf columns must be >= 0.
    eps : float
        Offset inside the logarithms of ``tv`` and ``hf``, > 0.

    Returns
    -------
    Tensor, shape ``(B, 12)``

    Examples
    --------
    >>> clustering_features(window_features(torch.zeros(1, 3, 100)))[0, :4]
    tensor([  0.0000, -13.8155,   0.0000, -13.8155])
    """
    if not torch.compiler.is_exporting():
        _check_features(features, "features", len(FEATURE_NAMES))
        check_positive(eps, "eps")
        kept = features.reshape(-1, 3, len(AXIS_FEATURES))[:, :, [0, 4, 5, 6]]
        if bool((kept < 0).any()):
            raise ValueError("features must have var, tv, cross and hf >= 0 (window_features output)")
    per_axis = features.reshape(-1, 3, len(AXIS_FEATURES))
    out = torch.stack(
        [
            per_axis[..., 0].sqrt(),
            torch.log(per_axis[..., 4] + eps),
            torch.log1p(per_axis[..., 5]),
            torch.log(per_axis[..., 6] + eps),
        ],
        dim=-1,
    )
    return out.reshape(-1, len(CLUSTERING_FEATURE_NAMES))


class ClusteringTransform(_FittedBuffers):
    """The unsupervised transform: 21 window features → ``n_components`` principal components.

    ``forward(x) = ((clustering_features(x) - mean_) / scale_) @ components_.T``: the 12 features of
    :func:`clustering_features`, standardised (if ``standardize``; ``ddof=1``, constant columns
    scale 1) with training statistics, projected on the leading principal axes of the training data.
    Components are the right singular vectors of the centred (standardised) training matrix, signed
    so that the largest-magnitude loading of each is positive (scikit-learn's ``svd_flip``
    convention), so a fit is reproducible.

    Parameters
    ----------
    n_components : int, default 3
        Number of principal components, ``1 <= n_components <= 12``.
    standardize : bool, default True
        Scale the 12 features to unit variance before the PCA (they mix g, log g and log counts).
    eps : float, default 1e-6
        Offset in the logarithms (see :func:`clustering_features`).

    Attributes
    ----------
    mean_, scale_ : Tensor, shape ``(12,)``
        Buffers; training mean and standard deviation (scale 1 if not ``standardize``).
    components_ : Tensor, shape ``(n_components, 12)``
        Buffer; principal axes.
    explained_variance_ : Tensor, shape ``(n_components,)``
        Buffer; variance of the training data along each axis (``ddof=1``).
    explained_variance_ratio_ : Tensor, shape ``(n_components,)``
        Buffer; its share of the total variance.

    Examples
    --------
    >>> feats = window_features(torch.randn(50, 3, 200))
    >>> ClusteringTransform(n_components=3).fit(feats)(feats).shape
    torch.Size([50, 3])
    """

    _fitted_buffers = ("mean_", "scale_", "components_", "explained_variance_", "explained_variance_ratio_")

    def __init__(self, n_components: int = 3, *, standardize: bool = True, eps: float = 1e-6) -> None:
        super().__init__()
        check_positive(n_components, "n_components", integer=True)
        if n_components > len(CLUSTERING_FEATURE_NAMES):
            raise ValueError(f"n_components must be <= {len(CLUSTERING_FEATURE_NAMES)}, got {n_components}")
        check_positive(eps, "eps")
        self.n_components = n_components
        self.standardize = standardize
        self.eps = eps

    def fit(self, features: torch.Tensor) -> ClusteringTransform:
        """Fit the standardisation and the PCA on ``features`` ``(n, 21)``, ``n >= 2``; return ``self``."""
        _check_features(features, "features", len(FEATURE_NAMES), min_rows=2)
        x = clustering_features(features, eps=self.eps).to(torch.float64)
        mean = x.mean(0)
        std = x.std(0, correction=1)
        scale = torch.where(std > 0, std, torch.ones_like(std)) if self.standardize else torch.ones_like(std)
        centred = (x - mean) / scale
        _, sing, vh = torch.linalg.svd(centred, full_matrices=False)
        vh = vh[: self.n_components]
        sign = torch.sign(vh.gather(1, vh.abs().argmax(1, keepdim=True)))
        variance = sing**2 / (x.shape[0] - 1)
        dtype = features.dtype
        self.mean_ = mean.to(dtype)
        self.scale_ = scale.to(dtype)
        self.components_ = (vh * sign).to(dtype)
        self.explained_variance_ = variance[: self.n_components].to(dtype)
        self.explained_variance_ratio_ = (variance[: self.n_components] / variance.sum()).to(dtype)
        return self

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        """Return the principal components of ``features`` ``(B, 21)`` → ``(B, n_components)``."""
        if not self.fitted:
            raise _not_fitted(self)
        x = clustering_features(features, eps=self.eps)
        dtype = x.dtype
        return ((x - self.mean_.to(dtype)) / self.scale_.to(dtype)) @ self.components_.to(dtype).T

    transform = forward

    def extra_repr(self) -> str:
        return f"n_components={self.n_components}, standardize={self.standardize}, eps={self.eps}"


__all__ = [
    "AXES",
    "AXIS_FEATURES",
    "CLUSTERING_FEATURE_NAMES",
    "FEATURE_NAMES",
    "ClusteringTransform",
    "FeatureScaler",
    "WindowFeatures",
    "clustering_features",
    "sliding_windows",
    "window_features",
]
