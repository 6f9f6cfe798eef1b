"""Models split into shared feature steps and per-model rests, the folds, and the seeds of tasks."""

from __future__ import annotations

import inspect
import pickle
import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from sklearn.base import clone
from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold
from sklearn.pipeline import Pipeline

Folds = list[tuple[np.ndarray, np.ndarray]]


def seed_of(base: int, *parts: object) -> int:
    """Return a 62-bit seed from ``base`` and the reprs of ``parts`` (stable across runs, platforms and
    execution order: every task derives its own)."""
    words = [int(base) % (2**63)] + [zlib.crc32(repr(p).encode()) for p in parts]
    return int(np.random.SeedSequence(words).generate_state(1, np.uint64)[0] >> np.uint64(2))


def take(X: Any, idx: np.ndarray) -> Any:
    """Return rows ``idx`` of a tensor or an array."""
    return X[torch.from_numpy(np.asarray(idx))] if isinstance(X, torch.Tensor) else X[idx]


def needs_fit(step: Any) -> bool:
    """Return whether a transformer must be fitted on training data (scikit-learn's ``requires_fit``
    tag; the one protocol of the engine). ``None`` (no step) needs none."""
    from sklearn.utils import get_tags

    if step is None:
        return False
    try:
        return get_tags(step).requires_fit is not False
    except (AttributeError, TypeError, ValueError):
        return True


def make_folds(y: np.ndarray, groups: np.ndarray, n_splits: int, seed: int) -> Folds:
    """Return stratified grouped folds (every group in one fold), at most as many as the rarest class has
    groups; ``ValueError`` when a class has fewer than 2 groups."""
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


def inner_splits(y: np.ndarray, groups: np.ndarray | None, n_splits: int, seed: int) -> tuple[Folds, str]:
    """Return the inner folds of one outer training part and how they were made.

    Grouped and stratified (``StratifiedGroupKFold``) when ``groups`` gives every class at least two
    groups, stratified otherwise; ``min(n_splits, what the rarest class allows)`` folds; no fold (an
    empty list) when a class has a single sample, so that nothing can be tuned.
    """
    classes = np.unique(y)
    seed = seed % (2**31)
    if groups is not None:
        per_class = min(len(np.unique(groups[y == c])) for c in classes)
        if per_class >= 2:
            k = min(n_splits, per_class)
            cv = StratifiedGroupKFold(k, shuffle=True, random_state=seed)
            return [(np.sort(a), np.sort(b)) for a, b in cv.split(y, y, groups)], f"{k} grouped folds"
    smallest = int(min(np.sum(y == c) for c in classes))
    k = min(n_splits, smallest)
    if k < 2:
        return [], "no inner folds (a class has a single training sample)"
    cv = StratifiedKFold(k, shuffle=True, random_state=seed)
    return [(np.sort(a), np.sort(b)) for a, b in cv.split(y, y)], f"{k} stratified folds"


def with_params(step: Any, params: Mapping[str, Any]) -> Any:
    """Return a clone of ``step`` with ``params`` set (into ``kw_args`` for a ``FunctionTransformer``
    whose function takes them)."""
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
    """Return ``(input of the last step, last step)`` of a fitted model rest on features ``Z``."""
    if isinstance(rest, Pipeline):
        return (rest[:-1].transform(Z) if len(rest.steps) > 1 else Z), rest.steps[-1][1]
    return Z, rest


def signature(step: Any) -> str:
    """Return a key equal for feature steps of one class with equal parameters (which fit and transform
    alike); a parameter that cannot be pickled (a lambda) counts by identity."""
    import joblib

    params = step.get_params(deep=True)
    kind = f"{type(step).__module__}.{type(step).__qualname__}"  # a class defined in a function pickles not
    try:
        return joblib.hash((kind, params))
    except (pickle.PicklingError, TypeError, AttributeError):
        safe = {}
        for name, value in params.items():
            try:
                pickle.dumps(value)
                safe[name] = value
            except (pickle.PicklingError, TypeError, AttributeError):
                safe[name] = ("unpicklable", id(value))
        return joblib.hash((kind, safe))


class Models:
    """Models split into shared ``features`` steps (by :func:`signature`) and per-model rests.

    A model that is a ``Pipeline`` whose first step is named ``"features"`` (and has more steps) shares
    that step with every model whose step has the same class and parameters; any other model is its own
    rest on the raw input (signature ``"identity"``).

    Attributes
    ----------
    names : list of str
    steps : dict of signature to step (``None`` for the identity)
    signature : dict of model name to signature
    rest : dict of model name to the estimator after ``features``
    errors : dict of model name to message
        Models whose features step does not take ``params``.
    """

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

    def stateless(self, key: str) -> bool:
        """Whether the features step of ``key`` needs no fit (computed once on the whole set)."""
        return not needs_fit(self.steps[key])

    def whole(self, X: Any, y: np.ndarray) -> dict:
        """Return the whole-set features of the steps that need no fit, by signature."""
        return {
            key: (X if step is None else clone(step).fit(X, y).transform(X))
            for key, step in self.steps.items()
            if not needs_fit(step)
        }

    def transform(self, key: str, fitted: Any, X: Any) -> Any:
        """Return the features of ``X`` by the step of ``key`` (``fitted`` for a step that needs a fit)."""
        step = self.steps[key]
        if step is None:
            return X
        return (fitted if needs_fit(step) else clone(step).fit(X[:1])).transform(X)
