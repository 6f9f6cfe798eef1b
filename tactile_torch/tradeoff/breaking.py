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
        summary["rows"] += [{"input": key, **row} for row in part["rows"]]
        summary["figures"] += [str(Path(p).relative_to(out)) for p in part["figures"]]
        summary["skipped"] += [[f"{key}: {name}", why] for name, why in part["skipped"]]
        for name, why in part["failed"]:  # a bug in one factor: the other factors' curves are kept
            summary["failed"].append([f"{key}: {name}", why])
            result.mark_incomplete(f"breaking points: {name} ({key})", why)
    result.breaking_points = summary
    return summary


__all__ = ["add_breaking_points"]
