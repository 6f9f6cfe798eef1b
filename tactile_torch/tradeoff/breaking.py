"""Breaking points of the recommended and the study's model, for ``tactile-torch tradeoff``'s output.

:func:`add_breaking_points` sweeps :mod:`tactile_torch.robustness`'s factors over the two models on
the raw input they were evaluated on (the same samples and groups), writes one chart per factor under
``DIR/breaking/`` and fills :attr:`~.summary.TradeoffResult.breaking_points`, which
:func:`~.output.write_outputs` puts in ``tradeoff.json`` and ``tradeoff.md``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

QUICK_SPLITS, FULL_SPLITS = 2, 5
"""Folds of the sweeps with and without ``--quick`` (at most as many as the study's folds allow)."""
SWEEP_CLEAN = "clean accuracy [95 % CI]"
"""The column :func:`tactile_torch.robustness.output.breaking_table` names the clean accuracy."""
CLEAN_COLUMN = "clean accuracy in the sweep ({n} folds, 95 % bootstrap CI)"
"""Its name in the trade-off's table: the sweep's own cross-validation (its folds, every sample pooled,
a cluster-bootstrap interval of that mean), not the study's accuracy (mean over units, prediction
interval for a new unit), so the two differ."""


def refits(kind: str, *, quick: bool) -> int:
    """Return about how many times a sweep of one model refits it (the estimate of the time the breaking
    points take, :mod:`.progress`): per factor, every level that retrains, on every fold; one fit per fold
    for the factors that only degrade the test input."""
    from ..robustness.degradations import QUICK_LEVELS, factors_for

    splits = QUICK_SPLITS if quick else FULL_SPLITS
    total = 0
    for f in factors_for(kind):
        levels = QUICK_LEVELS.get(f.name, f.levels) if quick else f.levels
        total += splits * (1 if f.stage == "test" else len(levels))
    return total


def plausibility_notes(curves: list, X: object) -> list[str]:
    """Notes on results a reader should doubt: a degradation that improves accuracy beyond its interval,
    and a sensor range below the data's own level (gravity) that costs nothing. Each says what the sweep
    does, so that the reader can tell a property of the data from a bug."""
    import numpy as np

    notes = []
    own = None
    for c in curves:
        unit = c.factor.unit
        for level, acc, low in zip(c.levels, c.accuracy, c.low, strict=False):
            if np.isfinite(low) and low > c.clean + 1e-9:
                notes.append(
                    f"{c.factor.name} at {c.factor.label(level)} scores {acc:.3f} (95 % CI from {low:.3f}) for "
                    f"{c.model}, above its clean {c.clean:.3f}: a degradation that improves accuracy. The sweep "
                    f"refits the model at each level ({c.factor.description}); a degraded input can remove "
                    "noise a model fitted to, but check the sweep before trusting it"
                )
                break
        if c.factor.name != "saturation":
            continue
        if own is None:
            x = np.abs(np.asarray(X, dtype=np.float64))
            own = float(np.quantile(x, 0.99))
        for level, acc in reversed(list(zip(c.levels, c.accuracy, strict=False))):  # the harshest first
            if level < own and acc >= c.clean_low:
                clipped = (np.abs(np.asarray(X, dtype=np.float64)) > level).mean(axis=(0, 2))
                axes = ", ".join(f"{a}: {v:.0%}" for a, v in zip("xyz", clipped, strict=False))
                notes.append(
                    f"saturation at ±{level:g} {unit}, below the data's own level (99 % of the samples within "
                    f"±{own:.2g} {unit}, gravity included), costs {c.model} nothing ({acc:.3f} against "
                    f"{c.clean:.3f} clean): samples clipped per axis {axes}. The sweep refits the model on the "
                    "clipped windows, so this says a model trained on such a sensor does as well: what tells "
                    "the surfaces apart survives on the axes that still vary"
                )
                break
    return notes


def add_breaking_points(
    result: Any, out_dir: str | Path, *, quick: bool = False, random_state: int = 0, progress: bool = False
) -> dict | None:
    """Sweep the recommended and the study's model; set and return ``result.breaking_points``.

    ``quick`` sweeps the shorter level lists of :data:`tactile_torch.robustness.degradations.QUICK_LEVELS` with one
    draw per random level and 2 folds; otherwise every level, the study's 10 draws per SNR and 5 folds.
    The samples, labels and groups are those the candidates were cross-validated on
    (:attr:`~.summary.TradeoffResult.inputs`). Every family is swept: a factor that does not apply to a
    model (noise on the feature rows of a network that classifies the raw input) is in ``skipped`` with
    one line saying why; an int8 variant is swept as its float model (said in ``notes``); a factor that
    fails (a bug) is in ``failed`` and marks the result incomplete
    (:meth:`~.summary.TradeoffResult.mark_incomplete`), the other factors' curves kept. Returns ``None``
    (and sets nothing) when neither model could be fitted.
    """
    from ..robustness.degradations import QUICK_LEVELS, factors_for
    from ..robustness.output import breaking_summary
    from ..robustness.sweeps import infer_kind, sweep

    roles: dict[str, list[str]] = {}
    notes = []
    for role, name in (("recommended", result.recommended), ("study's model", result.study_model)):
        if name is None:
            continue
        variant = result.result(name)
        if variant.variant_of is not None:  # an int8 file: the sweeps refit, and refits are in float
            notes.append(
                f"{role}: {name} is swept as its float model {variant.variant_of!r}: the sweeps refit the "
                "model on degraded data, in float; int8 is a property of an exported file"
            )
            name = variant.variant_of
        if result.result(name).model is not None:
            roles.setdefault(name, []).append(role)
    if not roles:
        return None
    by_input: dict[str, dict[str, Any]] = {}
    for name, role in roles.items():
        cand = result.result(name).candidate
        by_input.setdefault(cand.input, {})[f"{' and '.join(role)}: {name}"] = cand.estimator
    out = Path(out_dir)
    summary: dict[str, Any] = {"rows": [], "figures": [], "skipped": [], "failed": [], "notes": notes}
    for key, models in by_input.items():
        samples = result.inputs[key]
        kind = infer_kind(samples.X)
        factors = [
            dataclasses.replace(f, levels=QUICK_LEVELS.get(f.name, f.levels), path=None) if quick else f
            for f in factors_for(kind)
        ]
        sweep_result = sweep(
            models,
            samples.X,
            samples.y,
            samples.groups,
            kind,
            factors=factors,
            n_splits=QUICK_SPLITS if quick else FULL_SPLITS,
            n_trials=1 if quick else {"feature SNR": 10, "image noise": 1},
            random_state=random_state,
            progress=progress,
        )
        part = breaking_summary(sweep_result, out / "breaking" / key)
        n_splits = sweep_result.n_splits or (QUICK_SPLITS if quick else FULL_SPLITS)
        summary["rows"] += [
            {
                "input": key,
                **{CLEAN_COLUMN.format(n=n_splits) if k == SWEEP_CLEAN else k: v for k, v in row.items()},
            }
            for row in part["rows"]
        ]
        notes += plausibility_notes(sweep_result.curves, samples.X)
        summary["figures"] += [str(Path(p).relative_to(out)) for p in part["figures"]]
        summary["skipped"] += [[f"{key}: {name}", why] for name, why in part["skipped"]]
        for name, why in part["failed"]:  # a bug in one factor: the other factors' curves are kept
            summary["failed"].append([f"{key}: {name}", why])
            result.mark_incomplete(f"breaking points: {name} ({key})", why)
    result.breaking_points = summary
    return summary


__all__ = ["add_breaking_points", "plausibility_notes", "refits"]
