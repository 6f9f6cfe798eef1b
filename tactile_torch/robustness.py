"""Breaking points: how far each degradation can go before a model's accuracy falls halfway to chance.

A :class:`Degradation` is a small declarative record: what it degrades (``kinds`` of raw input), where
it acts (``stage``), the levels to sweep from mildest to harshest, and a pure function that applies one
level. :func:`sweep` evaluates clone-able scikit-learn estimators on their raw input (frames
``(N, T, 3, H, W)`` or pressure maps ``(N, T, H, W)``, signal windows ``(N, 3, W)``, or features
``(N, F)``) under every level, by grouped cross-validation, and returns one :class:`Curve` per factor
and model with its :class:`BreakingPoint`. :func:`breaking_points` is the same for one estimator.

Where a degradation acts (``stage``):

==============  ========================================================================================
``"features"``  the classifier's input, at test time: the output of every step before the last one of
                a :class:`~sklearn.pipeline.Pipeline` (features, standardised when a scaler precedes
                the classifier), or the raw input of a bare classifier. The study's Table 3.
``"test"``      the raw test input only; the model was trained on clean data (a disturbance met at
                run time: noise on the images or the signals).
``"retrain"``   the raw training and test input alike, the model retrained at each level (a sensor or
                protocol setting: fewer frames, coarser sensels, shorter windows, lower rate, coarser
                quantisation, smaller range).
``"train"``     the training split only (fewer training samples per class: the learning curve).
``"parameter"`` a parameter of the model's ``features`` step (the erosion element), retrained.
``"time"``      the split: train on the first part of every recording, test on later parts (drift).
==============  ========================================================================================

The breaking point of a curve is the first level at which accuracy is at or below
``chance + (clean - chance) / 2``, ``chance = 1 / n_classes``, interpolated linearly between the
last level above and the first at or below (in the level's value, or between the two levels' names
when the levels are not numbers). Its 95 % interval comes from a cluster bootstrap over the groups
(resampling whole recordings, objects or sessions with their pooled test predictions; the model is
not refitted): 2.5th and 97.5th percentiles of the replicates' breaking points, a replicate that
never falls counting as beyond the harshest level.

Examples
--------
>>> from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
>>> rng = np.random.default_rng(0)
>>> X = rng.normal(size=(60, 4)) + np.repeat(np.eye(3, 4) * 3, 20, axis=0)
>>> y = np.repeat(np.arange(3), 20)
>>> curves = breaking_points(LinearDiscriminantAnalysis(), X, y, factors=["feature SNR"], random_state=0)
>>> curves[0].breaking.status
'reached'
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from . import noise, sensor_limits
from ._checks import RandomState, check_positive, numpy_rng

KINDS = ("image", "vibration", "features")
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
        Raw inputs it applies to, among :data:`KINDS`.
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
    """Return the default factors that apply to raw input of ``kind`` (see :data:`KINDS`)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    return tuple(f for f in FACTORS if kind in f.kinds)


# ------------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class BreakingPoint:
    """Where a curve falls halfway from its clean accuracy to chance.

    Positions count along the curve's path: 0 is the clean input, ``k`` its ``k``-th level (from 1),
    ``math.inf`` beyond the harshest level tested.

    Attributes
    ----------
    status : str
        ``"reached"``; ``"not reached"`` (never at or below the threshold); ``"fit failed"`` (never at
        or below the threshold while the model could be fitted, and not at the next level, which is
        then its breaking level); ``"at chance"`` (the clean accuracy is not above chance).
    position, low, high : float
        The breaking position and its 95 % bootstrap interval.
    threshold : float
        ``chance + (clean - chance) / 2``.
    text : str
        The breaking level and its interval in the factor's unit, e.g. ``"8.3 dB [5.1 dB, 11 dB]"``.
    level : float or None
        The breaking level as a number (when reached between two numeric levels).
    """

    status: str
    position: float
    low: float
    high: float
    threshold: float
    text: str
    level: float | None = None


