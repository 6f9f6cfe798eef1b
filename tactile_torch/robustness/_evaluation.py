"""The degradations, curves and bootstrap behind :func:`tactile_torch.robustness.sweeps.sweep` (internal).

Built on the evaluation engine (:mod:`tactile_torch.model_selection`): models are split into shared ``features``
steps and per-model rests, so that models with the same features step share its fits and transforms, and
a step that needs no fit is applied to the whole set once per data variant. Every evaluation pools one
prediction per test sample; correct predictions are summed per group for the cluster bootstrap of the
intervals. This module imports nothing else of :mod:`tactile_torch.robustness` (whose sweeps sit above it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch

from ..model_selection import Folds, Models, cross_validate, last_input, seed_of, take


def apply_raw(apply: Any, X: Any, level: Any, seed: int) -> Any:
    """``apply(x, level, seed)`` on the raw input as a tensor, in chunks of samples (bounded memory,
    each chunk seeded from ``seed`` and its offset), returned in the type of ``X``."""
    x = X if isinstance(X, torch.Tensor) else torch.from_numpy(np.asarray(X))
    per = max(1, (1 << 24) // max(1, x[0].numel()))
    out = torch.cat([apply(x[i : i + per], level, seed + i) for i in range(0, x.shape[0], per)])
    return out if isinstance(X, torch.Tensor) else out.numpy()


def fit_predict(models: Models, X: Any, y: np.ndarray, folds: Folds, clean: dict | None = None, backend=None):
    """Fit every model on each fold's training part of ``X`` and test on its test part (the engine's
    :func:`~tactile_torch.model_selection.cross_validate`, untuned).

    Returns ``(correct, fitted, feats)``: per model an array ``(N,)`` of 1/0 (NaN where untested) or
    the error message of a failed fit; per model the fitted rests by fold; the features by signature.
    ``clean`` holds the whole-set features of the steps that need no fit on the same ``X`` (reused).
    """
    feats: dict[str, Any] = {}
    cache = {key: (Z, 0.0) for key, Z in (clean or {}).items()}
    results = cross_validate(
        models, X, y, folds, cache=cache, keep_models=True, backend=backend, features_out=feats
    )
    correct: dict[str, Any] = {}
    fitted: dict[str, list] = {}
    for m, res in results.items():
        if res.error is not None:
            correct[m] = res.error
            continue
        hits = np.full(len(y), np.nan)
        tested = res.fold >= 0
        hits[tested] = res.predictions[tested] == y[tested]
        correct[m] = hits
        identity = models.signature[m] == "identity"
        fitted[m] = [model if identity else model[1:] for model in res.models]
    return correct, fitted, feats


def bootstrap(hits: np.ndarray, count: np.ndarray, n_bootstrap: int, seed: int) -> np.ndarray:
    """Accuracy rows of cluster-bootstrap replicates: ``hits``/``count`` ``(rows, groups)`` →
    ``(rows, n_bootstrap)`` (groups drawn with replacement, the same draw for every row)."""
    rng = np.random.default_rng(seed)
    n_groups = hits.shape[1]
    weights = rng.multinomial(n_groups, np.full(n_groups, 1.0 / n_groups), size=n_bootstrap).T
    with np.errstate(invalid="ignore", divide="ignore"):
        return (hits @ weights) / (count @ weights)


def crossing(acc: np.ndarray, chance: float) -> np.ndarray:
    """Breaking positions of accuracy paths ``acc`` ``(1 + P, B)`` (row 0 clean): the first position
    at or below ``chance + (clean - chance) / 2``, interpolated; ``inf`` if never, ``0`` if the clean
    accuracy is not above chance."""
    clean = acc[0]
    threshold = chance + (clean - chance) / 2.0
    below = acc[1:] <= threshold
    first = np.argmax(below, axis=0) + 1
    cols = np.arange(acc.shape[1])
    prev, cur = acc[first - 1, cols], acc[first, cols]
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(prev > cur, (prev - threshold) / (prev - cur), 1.0)
    pos = np.where(below.any(axis=0), first - 1 + np.clip(frac, 0.0, 1.0), math.inf)
    return np.where(clean > chance, pos, 0.0)


def takes_feature_rows(base: Models, fitted: dict, feats: dict) -> dict[str, tuple]:
    """Per model: the shape of the input its last step (the classifier) takes on the first fold's test part.

    A ``"features"``-stage factor (noise on the classifier's input at an SNR per row) applies to models
    whose classifier takes feature rows ``(N, F)``; a network on the raw input (windows, frames, maps)
    takes ``(N, 3, W)``, ``(N, T, 3, H, W)`` ... and has no feature vector to degrade."""
    shapes = {}
    for m in base.names:
        if m not in fitted:
            continue
        Z, _ = last_input(fitted[m][0], feats[base.signature[m]][0][2])
        shapes[m] = tuple(np.shape(Z))
    return shapes


def evaluate(f, level, state, n_trials: int, names=None) -> dict:
    """Per model: correct (1/0) per sample at one level of ``f``, averaged over trials, or an error.

    ``state``: the sweep's shared state (models ``base``, their clean ``fitted`` folds and ``feats``,
    ``whole``, ``X``, ``y``, ``folds``, ``context``, ``seed``, the backend ``runner``). ``names``: the
    models to evaluate (default: every model of ``base``)."""
    base, fitted, feats, whole = state.base, state.fitted, state.feats, state.whole
    X, y, folds, context = state.X, state.y, state.folds, state.context
    seed, backend = state.seed, state.runner
    names = base.names if names is None else list(names)
    trials = n_trials if f.random else 1
    total: dict[str, Any] = {}

    def add(m: str, value: Any) -> None:
        if isinstance(value, str) or isinstance(total.get(m), str):
            total[m] = value if isinstance(value, str) else total[m]
        else:
            total[m] = total.get(m, 0.0) + value / trials

    for trial in range(trials):
        trial_seed = seed_of(seed, f.name, level, trial)
        if f.stage == "features":
            for m in names:
                hits = np.full(len(y), np.nan)
                for k, (_, te) in enumerate(folds):
                    Z, last = last_input(fitted[m][k], feats[base.signature[m]][k][2])
                    noisy = f.apply(torch.as_tensor(np.asarray(Z, dtype=np.float64)), level, trial_seed + k)
                    hits[te] = last.predict(noisy.numpy()) == y[te]
                add(m, hits)
        elif f.stage == "test":
            Xd = apply_raw(f.apply, X, level, trial_seed)
            for key in base.steps:
                users = [m for m in base.names if base.signature[m] == key]
                Z_all = base.transform(key, None, Xd) if key in whole else None
                hits = {m: np.full(len(y), np.nan) for m in users}
                for k, (_, te) in enumerate(folds):
                    Z_te = take(Z_all, te) if Z_all is not None else feats[key][k][0].transform(take(Xd, te))
                    for m in users:
                        hits[m][te] = fitted[m][k].predict(Z_te) == y[te]
                for m in users:
                    add(m, hits[m])
        elif f.stage == "train":
            rng = np.random.default_rng(trial_seed)
            subsets = [(tr[f.apply(y[tr], level, rng)], te) for tr, te in folds]
            for m, value in fit_predict(base, X, y, subsets, whole, backend)[0].items():
                add(m, value)
        elif f.stage == "retrain":
            Xd = apply_raw(f.apply, X, level, trial_seed)
            for m, value in fit_predict(base, Xd, y, folds, backend=backend)[0].items():
                add(m, value)
        elif f.stage == "parameter":
            models = Models(base.models, f.apply(context, level))
            for m, value in fit_predict(models, X, y, folds, backend=backend)[0].items():
                add(m, value)
        else:
            raise ValueError(f"stage {f.stage!r} is not one that evaluate handles")
    return total


def check_drift_context(context: Mapping, y: np.ndarray) -> None:
    """Raise ``ValueError`` unless the context's ``position`` and ``recording`` (when given) fit ``y``."""
    if "position" not in context or "recording" not in context:
        return
    position = np.asarray(context["position"], dtype=np.float64)
    recording = np.asarray(context["recording"])
    if position.shape != y.shape or recording.shape != y.shape:
        raise ValueError(
            f"context position and recording must have shape {y.shape} (one per sample), got "
            f"{position.shape} and {recording.shape}"
        )
    if position.min() < 0.0 or position.max() >= 1.0:
        raise ValueError(
            f"context position must be the fraction of the recording in [0, 1), got {position.min()}..{position.max()}"
        )


