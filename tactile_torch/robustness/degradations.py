"""The degradations a sweep applies: the :class:`Degradation` record and the default factors (:data:`FACTORS`).

Each factor is a declarative record (the raw inputs it applies to, where it acts, its levels from
mildest to harshest) and a pure function that applies one level; :mod:`tactile_torch.robustness.sweeps`
sweeps them. The stages are described in :mod:`tactile_torch.robustness`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from .. import noise
from . import sensor_limits

INPUT_KINDS = ("image", "vibration", "features")
"""The kinds of raw input a degradation applies to (:attr:`Degradation.kinds`)."""
STAGES = ("features", "test", "retrain", "train", "parameter", "time")


def _image_noise(frames: torch.Tensor, level: tuple[float, float], generator: int) -> torch.Tensor:
    """:func:`tactile_torch.noise.gaussian_image_noise`, rounded back to uint8 for uint8 frames
    (like MATLAB's ``imnoise`` on a uint8 image)."""
    mean, var = level
    noisy = noise.gaussian_image_noise(frames, mean, var, generator=generator)
    if frames.dtype == torch.uint8:
        return torch.round(noisy * 255.0).to(torch.uint8)
    return noisy


def _float_op(op: Callable) -> Callable:
    """Apply ``op(x, level)`` to a float copy of integer windows."""

    def apply(x: torch.Tensor, level: Any, generator: int) -> torch.Tensor:
        return op(x if x.is_floating_point() else x.float(), level)

    return apply


# --------------------------------------------------------------------------------- the records
@dataclass(frozen=True)
class Degradation:
    """One factor to sweep: a declarative record and the pure function that applies one level.

    Attributes
    ----------
    name : str
        Unique name (``"feature SNR"``), used to pick factors and to seed their randomness.
    kinds : tuple of str
        Raw inputs it applies to, among :data:`INPUT_KINDS`.
    stage : str
        Where it acts, among :data:`STAGES` (see the module docstring).
    levels : tuple
        Levels from mildest to harshest. Levels the data cannot take (more frames than recorded, a
        window longer than the data's) are dropped when sweeping.
    unit : str
        What a level is (``"dB"``, ``"frames"``).
    description : str
        One line for tables and charts.
    apply : callable or None
        ``"features"``/``"test"``/``"retrain"``: ``apply(x, level, generator) -> x`` on a tensor;
        ``"train"``: ``apply(y_train, level, rng) -> indices`` of the kept training samples;
        ``"parameter"``: ``apply(context, level) -> {parameter: value}`` for the ``features`` step;
        ``"time"``: unused.
    random : bool
        Whether the function draws random numbers (then ``n_trials`` draws are averaged).
    limit : str or None
        Which size of the data bounds the levels (levels above the bound are dropped): ``"frames"``
        (below T), ``"pixels"`` (up to min(H, W) / 2), ``"samples"`` (below W), ``"decimation"`` (up to
        W / 4: at least 4 samples left), ``"train_per_class"`` (below the smallest class of a
        training fold).
    needs : tuple of str
        Keys that must be in the sweep's ``context`` (e.g. ``"pitch_px"``); without them the factor is
        skipped with a note.
    needs_words : str
        What those keys are, in the user's words (the note: ``"needs <needs_words>, which these data do
        not give"``).
    ndim : int or None
        Only for raw input of this many dimensions (image noise: RGB frames, 5).
    path : tuple of int or None
        For a grid of levels (Table 4), the indices of the levels whose curve decides the breaking
        point (the grid's diagonal); ``None``: all levels in order.
    log_x : bool
        Draw the levels on a log axis.
    """

    name: str
    kinds: tuple[str, ...]
    stage: str
    levels: tuple
    unit: str
    description: str
    apply: Callable | None = None
    random: bool = False
    limit: str | None = None
    needs: tuple[str, ...] = ()
    needs_words: str = ""
    ndim: int | None = None
    path: tuple[int, ...] | None = None
    log_x: bool = False

    def label(self, level: Any) -> str:
        """Return a level as text with its unit (three significant digits)."""
        if isinstance(level, tuple):
            return "(" + ", ".join(f"{v:.3g}" for v in level) + ")"
        return f"{level:.3g} {self.unit}".strip() if isinstance(level, int | float) else str(level)


def _awgn(x: torch.Tensor, level: float, generator: int) -> torch.Tensor:
    return noise.awgn(x, float(level), generator=generator)


def _sensor_noise(x: torch.Tensor, level: float, generator: int) -> torch.Tensor:
    return noise.gaussian_noise(x if x.is_floating_point() else x.float(), float(level), generator=generator)


def _per_class(y: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of at most ``level`` randomly chosen samples of every class of ``y``."""
    keep = [rng.permutation(np.flatnonzero(y == c))[: int(level)] for c in np.unique(y)]
    return np.sort(np.concatenate(keep))


def _erosion_from_pitch(context: Mapping[str, Any], level: float) -> dict[str, int]:
    return {"erosion": max(1, round(float(level) * float(context["pitch_px"])))}


IMAGE_NOISE_MEANS = (0.1, 0.2, 0.3, 0.4, 0.5)
IMAGE_NOISE_VARIANCES = (0.01, 0.03, 0.05, 0.07, 0.09)
SNR_DB = (30, 25, 20, 15, 10, 8, 5, 3, 1, -3)

FACTORS: tuple[Degradation, ...] = (
    Degradation(
        "feature SNR",
        ("image", "vibration", "features"),
        "features",
        SNR_DB,
        "dB",
        "white Gaussian noise on the classifier's input at this signal-to-noise ratio (study, Table 3)",
        _awgn,
        random=True,
    ),
    Degradation(
        "image noise",
        ("image",),
        "test",
        tuple((m, v) for m in IMAGE_NOISE_MEANS for v in IMAGE_NOISE_VARIANCES),
        "(mean, variance)",
        "Gaussian noise of this (mean, variance) on the raw 0-1 frames, clipped (study, Table 4: the 5 x 5 "
        "grid; breaking point along its diagonal)",
        _image_noise,
        random=True,
        ndim=5,
        path=tuple(5 * k + k for k in range(5)),
    ),
    Degradation(
        "frames",
        ("image",),
        "retrain",
        (100, 50, 30, 20, 10, 5, 3, 2, 1),
        "frames",
        "only the first frames of every exploration (a shorter exploration), retrained",
        lambda x, level, generator: sensor_limits.keep_frames(x, level),
        limit="frames",
        log_x=True,
    ),
    Degradation(
        "sensel grid",
        ("image",),
        "retrain",
        (1, 2, 3, 4, 6, 8, 12, 16),
        "x coarser",
        "sensels this many times larger per side (block mean, shown at the same size), retrained",
        lambda x, level, generator: sensor_limits.coarsen_grid(x, level),
        limit="pixels",
        log_x=True,
    ),
    Degradation(
        "erosion / pitch",
        ("image",),
        "parameter",
        (0.05, 0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0),
        "x pitch",
        "side of the erosion square relative to the texture pitch (context pitch_px), retrained",
        _erosion_from_pitch,
        needs=("pitch_px",),
        needs_words="the texture's pitch in pixels (a data file does not say it)",
    ),
    Degradation(
        "window",
        ("vibration",),
        "retrain",
        (1600, 800, 400, 200, 100, 50, 25, 12),
        "samples",
        "only the first samples of every window (a shorter window), retrained",
        lambda x, level, generator: sensor_limits.crop_windows(x, level),
        limit="samples",
        log_x=True,
    ),
    Degradation(
        "sensor noise",
        ("vibration",),
        "test",
        (0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0),
        "g",
        "white Gaussian noise of this standard deviation on the raw test windows",
        _sensor_noise,
        random=True,
        log_x=True,
    ),
    Degradation(
        "quantisation",
        ("vibration",),
        "retrain",
        (0.0039, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0),
        "g",
        "samples rounded to this step (an ADC's resolution), retrained",
        _float_op(sensor_limits.quantize),
        log_x=True,
    ),
    Degradation(
        "saturation",
        ("vibration",),
        "retrain",
        (4.0, 2.0, 1.0, 0.5, 0.2, 0.1, 0.05, 0.02),
        "g",
        "samples clipped to ± this range, retrained",
        _float_op(sensor_limits.saturate),
        log_x=True,
    ),
    Degradation(
        "sample rate",
        ("vibration",),
        "retrain",
        (2, 4, 8, 16, 32),
        "x lower",
        "windows resampled to this fraction of the rate (anti-aliased), retrained",
        lambda x, level, generator: sensor_limits.downsample(
            x if x.is_floating_point() else x.float(), level
        ),
        limit="decimation",
        log_x=True,
    ),
    Degradation(
        "training samples",
        ("image", "vibration", "features"),
        "train",
        (200, 100, 50, 20, 10, 5, 3, 2),
        "per class",
        "at most this many training samples per class (learning curve)",
        _per_class,
        random=True,
        limit="train_per_class",
        log_x=True,
    ),
    Degradation(
        "drift",
        ("vibration",),
        "time",
        (0.51, 0.65, 0.79, 0.93),
        "of the recording",
        "trained on the first 30 % of every recording, tested on the later 70 % cut into 5 segments (level: "
        "the segment's centre; the first segment, centred at 0.37, is the clean reference)",
        needs=("position", "recording"),
        needs_words="where each window lies in its recording (the trade-off's windows are cut without it; "
        "tactile-torch report sweeps drift on the bundled recordings)",
    ),
)
"""The default factors, in report order."""

QUICK_LEVELS: dict[str, tuple] = {
    "feature SNR": (20, 10, 5, 1, -3),
    "image noise": ((0.1, 0.01), (0.3, 0.05), (0.5, 0.09)),  # on Table 4's diagonal
    "frames": (20, 10, 5),
    "sensel grid": (2, 4, 8),
    "erosion / pitch": (0.25, 0.5, 1.0),
    "training samples": (10, 5, 2),
    "window": (200, 50, 25),
    "sensor noise": (0.01, 0.02, 0.05, 0.1),
    "quantisation": (0.1, 0.5, 1.0),
    "saturation": (0.5, 0.05, 0.02),
    "sample rate": (4, 16, 32),
}
"""Shorter level lists for a quick sweep (``make run``'s section, ``tactile-torch tradeoff --quick``):
``dataclasses.replace(factor(name), levels=QUICK_LEVELS[name], path=None)``."""

DEFAULT_TRIALS = 3
"""Draws per level of a random factor that a per-factor ``n_trials`` mapping does not name."""
DRIFT_TRAIN_SHARE = 0.3
"""Share of every recording that trains in the drift factor; the rest is cut into five test segments."""
DRIFT_SEGMENTS = 5


def factor(name: str) -> Degradation:
    """Return the default factor called ``name`` (see :data:`FACTORS`)."""
    for f in FACTORS:
        if f.name == name:
            return f
    raise ValueError(f"factor must be one of {[f.name for f in FACTORS]}, got {name!r}")


def factors_for(kind: str) -> tuple[Degradation, ...]:
    """Return the default factors that apply to raw input of ``kind`` (see :data:`INPUT_KINDS`)."""
    if kind not in INPUT_KINDS:
        raise ValueError(f"kind must be one of {INPUT_KINDS}, got {kind!r}")
    return tuple(f for f in FACTORS if kind in f.kinds)