@dataclass
class Curve:
    """Accuracy of one model under one factor, level by level, with its breaking point.

    Attributes
    ----------
    factor : Degradation
    model : str
    levels : tuple
        The levels evaluated (those the data allows; fewer when a fit failed), mildest first.
    accuracy, low, high : ndarray of shape (len(levels),)
        Accuracy of the pooled test predictions and its 95 % cluster-bootstrap interval.
    clean, clean_low, clean_high : float
        The same without degradation (drift: on the segment right after training).
    chance : float
        ``1 / n_classes``.
    breaking : BreakingPoint
    note : str
        Why the curve stops early (a level at which the model could not be fitted), or ``""``.
    """

    factor: Degradation
    model: str
    levels: tuple
    accuracy: np.ndarray
    low: np.ndarray
    high: np.ndarray
    clean: float
    clean_low: float
    clean_high: float
    chance: float
    breaking: BreakingPoint
    note: str = ""

    def path(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
        """The levels, accuracies and bounds along the breaking path (Table 4: the grid's diagonal)."""
        idx = [i for i in (self.factor.path or range(len(self.levels))) if i < len(self.levels)]
        return [self.levels[i] for i in idx], self.accuracy[idx], self.low[idx], self.high[idx]


@dataclass
class SweepResult:
    """What :func:`sweep` returns: the curves, the factors skipped and why, and the folds used."""

    curves: list[Curve]
    skipped: list[tuple[str, str]] = field(default_factory=list)
    n_splits: int = 0
    kind: str = ""

    def by_factor(self) -> dict[str, list[Curve]]:
        """Curves grouped by factor name, in sweep order."""
        out: dict[str, list[Curve]] = {}
        for c in self.curves:
            out.setdefault(c.factor.name, []).append(c)
        return out


# ------------------------------------------------------------------------------------------ API
def infer_kind(X: object) -> str:
    """Return the kind of raw input from its shape: ``"image"``, ``"vibration"`` or ``"features"``."""
    shape = tuple(getattr(X, "shape", ()))
    if (len(shape) == 5 and shape[2] == 3) or len(shape) == 4:
        return "image"
    if len(shape) == 3 and shape[1] == 3:
        return "vibration"
    if len(shape) == 2:
        return "features"
    raise ValueError(
        "X must be frames (N, T, 3, H, W), pressure maps (N, T, H, W), windows (N, 3, W) or features "
        f"(N, F), got shape {shape}"
    )


def recording_blocks(recording: object, position: object, n_blocks: int = 5) -> np.ndarray:
    """Return group ids that cut every recording into ``n_blocks`` runs of consecutive windows.

    For grouped folds on data with one recording per class: neighbouring windows stay in one fold
    (only the block borders touch), so a fold never tests a window whose neighbour trained.

    Parameters
    ----------
    recording : array-like of shape (N,)
        Recording of each window.
    position : array-like of shape (N,)
        Index of each window within its recording (time order, from 0).
    n_blocks : int >= 1

    Examples
    --------
    >>> recording_blocks([0, 0, 0, 0, 1, 1], [0, 1, 2, 3, 0, 1], n_blocks=2).tolist()
    [0, 0, 1, 1, 2, 3]
    """
    check_positive(n_blocks, "n_blocks", integer=True)
    recording, position = np.asarray(recording), np.asarray(position)
    if recording.shape != position.shape or recording.ndim != 1:
        raise ValueError(
            f"recording and position must be 1-D of one length, got {recording.shape} and {position.shape}"
        )
    ids = np.zeros(len(recording), dtype=np.int64)
    for offset, r in enumerate(np.unique(recording)):
        at = recording == r
        count = int(position[at].max()) + 1
        ids[at] = offset * n_blocks + np.minimum(position[at] * n_blocks // count, n_blocks - 1)
    return np.unique(ids, return_inverse=True)[1]


def _check_inputs(X: object, y: object, groups: object) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(X, torch.Tensor | np.ndarray):
        raise TypeError(f"X must be a torch.Tensor or numpy.ndarray, got {type(X).__name__}")
    y = y.numpy() if isinstance(y, torch.Tensor) else np.asarray(y)
    n = X.shape[0]
    if y.shape != (n,):
        raise ValueError(f"y must have shape ({n},) (one label per sample of X), got {y.shape}")
    if len(np.unique(y)) < 2:
        raise ValueError(f"y must hold at least 2 classes, got {len(np.unique(y))}")
    groups = np.arange(n) if groups is None else groups
    groups = groups.numpy() if isinstance(groups, torch.Tensor) else np.asarray(groups)
    if groups.shape != (n,):
        raise ValueError(f"groups must have shape ({n},) (one group per sample of X), got {groups.shape}")
    return y, groups


def _allowed_levels(f: Degradation, X: Any, y: np.ndarray, folds: list) -> tuple:
    """The factor's levels that the data allows (see :attr:`Degradation.limit`)."""
    if f.limit is None:
        return tuple(f.levels)
    if f.limit == "frames":
        top = X.shape[1] - 1
    elif f.limit == "pixels":
        top = min(X.shape[-2:]) // 2
    elif f.limit == "samples":
        top = X.shape[-1] - 1
    elif f.limit == "decimation":
        top = X.shape[-1] // 4
    else:  # "train_per_class": fewer than the smallest class has in any training fold
        top = min(int(np.bincount(y[tr])[np.unique(y[tr])].min()) for tr, _ in folds) - 1
    return tuple(v for v in f.levels if v <= top)


def sweep(
    models: Mapping[str, Any] | Any,
    X: torch.Tensor | np.ndarray,
    y: object,
    groups: object = None,
    kind: str | None = None,
    *,
    factors: Iterable[Degradation | str] | None = None,
    context: Mapping[str, Any] | None = None,
    n_splits: int = 5,
    n_trials: int | Mapping[str, int] = 3,
    n_bootstrap: int = 1000,
    random_state: RandomState = None,
    progress: bool = False,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
) -> SweepResult:
    """Sweep every factor over every model; return the accuracy curves and their breaking points.

    Parameters
    ----------
    models : estimator or mapping of name to estimator
        Clone-able scikit-learn classifiers on the raw input ``X``. In a
        :class:`~sklearn.pipeline.Pipeline` whose first step is named ``"features"``, that step is
        fitted once per fold and data variant for all the models that share it (same class and
        parameters); one that needs no fit (scikit-learn's ``requires_fit`` tag, e.g. a
        ``FunctionTransformer``) runs once on the whole set.
    X : tensor or ndarray
        Frames ``(N, T, 3, H, W)``, pressure maps ``(N, T, H, W)``, windows ``(N, 3, W)`` or features
        ``(N, F)``, in the type the models take.
    y : array-like of shape (N,)
    groups : array-like of shape (N,), optional
        Recording, object or session of each sample: folds never split a group (stratified grouped
        folds) and the bootstrap resamples groups. Default: every sample its own group.
    kind : str, optional
        ``"image"``, ``"vibration"`` or ``"features"``; default (and checked against) the shape of ``X``.
    factors : iterable of Degradation or names, optional
        Default: :func:`factors_for` ``kind``. Factors whose ``needs`` are missing from ``context``, or
        that do not apply to ``X``, are skipped and listed in the result's ``skipped``.
    context : mapping, optional
        ``pitch_px``: the texture pitch in pixels (erosion factor); ``position``: fraction of its
        recording elapsed at each sample, in [0, 1), and ``recording``: recording of each sample (drift).
    n_splits : int
        Folds (at most as many as the rarest class has groups).
    n_trials : int or mapping of factor name to int
        Draws of every random degradation, averaged per sample; a mapping gives them per factor (3 for a
        factor it does not name), e.g. the study's 10 for the feature SNR and 1 for image noise.
    n_bootstrap : int
        Bootstrap replicates for the intervals.
    random_state : int, numpy or torch Generator, or None
        Folds, noise and bootstrap. With an int, every model meets the same folds and noise draws.
    progress : bool
        A progress bar per factor (tqdm, on stderr).
    backend, n_jobs, scheduler
        Where the fits (model x fold, at every level that retrains) run: the evaluation engine's
        :class:`tactile_torch.engine.Backend` (``"loky"``, ``"threading"``, ``"dask"`` with a scheduler
        address ...); default in this process. Results do not depend on them.

    Returns
    -------
    SweepResult

    Raises
    ------
    ValueError
        For inputs of the wrong shape, fewer than 2 classes or groups per class, an unknown factor, or
        a model that cannot be fitted on the clean folds.
    """
    from tqdm.auto import tqdm

    from . import _sweep
    from .engine import Models, as_backend, make_folds

    runner = as_backend(backend, n_jobs, scheduler)  # a Dask client opens for each stage's tasks
    y, groups = _check_inputs(X, y, groups)
    found = infer_kind(X)
    kind = found if kind is None else kind
    if kind not in KINDS or kind != found:
        raise ValueError(
            f"kind must be one of {KINDS} and match X of shape {tuple(X.shape)} ({found!r}), got {kind!r}"
        )
    trials = dict(n_trials) if isinstance(n_trials, Mapping) else {}
    default_trials = DEFAULT_TRIALS if isinstance(n_trials, Mapping) else n_trials
    for value, name in ((n_splits, "n_splits"), (default_trials, "n_trials"), (n_bootstrap, "n_bootstrap")):
        check_positive(value, name, integer=True)
    for key, value in trials.items():
        check_positive(value, f"n_trials[{key!r}]", integer=True)
    models = dict(models) if isinstance(models, Mapping) else {"model": models}
    if not models:
        raise ValueError("models must hold at least one estimator, got an empty mapping")
    context = dict(context or {})
    chosen = (
        factors_for(kind)
        if factors is None
        else tuple(factor(f) if isinstance(f, str) else f for f in factors)
    )
    seed = int(numpy_rng(random_state).integers(2**62))
    folds = make_folds(y, groups, n_splits, seed)
    chance = 1.0 / len(np.unique(y))
    base = Models(models)
    whole = base.whole(X, y)
    clean, fitted, feats = _sweep.fit_predict(base, X, y, folds, whole, runner)
    for name, value in clean.items():
        if isinstance(value, str):
            raise ValueError(f"models[{name!r}] could not be fitted on the clean folds: {value}")
    result = SweepResult(curves=[], n_splits=len(folds), kind=kind)
    for f in chosen:
        missing = [k for k in f.needs if k not in context]
        if missing or kind not in f.kinds or (f.ndim is not None and X.ndim != f.ndim):
            why = (
                f"needs {missing} in context" if missing else f"does not apply to X of shape {tuple(X.shape)}"
            )
            result.skipped.append((f.name, why))
            continue
        if f.stage == "time":
            drift = _sweep.drift_rows(
                f, base, X, y, context, whole, DRIFT_TRAIN_SHARE, DRIFT_SEGMENTS, backend=runner
            )
            if drift is None:
                result.skipped.append(
                    (f.name, "recordings too short: fewer than two test segments hold samples")
                )
                continue
            rows, levels, group_of = drift
        else:
            levels = _allowed_levels(f, X, y, folds)
            if not levels:
                result.skipped.append((f.name, f"no level applies to X of shape {tuple(X.shape)}"))
                continue
            names = base.names
            if f.stage == "parameter":  # a model without the parameter is not swept (not broken)
                probe = Models(models, f.apply(context, levels[0]))
                result.skipped += [(f"{f.name} for {m}", why) for m, why in probe.errors.items()]
                names = [m for m in names if m not in probe.errors]
            rows = {m: [clean[m]] for m in names}
            bar = tqdm(total=len(levels), desc=f.name, disable=not progress, leave=False)
            for level in levels:
                n = trials.get(f.name, default_trials)
                got = _sweep.evaluate(
                    f, level, base, fitted, feats, whole, X, y, folds, context, n, seed, backend=runner
                )
                for m in rows:
                    if not isinstance(rows[m][-1], str):
                        rows[m].append(got[m])
                bar.update()
            bar.close()
            group_of = groups
        for m in rows:
            fields = _sweep.build_curve(f, m, levels, rows[m], group_of, chance, n_bootstrap, seed)
            result.curves.append(Curve(**{**fields, "breaking": BreakingPoint(*fields["breaking"])}))
    return result


def breaking_points(
    estimator: Any,
    X: torch.Tensor | np.ndarray,
    y: object,
    groups: object = None,
    kind: str | None = None,
    **kwargs: Any,
) -> list[Curve]:
    """Return the curves (with breaking points) of one estimator under every factor of ``kind``.

    The entry point for one model: :func:`sweep` with ``{"model": estimator}``; keyword arguments are
    :func:`sweep`'s. Each curve's ``breaking`` holds the level, its interval and a text.
    """
    return sweep({"model": estimator}, X, y, groups, kind, **kwargs).curves


# --------------------------------------------------------------------------------- presentation
def breaking_table(curves: Iterable[Curve]) -> list[dict[str, Any]]:
    """Return one row per curve: factor, model, clean accuracy with its interval, the halfway
    threshold, the breaking level with its 95 % interval, and a note."""
    return [
        {
            "factor": c.factor.name,
            "model": c.model,
            "clean accuracy [95 % CI]": f"{c.clean:.3f} [{c.clean_low:.3f}, {c.clean_high:.3f}]",
            "halfway to chance": round(c.breaking.threshold, 3),
            "breaks at [95 % CI]": c.breaking.text,
            "note": c.note,
        }
        for c in curves
    ]


_AXIS_TITLES = {
    "feature SNR": "feature SNR (dB)",
    "image noise": "image noise (mean, variance)",
    "frames": "frames per exploration",
    "sensel grid": "sensel size (times the sensor's)",
    "erosion / pitch": "erosion square (texture pitches)",
    "window": "window (samples)",
    "sensor noise": "sensor noise (g, standard deviation)",
    "quantisation": "quantisation step (g)",
    "saturation": "sensor range (± g)",
    "sample rate": "sample rate (times lower)",
    "training samples": "training samples per class",
    "drift": "test segment centre (share of the recording)",
}


def axis_title(f: Degradation) -> str:
    """Return the x-axis title of a factor's chart: the quantity and its unit, said once (the tick
    labels are bare numbers)."""
    if f.name in _AXIS_TITLES:
        return _AXIS_TITLES[f.name]
    return f.name if not f.unit or f.unit in f.name else f"{f.name} ({f.unit})"


def _tick(level: Any) -> str:
    if isinstance(level, tuple):
        return "(" + ", ".join(f"{v:.3g}" for v in level) + ")"
    return f"{level:.3g}" if isinstance(level, int | float) else str(level)


def _legend_handles(models: Sequence[str]) -> tuple[list, list[str]]:
    """Legend entries shared by the factor charts: one line per model, then what the marks mean."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=f"C{i}", marker="o", ms=3) for i in range(len(models))]
    labels = list(models)
    handles += [
        Line2D([], [], color="grey", ls="--", lw=0.8),
        Line2D([], [], color="k", ls=":", lw=0.8),
        Line2D([], [], color="k", marker="v", ls="", ms=7),
    ]
    labels += ["chance", "halfway to chance (model's colour)", "breaking point"]
    return handles, labels


def plot_factor(
    curves: Sequence[Curve], *, ax: Any = None, legend: bool = True, models: Sequence[str] | None = None
) -> Any:
    """Return a figure of accuracy against level for every curve of one factor.

    Lines are the accuracies along the breaking path with their 95 % bands; the clean accuracy is the
    first point (at the left, marked "clean"), dotted lines the halfway thresholds, the dashed grey line
    chance, and triangles the breaking levels. Severity grows to the right. The x-axis title gives the
    quantity and its unit; the ticks are the levels. ``legend=False`` leaves the legend to the caller
    (:func:`plot_factors` draws one for all panels); ``models`` fixes each model's colour (its index).
    """
    import matplotlib.pyplot as plt

    if not curves:
        raise ValueError("curves must hold at least one curve, got none")
    f = curves[0].factor
    models = list(models) if models is not None else list(dict.fromkeys(c.model for c in curves))
    fig = ax.figure if ax is not None else plt.subplots(figsize=(6.4, 3.8))[0]
    ax = ax if ax is not None else fig.axes[0]
    longest = max(curves, key=lambda c: len(c.path()[0]))
    labels = ["clean"] + [_tick(v) for v in longest.path()[0]]
    for c in curves:
        _, acc, low, high = c.path()
        x = np.arange(len(acc) + 1)
        colour = f"C{models.index(c.model)}"
        ax.plot(x, np.r_[c.clean, acc], marker="o", ms=3, color=colour)
        ax.fill_between(x, np.r_[c.clean_low, low], np.r_[c.clean_high, high], color=colour, alpha=0.15)
        ax.axhline(c.breaking.threshold, color=colour, ls=":", lw=0.8)
        if c.breaking.status == "reached":
            ax.plot([c.breaking.position], [c.breaking.threshold], marker="v", ms=8, color=colour)
    ax.axhline(curves[0].chance, color="grey", ls="--", lw=0.8)
    crowded = len(labels) * max(len(t) for t in labels) > 36  # about what a 4-inch axis holds at 8 pt
    ax.set_xticks(
        np.arange(len(labels)),
        labels,
        rotation=45 if crowded else 0,
        ha="right" if crowded else "center",
        fontsize=8,
    )
    ax.set_xlabel(axis_title(f))
    ax.set_ylabel("accuracy")
    ax.set_ylim(0.0, 1.02)
    ax.set_title(f.name, fontsize=9)
    if legend:
        ax.legend(*_legend_handles(models), fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    return fig


def plot_factors(curves: Iterable[Curve], *, columns: int = 4) -> Any:
    """Return one figure with a panel per factor (:func:`plot_factor`), every candidate's curve in each,
    and one legend for all panels (the models keep their colour from panel to panel)."""
    import matplotlib.pyplot as plt

    by: dict[str, list[Curve]] = {}
    for c in curves:
        by.setdefault(c.factor.name, []).append(c)
    if not by:
        raise ValueError("curves must hold at least one curve, got none")
    models = list(dict.fromkeys(c.model for group in by.values() for c in group))
    rows = -(-len(by) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.4 * rows + 0.6), squeeze=False)
    for ax, group in zip(axes.flat, by.values(), strict=False):
        plot_factor(group, ax=ax, legend=False, models=models)
    for ax in list(axes.flat)[len(by) :]:
        ax.set_visible(False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.6 / (3.4 * rows + 0.6)))
    handles, labels = _legend_handles(models)
    fig.legend(handles, labels, loc="upper center", ncol=min(len(labels), 6), fontsize=8, frameon=False)
    return fig


def plot_grid(curve: Curve, means: Sequence[float], variances: Sequence[float]) -> Any:
    """Return a heat map of a grid factor's accuracies (Table 4: rows mean, columns variance); cells at
    or below the halfway threshold are hatched."""
    import matplotlib.pyplot as plt

    acc = {lvl: a for lvl, a in zip(curve.levels, curve.accuracy, strict=True)}
    grid = np.array([[acc.get((m, v), np.nan) for v in variances] for m in means])
    fig, ax = plt.subplots(figsize=(4.6, 3.8))
    image = ax.imshow(grid, vmin=curve.chance, vmax=1.0, cmap="viridis", origin="upper")
    for i, j in np.ndindex(grid.shape):
        if np.isfinite(grid[i, j]):
            broken = grid[i, j] <= curve.breaking.threshold
            ax.text(
                j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=7, color="w" if broken else "k"
            )
            if broken:
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="//", ec="w", lw=0))
    ax.set_xticks(range(len(variances)), [f"{v:g}" for v in variances])
    ax.set_yticks(range(len(means)), [f"{m:g}" for m in means])
    ax.set_xlabel("noise variance")
    ax.set_ylabel("noise mean")
    ax.set_title(
        f"{curve.model}: clean {curve.clean:.2f}, halfway {curve.breaking.threshold:.2f}", fontsize=8
    )
    fig.colorbar(image, ax=ax, label="accuracy")
    return fig


def breaking_summary(result: SweepResult | Sequence[Curve], out_dir: str | Path) -> dict[str, Any]:
    """Write one chart per factor to ``out_dir`` (``breaking-<factor>.png``) and return
    ``{"rows": breaking_table(...), "figures": [paths], "skipped": [...]}``: what a results file such as
    ``tactile-torch tradeoff``'s ``tradeoff.json`` / ``tradeoff.md`` holds about breaking points."""
    import matplotlib.pyplot as plt

    if not isinstance(result, SweepResult):
        result = SweepResult(curves=list(result))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = []
    for name, curves in result.by_factor().items():
        slug = "".join(ch if ch.isalnum() else "-" for ch in name.lower()).strip("-")
        fig = plot_factor(curves)
        figures.append(out / f"breaking-{slug}.png")
        fig.savefig(figures[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)
    return {
        "rows": breaking_table(result.curves),
        "figures": [str(p) for p in figures],
        "skipped": [list(s) for s in result.skipped],
    }


def write_breaking_points(
    result: SweepResult | Sequence[Curve], out_dir: str | Path, *, title: str = "Breaking points"
) -> Path:
    """Write a sweep's table and charts to ``out_dir``; return the path of the markdown file.

    ``result`` is a :class:`SweepResult` or the curves of :func:`breaking_points`. Writes
    ``breaking_points.md`` (the table of :func:`breaking_table`, the skipped factors and one chart per
    factor, see :func:`breaking_summary`), ``breaking_points.json`` (every curve: levels, accuracies,
    intervals, breaking point) and ``breaking-<factor>.png``.
    """
    import json

    if not isinstance(result, SweepResult):
        result = SweepResult(curves=list(result))
    out = Path(out_dir)
    summary = breaking_summary(result, out)
    rows = summary["rows"]
    columns = list(rows[0]) if rows else []
    folds = f"{result.n_splits} grouped folds; " if result.n_splits else ""
    lines = [f"# {title}", "", f"{folds}95 % cluster-bootstrap intervals.", ""]
    if rows:
        lines += ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        lines += ["| " + " | ".join(str(r[c]).replace("|", "\\|") for c in columns) + " |" for r in rows]
    lines += [""] + [f"- not swept: {name} ({why})" for name, why in result.skipped]
    lines += ["", *(f"![{Path(p).stem}]({Path(p).name})" for p in summary["figures"])]
    md = out / "breaking_points.md"
    md.write_text("\n".join(lines) + "\n")
    curves = [
        {
            "factor": c.factor.name,
            "unit": c.factor.unit,
            "model": c.model,
            "levels": [list(v) if isinstance(v, tuple) else v for v in c.levels],
            "accuracy": c.accuracy.tolist(),
            "low": c.low.tolist(),
            "high": c.high.tolist(),
            "clean": [c.clean, c.clean_low, c.clean_high],
            "chance": c.chance,
            "breaking": {
                "status": c.breaking.status,
                "text": c.breaking.text,
                "level": c.breaking.level,
                "threshold": c.breaking.threshold,
            },
            "note": c.note,
        }
        for c in result.curves
    ]
    (out / "breaking_points.json").write_text(
        json.dumps({"curves": curves, "skipped": result.skipped}, indent=1)
    )
    return md