def drift_rows(
    f,
    base: Models,
    X: Any,
    y: np.ndarray,
    context: Mapping,
    whole: dict,
    share: float,
    segments: int,
    backend=None,
):
    """Rows of the drift factor: train on ``position < share`` of every recording, test on the rest cut
    into ``segments`` equal segments (row 0: the first segment with windows, the clean reference).

    Returns ``(rows per model, levels = centres of the later segments, recording of each sample)``, or
    ``None`` when fewer than two segments hold windows; a model that cannot be fitted has the error
    message as its only row."""
    check_drift_context(context, y)
    position = np.asarray(context["position"], dtype=np.float64)
    recording = np.asarray(context["recording"])
    train, test = np.flatnonzero(position < share), np.flatnonzero(position >= share)
    segment = np.minimum(((position[test] - share) / (1.0 - share) * segments).astype(int), segments - 1)
    present = [j for j in range(segments) if (segment == j).any()]  # short recordings leave gaps
    if len(present) < 2 or not len(train):
        return None
    correct = fit_predict(base, X, y, [(train, test)], whole, backend)[0]
    rows: dict[str, list] = {}
    for m in base.names:
        if isinstance(correct[m], str):
            rows[m] = [correct[m]]
            continue
        rows[m] = []
        for j in present:
            row = np.full(len(y), np.nan)
            at = test[segment == j]
            row[at] = correct[m][at]
            rows[m].append(row)
    centres = [round(share + (j + 0.5) * (1.0 - share) / segments, 2) for j in present]
    return rows, tuple(centres[1:]), recording


