"""Sweep degradations over models: :func:`sweep` (every factor, every model), :func:`breaking_points`
(one estimator), and :func:`recording_blocks` (group ids for folds on long recordings).

See :mod:`tactile_torch.robustness` for the stages and the definition of a breaking point.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ..exceptions import InputTypeError
from ..validation import RandomState, check_positive, numpy_rng
from .degradations import (
    DEFAULT_TRIALS,
    DRIFT_SEGMENTS,
    DRIFT_TRAIN_SHARE,
    INPUT_KINDS,
    Degradation,
    factor,
    factors_for,
)
from .results import BreakingPoint, Curve, SweepResult


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
        raise InputTypeError(f"X must be a torch.Tensor or numpy.ndarray, got {type(X).__name__}")
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


def sweep(  # noqa: PLR0913
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
        :class:`tactile_torch.model_selection.Backend` (``"loky"``, ``"threading"``, ``"dask"`` with a scheduler
        address ...); default in this process. Results do not depend on them.

    Returns
    -------
    SweepResult
        A factor that does not apply to a model (noise on the feature rows of a network that classifies
        the raw input, a parameter the model lacks) is listed in ``skipped`` with why; a factor that
        raised is listed in ``failed`` with the error (a bug), and the other factors' curves are kept.

    Raises
    ------
    ValueError
        For inputs of the wrong shape, fewer than 2 classes or groups per class, an unknown factor, or
        a model that cannot be fitted on the clean folds.
    """
    from ..model_selection import Models, as_backend, make_folds
    from . import _evaluation

    runner = as_backend(backend, n_jobs, scheduler)  # a Dask client opens for each stage's tasks
    y, groups = _check_inputs(X, y, groups)
    found = infer_kind(X)
    kind = found if kind is None else kind
    if kind not in INPUT_KINDS or kind != found:
        raise ValueError(
            f"kind must be one of {INPUT_KINDS} and match X of shape {tuple(X.shape)} ({found!r}), got {kind!r}"
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
    _evaluation.check_drift_context(context, y)
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
    clean, fitted, feats = _evaluation.fit_predict(base, X, y, folds, whole, runner)
    for name, value in clean.items():
        if isinstance(value, str):
            raise ValueError(f"models[{name!r}] could not be fitted on the clean folds: {value}")
    state = _SweepState(
        models,
        base,
        X,
        y,
        groups,
        kind,
        context,
        clean,
        fitted,
        feats,
        whole,
        folds,
        chance,
        seed,
        trials,
        default_trials,
        n_bootstrap,
        progress,
        runner,
    )
    result = SweepResult(curves=[], n_splits=len(folds), kind=kind)
    for f in chosen:
        try:
            _sweep_factor(f, state, result)
        except Exception as err:  # a bug in one factor: the other factors' curves are kept, the failure said
            text = " ".join(str(err).split())[:300]
            result.failed.append((f.name, f"{type(err).__name__}: {text}"))
    return result


@dataclass(frozen=True)
class _SweepState:
    """What every factor of one :func:`sweep` shares: the models, data, folds and the clean fits."""

    models: dict
    base: Any
    X: Any
    y: np.ndarray
    groups: np.ndarray
    kind: str
    context: dict
    clean: dict
    fitted: dict
    feats: dict
    whole: dict
    folds: list
    chance: float
    seed: int
    trials: dict
    default_trials: int
    n_bootstrap: int
    progress: bool
    runner: Any


def _skip_reason(f: Degradation, s: _SweepState) -> str | None:
    """Why factor ``f`` does not apply to the sweep's data at all, or ``None``."""
    missing = [k for k in f.needs if k not in s.context]
    if missing:
        return f"needs {f.needs_words or ', '.join(missing)}, which these data do not give"
    if s.kind not in f.kinds or (f.ndim is not None and s.X.ndim != f.ndim):
        return f"does not apply to X of shape {tuple(s.X.shape)}"
    return None


def _applicable_models(f: Degradation, levels: tuple, s: _SweepState, result: SweepResult) -> list[str]:
    """The models factor ``f`` can degrade; each other one is listed in ``result.skipped`` with why."""
    from ..model_selection import Models
    from . import _evaluation

    names = list(s.base.names)
    if f.stage == "parameter":  # a model without the parameter is not swept (not broken)
        probe = Models(s.models, f.apply(s.context, levels[0]))
        result.skipped += [(f"{f.name} for {m}", why) for m, why in probe.errors.items()]
        names = [m for m in names if m not in probe.errors]
    elif f.stage == "features":  # noise on feature rows: not for a classifier of the raw input
        shapes = _evaluation.takes_feature_rows(s.base, s.fitted, s.feats)
        for m in [m for m in names if len(shapes[m]) != 2]:
            result.skipped.append(
                (
                    f"{f.name} for {m}",
                    f"does not apply: the model classifies the raw input {shapes[m][1:]} itself, it has no "
                    "feature vector (noise on its raw input: the sensor-noise and image-noise factors)",
                )
            )
        names = [m for m in names if len(shapes[m]) == 2]
    return names


def _sweep_factor(f: Degradation, s: _SweepState, result: SweepResult) -> None:
    """Sweep one factor over the models it applies to; append the curves (or why not) to ``result``."""
    from tqdm.auto import tqdm

    from . import _evaluation

    why = _skip_reason(f, s)
    if why is not None:
        result.skipped.append((f.name, why))
        return
    if f.stage == "time":
        drift = _evaluation.drift_rows(
            f, s.base, s.X, s.y, s.context, s.whole, DRIFT_TRAIN_SHARE, DRIFT_SEGMENTS, backend=s.runner
        )
        if drift is None:
            result.skipped.append((f.name, "recordings too short: fewer than two test segments hold samples"))
            return
        rows, levels, group_of = drift
    else:
        levels = _allowed_levels(f, s.X, s.y, s.folds)
        if not levels:
            result.skipped.append((f.name, f"no level applies to X of shape {tuple(s.X.shape)}"))
            return
        names = _applicable_models(f, levels, s, result)
        rows = {m: [s.clean[m]] for m in names}
        bar = tqdm(total=len(levels), desc=f.name, disable=not s.progress or not names, leave=False)
        for level in levels if names else ():
            n = s.trials.get(f.name, s.default_trials)
            got = _evaluation.evaluate(f, level, s, n, names)
            for m in rows:
                if not isinstance(rows[m][-1], str):
                    rows[m].append(got[m])
            bar.update()
        bar.close()
        group_of = s.groups
    for m in rows:
        fields = _evaluation.build_curve(f, m, levels, rows[m], group_of, s.chance, s.n_bootstrap, s.seed)
        result.curves.append(Curve(**{**fields, "breaking": BreakingPoint(*fields["breaking"])}))


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
