"""How long must the hand hold before it knows: accuracy against time into the touch, and the early rule.

For frame data (explorations of ``T`` frames: RGB images or pressure maps) every held-out exploration is
a touch. Each fold's model (fitted without it) classifies the touch's first ``k`` frames at the
checkpoints of :func:`tactile_torch.robot.stream.early_decision.checkpoints_for` (in ``quick`` runs the
quarters), brought to ``T`` frames exactly as the live stream brings them
(:func:`tactile_torch.robot.stream.touches.fit_frames`), and the whole touch (the study's out-of-fold
prediction). Per checkpoint the accuracy is summarised over the data's units with the study's
interval (:func:`~.selection.unit_interval`: the 95 % prediction interval for a new unit, or the range
over fewer than 5 units): :func:`accuracy_vs_time`, for the recommended candidate and the runner-up.

The same held-out scores calibrate the deployed bundle's early-decision rule
(:func:`tactile_torch.robot.stream.early_decision.calibrate_early_rule`): the score margin of each touch at each
checkpoint, and whether its label was right. The scores are the ones the exported graph gives
(the candidate's features, then its head's torch inference modules: what the ONNX file computes).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..robot.stream.early_decision import (
    DEFAULT_ERROR,
    EarlyRule,
    checkpoints_for,
    held_out_rule,
    score_margins,
)
from ..robot.stream.touches import fit_frames

QUICK_SHARES = (0.25, 0.5, 0.75)
"""Checkpoints of a ``quick`` study, as shares of ``T`` (the full rule's seven in a full study)."""


@dataclass
class TouchTime:
    """Held-out accuracy of one candidate against the frames of the touch it has seen.

    Attributes
    ----------
    name : str
        The candidate.
    frames : list of int
        Frames into the touch of each column: the checkpoints, then ``T``.
    seconds : list of float
        The same in seconds at the data's frame rate.
    rows : list of dict
        Per column: ``frames``, ``seconds``, ``accuracy`` (mean over units), ``accuracy_low``,
        ``accuracy_high``, ``interval`` (``"prediction"`` or ``"range"``), ``unit``, ``n_units``.
    margins, correct : ndarray of shape (N, K)
        At the checkpoints (not ``T``): each held-out touch's score margin and whether its label was right.
    rule : EarlyRule or None
        The early rule these touches calibrate (:func:`calibrate_early_rule` at ``target_error``).
    """

    name: str
    frames: list[int]
    seconds: list[float]
    rows: list[dict]
    margins: np.ndarray = field(repr=False)
    correct: np.ndarray = field(repr=False)
    rule: EarlyRule | None = None

    def to_json(self) -> dict:
        """What ``tradeoff.json`` keeps (``accuracy_vs_time``)."""
        return {
            "name": self.name,
            "rows": self.rows,
            "early_rule": None if self.rule is None else self.rule.to_metadata(),
        }


def fold_scores(
    model: object, X: np.ndarray, features: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(labels, scores)`` of a fitted candidate on raw input ``X`` as its exported graph gives them.

    ``labels`` index the classifier's ``classes_`` (as the bundle's ``class_names``); ``scores`` ``(N, C)``.
    ``features``: the ``features`` step's output for ``X`` when already known (a classical candidate).
    """
    import torch
    from torch import nn

    from ..export.parts import head_modules
    from .candidates import is_learned

    with torch.no_grad():
        if is_learned(model):
            module = model.steps[-1][1].to_module().eval()
            x = np.ascontiguousarray(X)
            out = module(torch.from_numpy(x if x.dtype == np.uint8 else x.astype(np.float32)))
        else:
            z = model.named_steps["features"].transform(X) if features is None else features
            head = nn.Sequential(*head_modules(model)).eval()
            out = head(torch.from_numpy(np.ascontiguousarray(z, dtype=np.float32)))
    return np.asarray(out[0].numpy(), dtype=np.int64), np.asarray(out[1].numpy(), dtype=np.float64)


def _classes(model: object) -> np.ndarray:
    return np.asarray(model.steps[-1][1].classes_)


def prefixes(X: np.ndarray, frames: int, step: object = None) -> np.ndarray:
    """Return each exploration's first ``frames`` frames brought to its ``T`` frames as the stream brings them.

    For a fused features step (``step.fuse``: the OR of every frame's edges) the ``frames`` themselves
    are returned: each is repeated in the stretched touch, and the OR of repeated frames is the OR of
    the frames, so its features are the same at a fraction of the cost.
    """
    if getattr(step, "fuse", False):
        return X[:, :frames]
    t = X.shape[1]
    return np.stack([fit_frames(x[:frames], t) for x in X])


def touch_time(
    result: object,
    samples: object,
    rate_hz: float,
    *,
    quick: bool,
    target_error: float = DEFAULT_ERROR,
    cache: dict | None = None,
) -> TouchTime:
    """Return the :class:`TouchTime` of one candidate result (its fold models, kept by the study).

    ``samples``: the candidate's raw input (explorations ``(N, T, ...)`` with folds and units).
    ``cache``: features of prefixes by (features step, frames), shared between candidates whose
    ``features`` step needs no fit.
    """
    from ..model_selection import needs_fit
    from .candidates import features_key, is_learned
    from .selection import unit_accuracy, unit_interval

    cv = result.cv
    X, y = samples.X, samples.y
    t = X.shape[1]
    checkpoints = (
        tuple(sorted({max(1, round(s * t)) for s in QUICK_SHARES} - {t})) if quick else checkpoints_for(t)
    )
    cache = {} if cache is None else cache
    learned = is_learned(result.candidate.estimator)
    shared = not learned and not needs_fit(result.candidate.estimator.steps[0][1])

    def classify(fold: int, j: int, test: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        model, frames = cv.models[fold], checkpoints[j]
        fitted = model.steps[0][1]
        if shared:  # one transform of every exploration's prefix, for every fold and candidate
            key = (features_key(result.candidate), frames)
            if key not in cache:
                cache[key] = fitted.transform(prefixes(X, frames, fitted))
            labels, scores = fold_scores(model, None, cache[key][test])
        else:
            labels, scores = fold_scores(model, prefixes(X[test], frames, None if learned else fitted))
        return _classes(model)[labels], score_margins(scores, labels)

    n_tested = len(np.unique(np.concatenate([test for _, test in samples.folds])))
    at_checkpoints, margins, rule = held_out_rule(
        y,
        samples.folds,
        checkpoints,
        classify,
        target_error=target_error,
        how=f"{n_tested} held-out explorations of {t} frames ({result.candidate.name}, fold models)",
    )
    predicted = np.column_stack(
        [at_checkpoints, cv.predictions]
    )  # the whole touch: the study's own predictions
    correct = at_checkpoints == y[:, None]
    rows = []
    seconds = [f / rate_hz for f in (*checkpoints, t)]
    for j, frames in enumerate((*checkpoints, t)):
        ids, right, count = unit_accuracy(y, predicted[:, j], samples.units)
        u = unit_interval(right, count, units=ids)
        rows.append(
            {
                "frames": int(frames),
                "seconds": round(seconds[j], 6),
                "accuracy": u.mean,
                "accuracy_low": u.low,
                "accuracy_high": u.high,
                "interval": u.kind,
                "unit": samples.unit,
                "n_units": u.n,
            }
        )
    return TouchTime(result.candidate.name, [*checkpoints, t], seconds, rows, margins, correct, rule)


def accuracy_vs_time(study: object, *, quick: bool, log=print) -> dict[str, TouchTime]:
    """Return the :class:`TouchTime` of the recommended candidate and the runner-up of a frame-data study.

    ``{}`` for vibration and feature data, or when no candidate was recommended. A candidate whose
    fold models fail on prefixes is left out with a note in the study's notes.
    """
    if study.data.kind not in ("image", "pressure"):
        return {}
    out, cache = {}, {}
    for name in (study.recommended, study.runner_up):
        if name is None or name in out:
            continue
        res = study.result(name)
        if res.cv is None or not res.cv.models:
            continue
        try:
            out[name] = touch_time(
                res, study.inputs[res.candidate.input], study.data.rate_hz, quick=quick, cache=cache
            )
        except Exception as err:  # a late stage never throws away what the study computed
            study.notes.append(
                f"accuracy against time into the touch of {name}: failed ({type(err).__name__}: {err})"
            )
    if out:
        log(f"[tradeoff] accuracy against time into the touch: {', '.join(out)}")
    return out


def draw_touch_time(curves: dict[str, TouchTime], path: str | Path, *, chance: float | None = None) -> Path:
    """Draw accuracy (with its interval) against seconds into the touch, one line per candidate; return ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    handles = []
    for i, (name, curve) in enumerate(curves.items()):
        x = np.array(curve.seconds)  # at the measured time: the runner-up's interval is a band, not bars
        acc = np.array([r["accuracy"] for r in curve.rows])
        low = np.array([r["accuracy_low"] for r in curve.rows])
        high = np.array([r["accuracy_high"] for r in curve.rows])
        colour = ("tab:blue", "tab:orange")[i % 2]
        role = ("recommended", "runner-up")[i % 2]
        if i % 2 == 0:
            ax.errorbar(x, acc, yerr=[acc - low, high - acc], fmt="o-", color=colour, capsize=3, lw=1.4, ms=5)
        else:
            ax.fill_between(x, low, high, color=colour, alpha=0.18, lw=0)
            ax.plot(x, acc, "s--", color=colour, lw=1.4, ms=5)
        handles.append(
            Line2D([], [], color=colour, marker="o" if i % 2 == 0 else "s", ls="-" if i % 2 == 0 else "--",
                   label=f"{role}: {name}" + ("" if i % 2 == 0 else " (band: its interval)"))
        )  # fmt: skip
        rule = curve.rule
        if rule is not None and rule.active and rule.median_frames is not None and i == 0:
            at = rule.median_frames / curve.frames[-1] * curve.seconds[-1]
            ax.axvline(at, color=colour, ls=":", lw=1.2)
            handles.append(
                Line2D(
                    [],
                    [],
                    color=colour,
                    ls=":",
                    label=f"its early decisions: median {at:.2g} s into the touch ({rule.decided} of "
                    f"{rule.touches} touches early, {rule.error:.0%} wrong; target {rule.target_error:.0%})",
                )
            )
    if chance is not None:
        ax.axhline(chance, ls="--", color="0.45", lw=1)
        handles.append(Line2D([], [], ls="--", color="0.45", label=f"chance {chance:.2f}"))
    first = next(iter(curves.values())).rows[0]
    what = "95 % interval" if first["interval"] == "prediction" else f"range over {first['n_units']}"
    ax.set_xlabel("time into the touch (s): frames seen / frame rate")
    ax.set_ylabel(f"accuracy (mean over {first['unit']}s, {what})")
    ax.set_ylim(0.0, 1.02)
    ax.set_xlim(0.0, None)
    ax.grid(alpha=0.3)
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.16), frameon=False)
    ax.set_title("How long must the hand hold before it knows? (held-out touches)", fontsize=9.5, loc="left")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def touch_time_markdown(curves: dict[str, TouchTime], figure: str | None = None) -> list[str]:
    """The ``tradeoff.md`` section: one table per candidate and the chart."""
    if not curves:
        return []
    lines = ["## Accuracy against time into the touch", ""]
    lines += [
        "Every held-out exploration is a touch; its first k frames, brought to the bundle's frames as the live "
        "stream brings them (each repeated evenly), are classified by the fold's model. Accuracy: mean over the "
        "units, with the 95 % prediction interval for a new unit (the range under 5 units).",
        "",
    ]
    for name, curve in curves.items():
        lines += [
            f"**{name}**",
            "",
            "| frames | s into the touch | accuracy | interval |",
            "|---|---|---|---|",
        ]
        for r in curve.rows:
            kind = "95 %" if r["interval"] == "prediction" else "range"
            lines.append(
                f"| {r['frames']} | {r['seconds']:.3g} | {r['accuracy']:.3f} | {kind} [{r['accuracy_low']:.3f}, "
                f"{r['accuracy_high']:.3f}] per {r['unit']} |"
            )
        if curve.rule is not None:
            lines += ["", f"Early-decision rule (calibrated on these touches): {curve.rule.describe()}."]
        lines.append("")
    if figure:
        lines += [f"![accuracy against time into the touch]({figure})", ""]
    return lines


__all__ = [
    "QUICK_SHARES",
    "TouchTime",
    "accuracy_vs_time",
    "draw_touch_time",
    "fold_scores",
    "prefixes",
    "touch_time",
    "touch_time_markdown",
]