def level_text(f, levels: list, position: float) -> tuple[str, float | None]:
    """A breaking position along ``levels`` as text in the factor's unit, and as a number if it is one."""
    if math.isinf(position):
        return f"beyond {f.label(levels[-1])}", None
    if position <= 0.0:
        return "the clean input", None
    if position < 1.0:
        return f"before {f.label(levels[0])}", None
    k = math.floor(position)
    frac = position - k
    a = levels[k - 1]
    numeric = isinstance(a, int | float)
    if frac == 0.0 or k >= len(levels):
        return f.label(a), float(a) if numeric else None
    b = levels[k]
    if not numeric:
        return f"between {f.label(a)} and {f.label(b)}", None
    if f.log_x and a > 0 and b > 0:
        value = a * (b / a) ** frac
    else:
        value = a + frac * (b - a)
    return f.label(value), float(value)


def _numeric(levels: list) -> bool:
    return bool(levels) and all(isinstance(v, int | float) for v in levels)


def bound_text(f, levels: list, position: float) -> tuple[str, float]:
    """One end of a breaking point's interval: its text and a key that orders it with the other end by
    value (``-inf``/``inf`` for an end outside the sweep: below or above every level swept, in words)."""
    text, value = level_text(f, levels, position)
    if value is not None:
        return text, value
    if not _numeric(levels):
        return text, position
    falling = len(levels) > 1 and levels[-1] < levels[0]  # harsher levels are lower numbers (dB, frames)
    if math.isinf(position):  # past the harshest level swept
        edge = f.label(levels[-1])
        return (
            (f"< {edge} (beyond the sweep)", -math.inf)
            if falling
            else (f"> {edge} (beyond the sweep)", math.inf)
        )
    edge = f.label(levels[0])  # before the mildest level swept: between the clean input and it
    return (f"> {edge}", math.inf) if falling else (f"< {edge}", -math.inf)


