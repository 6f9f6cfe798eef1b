"""The evaluation engine behind :func:`tactile_torch.robustness.sweep` (internal).

Models are split into a shared ``features`` step and a per-model rest, so that models with the same
features step (same class and parameters) share its fits and transforms; a step that does not require
fitting is applied to the whole set once per data variant. Every evaluation pools one prediction per
test sample; correct predictions are summed per group for the cluster bootstrap of the intervals.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from sklearn.base import clone
from sklearn.model_selection import StratifiedGroupKFold
from sklearn.pipeline import Pipeline

Folds = list[tuple[np.ndarray, np.ndarray]]


def seed_of(base: int, *parts: object) -> int:
    """A 62-bit seed from ``base`` and the reprs of ``parts`` (stable across runs and platforms)."""
    words = [base] + [zlib.crc32(repr(p).encode()) for p in parts]
    return int(np.random.SeedSequence(words).generate_state(1, np.uint64)[0] >> np.uint64(2))


def take(X: Any, idx: np.ndarray) -> Any:
    """Rows ``idx`` of a tensor or an array."""
    return X[torch.from_numpy(idx)] if isinstance(X, torch.Tensor) else X[idx]


def apply_raw(apply: Any, X: Any, level: Any, seed: int) -> Any:
    """``apply(x, level, seed)`` on the raw input as a tensor, in chunks of samples (bounded memory,
    each chunk seeded from ``seed`` and its offset), returned in the type of ``X``."""
    x = X if isinstance(X, torch.Tensor) else torch.from_numpy(np.asarray(X))
    per = max(1, (1 << 24) // max(1, x[0].numel()))
    out = torch.cat([apply(x[i : i + per], level, seed + i) for i in range(0, x.shape[0], per)])
    return out if isinstance(X, torch.Tensor) else out.numpy()


def make_folds(y: np.ndarray, groups: np.ndarray, n_splits: int, seed: int) -> Folds:
    """Stratified grouped folds (every group in one fold), at most as many as the rarest class has groups."""
    classes = np.unique(y)
    per_class = [len(np.unique(groups[y == c])) for c in classes]
    n = min(n_splits, min(per_class))
    if n < 2:
        worst = classes[int(np.argmin(per_class))]
        raise ValueError(
            f"groups must give every class at least 2 groups for grouped folds, class {worst!r} has "
            f"{min(per_class)} (cut long recordings into time blocks with recording_blocks)"
        )
    cv = StratifiedGroupKFold(n_splits=n, shuffle=True, random_state=seed % (2**31))
    return [(np.sort(tr), np.sort(te)) for tr, te in cv.split(np.zeros(len(y)), y, groups)]


def stateless(step: Any) -> bool:
    """Whether a transformer needs no fit (scikit-learn's ``requires_fit`` tag is False)."""
    from sklearn.utils import get_tags

    if step is None:
        return True
    try:
        return get_tags(step).requires_fit is False
    except (AttributeError, TypeError, ValueError):
        return False


def with_params(step: Any, params: Mapping[str, Any]) -> Any:
    """A clone of ``step`` with ``params`` set (into ``kw_args`` for a ``FunctionTransformer`` whose
    function takes them)."""
    import inspect

    from sklearn.preprocessing import FunctionTransformer

    step = clone(step)
    names = step.get_params(deep=False)
    if all(k in names for k in params):
        return step.set_params(**params)
    if isinstance(step, FunctionTransformer) and step.func is not None:
        try:
            accepted = inspect.signature(step.func).parameters
        except (TypeError, ValueError):  # a builtin without a signature
            accepted = {}
        takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepted.values())
        if takes_any or all(k in accepted for k in params):
            return step.set_params(kw_args={**(step.kw_args or {}), **params})
    raise ValueError(f"the features step {type(step).__name__} has no parameter(s) {sorted(params)}")


def last_input(rest: Any, Z: Any) -> tuple[Any, Any]:
    """``(input of the last step, last step)`` of a fitted model rest on features ``Z``."""
    if isinstance(rest, Pipeline):
        return (rest[:-1].transform(Z) if len(rest.steps) > 1 else Z), rest.steps[-1][1]
    return Z, rest


def signature(step: Any) -> str:
    """A key equal for feature steps of one class with equal parameters (which fit and transform alike);
    a parameter that cannot be pickled (a lambda) counts by identity."""
    import pickle

    import joblib

    params = step.get_params(deep=True)
    try:
        return joblib.hash((type(step), params))
    except (pickle.PicklingError, TypeError, AttributeError):
        safe = {}
        for name, value in params.items():
            try:
                pickle.dumps(value)
                safe[name] = value
            except (pickle.PicklingError, TypeError, AttributeError):
                safe[name] = ("unpicklable", id(value))
        return joblib.hash((type(step), safe))