def interval_text(f, levels: list, low: float, high: float) -> str:
    """``[a, b]``: a breaking point's interval with its ends in numeric order (module notes)."""
    ends = sorted((bound_text(f, levels, p) for p in (low, high)), key=lambda e: e[1])
    return f"[{ends[0][0]}, {ends[1][0]}]"


def build_curve(
    f, model: str, levels: tuple, rows: list, groups: np.ndarray, chance: float, n_bootstrap: int, seed: int
):
    """The fields of one model's :class:`~tactile_torch.robustness.results.Curve` from its per-sample rows
    (``breaking``: the fields of its :class:`~tactile_torch.robustness.results.BreakingPoint` in order)."""
    note, failed = "", None
    if isinstance(rows[-1], str):
        if len(rows) == 1:
            raise ValueError(f"models[{model!r}] could not be fitted for factor {f.name!r}: {rows[-1]}")
        failed = levels[len(rows) - 2]
        note = f"cannot be fitted at {f.label(failed)} ({rows[-1][:120]})"
        rows = rows[:-1]
    levels = tuple(levels[: len(rows) - 1])
    _, g = np.unique(groups, return_inverse=True)
    hits = np.zeros((len(rows), g.max() + 1))
    count = np.zeros_like(hits)
    for r, row in enumerate(rows):
        ok = ~np.isnan(row)
        np.add.at(hits[r], g[ok], row[ok])
        np.add.at(count[r], g[ok], 1.0)
    acc = hits.sum(1) / count.sum(1)
    boot = bootstrap(hits, count, n_bootstrap, seed_of(seed, "bootstrap", f.name))
    low, high = np.nanpercentile(boot, [2.5, 97.5], axis=1)
    idx = [i for i in (f.path or range(len(levels))) if i < len(levels)]
    path = [0] + [i + 1 for i in idx]
    position = lo_pos = hi_pos = math.inf
    if len(path) > 1:  # no level left when the model could not be fitted at the first one
        position = float(crossing(acc[path][:, None], chance)[0])
        reps = crossing(boot[path], chance)
        lo_pos = float(np.percentile(reps, 2.5, method="lower"))
        hi_pos = float(np.percentile(reps, 97.5, method="higher"))
    path_levels = [levels[i] for i in idx]
    threshold = chance + (acc[0] - chance) / 2.0
    value = None
    if acc[0] <= chance:
        status, text = "at chance", "clean accuracy at chance"
    elif not path_levels and failed is None:
        status, text = "not reached", "no level evaluated"
    elif math.isfinite(position):
        status, (text, value) = "reached", level_text(f, path_levels, position)
        text += f" {interval_text(f, path_levels, lo_pos, hi_pos)}"
    elif failed is not None:  # never below halfway while it could be fitted: broken where it cannot
        position = lo_pos = hi_pos = float(len(path_levels) + 1)
        status, text = "fit failed", f"{f.label(failed)} (cannot be fitted there)"
        value = float(failed) if isinstance(failed, int | float) else None
    else:
        status, text = "not reached", f"beyond the sweep (not reached by {f.label(path_levels[-1])})"
        if math.isfinite(lo_pos):
            text += f" {interval_text(f, path_levels, lo_pos, math.inf)}"
    return dict(
        factor=f,
        model=model,
        levels=levels,
        accuracy=acc[1:],
        low=low[1:],
        high=high[1:],
        clean=float(acc[0]),
        clean_low=float(low[0]),
        clean_high=float(high[0]),
        chance=chance,
        breaking=(status, position, lo_pos, hi_pos, float(threshold), text, value),
        note=note,
    )