class Models:
    """Models split into shared ``features`` steps (by signature) and per-model rests."""

    def __init__(self, models: Mapping[str, Any], params: Mapping[str, Any] | None = None) -> None:
        self.models = dict(models)
        self.names = list(models)
        self.steps: dict[str, Any] = {}
        self.signature: dict[str, str] = {}
        self.rest: dict[str, Any] = {}
        self.errors: dict[str, str] = {}
        for name, model in models.items():
            step, rest = None, model
            if isinstance(model, Pipeline) and model.steps[0][0] == "features" and len(model.steps) > 1:
                step, rest = model.steps[0][1], model[1:]
            if step is not None and params:
                try:
                    step = with_params(step, params)
                except ValueError as err:
                    self.errors[name] = str(err)
                    continue
            key = "identity" if step is None else signature(step)
            self.steps.setdefault(key, step)
            self.signature[name] = key
            self.rest[name] = rest

    def features(self, X: Any, y: np.ndarray, folds: Folds, clean: dict | None = None) -> dict:
        """Per signature: a list over folds of ``(fitted step, Z_train, Z_test)``, or the error.

        ``clean`` holds the whole-set features of stateless steps on the same ``X`` (reused)."""
        out: dict[str, Any] = {}
        for key, step in self.steps.items():
            try:
                if step is None:
                    out[key] = [(None, take(X, tr), take(X, te)) for tr, te in folds]
                elif stateless(step):
                    Z = clean[key] if clean and key in clean else clone(step).fit(X, y).transform(X)
                    out[key] = [(step, take(Z, tr), take(Z, te)) for tr, te in folds]
                else:
                    per_fold = []
                    for tr, te in folds:
                        fitted = clone(step)
                        Z_tr = fitted.fit_transform(take(X, tr), y[tr])
                        per_fold.append((fitted, Z_tr, fitted.transform(take(X, te))))
                    out[key] = per_fold
            except Exception as err:  # as in fit_predict: a degraded input may break the features step
                out[key] = err
        return out

    def whole(self, X: Any, y: np.ndarray) -> dict:
        """Whole-set features of the stateless steps (to pass as ``clean`` to :meth:`features`)."""
        return {
            key: (X if step is None else clone(step).fit(X, y).transform(X))
            for key, step in self.steps.items()
            if stateless(step)
        }

    def transform(self, key: str, fitted: Any, X: Any) -> Any:
        step = self.steps[key]
        if step is None:
            return X
        return (clone(step).fit(X[:1]) if stateless(step) else fitted).transform(X)


def fit_predict(models: Models, X: Any, y: np.ndarray, folds: Folds, clean: dict | None = None):
    """Fit every model on each fold's training part of ``X`` and test on its test part.

    Returns ``(correct, fitted, feats)``: per model an array ``(N,)`` of 1/0 (NaN where untested) or
    the error message of a failed fit; per model the fitted rests by fold; the features by signature.
    """
    feats = models.features(X, y, folds, clean)
    correct: dict[str, Any] = dict(models.errors)
    fitted: dict[str, list] = {}
    for m in models.rest:
        per = feats[models.signature[m]]
        if isinstance(per, Exception):
            correct[m] = f"features: {per}"
            continue
        hits = np.full(len(y), np.nan)
        fitted[m] = []
        try:
            for (tr, te), (_, Z_tr, Z_te) in zip(folds, per, strict=True):
                rest = clone(models.rest[m]).fit(Z_tr, y[tr])
                fitted[m].append(rest)
                hits[te] = rest.predict(Z_te) == y[te]
        except Exception as err:  # a degraded input may break any estimator in any way: record it
            correct[m] = f"{type(err).__name__}: {err}"
            continue
        correct[m] = hits
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


def evaluate(f, level, base, fitted, feats, whole, X, y, folds, context, n_trials, seed) -> dict:
    """Per model: correct (1/0) per sample at one level of ``f``, averaged over trials, or an error."""
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
            for m in base.names:
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
            for m, value in fit_predict(base, X, y, subsets, whole)[0].items():
                add(m, value)
        elif f.stage == "retrain":
            Xd = apply_raw(f.apply, X, level, trial_seed)
            for m, value in fit_predict(base, Xd, y, folds)[0].items():
                add(m, value)
        elif f.stage == "parameter":
            models = Models(base.models, f.apply(context, level))
            for m, value in fit_predict(models, X, y, folds)[0].items():
                add(m, value)
        else:
            raise ValueError(f"stage {f.stage!r} is not one that evaluate handles")
    return total


def drift_rows(
    f, base: Models, X: Any, y: np.ndarray, context: Mapping, whole: dict, share: float, segments: int
):
    """Rows of the drift factor: train on ``position < share`` of every recording, test on the rest cut
    into ``segments`` equal segments (row 0: the first segment with windows, the clean reference).

    Returns ``(rows per model, levels = centres of the later segments, recording of each sample)``, or
    ``None`` when fewer than two segments hold windows; a model that cannot be fitted has the error
    message as its only row."""
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
    train, test = np.flatnonzero(position < share), np.flatnonzero(position >= share)
    segment = np.minimum(((position[test] - share) / (1.0 - share) * segments).astype(int), segments - 1)
    present = [j for j in range(segments) if (segment == j).any()]  # short recordings leave gaps
    if len(present) < 2 or not len(train):
        return None
    correct = fit_predict(base, X, y, [(train, test)], whole)[0]
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


def build_curve(
    f, model: str, levels: tuple, rows: list, groups: np.ndarray, chance: float, n_bootstrap: int, seed: int
):
    """The :class:`~tactile_torch.robustness.Curve` of one model from its per-sample rows."""
    from .robustness import BreakingPoint, Curve

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
        bounds = [level_text(f, path_levels, p) for p in (lo_pos, hi_pos)]
        if bounds[0][1] is not None and bounds[1][1] is not None and bounds[0][1] > bounds[1][1]:
            bounds.reverse()  # levels that fall as they get harsher (dB, frames): show low, high
        text += f" [{bounds[0][0]}, {bounds[1][0]}]"
    elif failed is not None:  # never below halfway while it could be fitted: broken where it cannot
        position = lo_pos = hi_pos = float(len(path_levels) + 1)
        status, text = "fit failed", f"{f.label(failed)} (cannot be fitted there)"
        value = float(failed) if isinstance(failed, int | float) else None
    else:
        status, text = "not reached", f"not reached by {f.label(path_levels[-1])}"
        if math.isfinite(lo_pos):
            text += f" [{level_text(f, path_levels, lo_pos)[0]}, beyond]"
    return Curve(
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
        breaking=BreakingPoint(status, position, lo_pos, hi_pos, float(threshold), text, value),
        note=note,
    )
