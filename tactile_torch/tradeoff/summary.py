"""What a trade-off study returns: :class:`TradeoffResult`, and its rows (:func:`summarise`: one per
candidate, with the per-unit interval, the trivial baseline of :func:`baseline_rows`, the Pareto front and
the recommended model of :mod:`.selection`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .candidates import CandidateResult
from .inputs import Samples, TradeoffData
from .selection import (
    MIN_UNITS,
    above_baseline,
    choose,
    majority_predictions,
    pareto_front,
    unit_accuracy,
    unit_interval,
)


@dataclass
class TradeoffResult:
    """The outcome of :func:`~.runner.run_tradeoff`.

    Attributes
    ----------
    data : TradeoffData
    results : list of CandidateResult
        In candidate order; ``accuracy``, intervals and ``pareto`` in :attr:`rows`.
    rows : list of dict
        One per candidate: the fields of ``tradeoff.json``.
    recommended, runner_up : str or None
        Candidate names (``runner_up`` is ``None`` with a single eligible model: it is another model than
        the recommended one, never its int8 copy or float twin).
    splits : dict of str to str
        How each raw input was split into folds.
    notes : list of str
    seconds : float
    exports : int
        Distinct exported parts (feature graphs and classifier structures) the candidates' files join.
    study_model : str or None
        The studies' own model among the candidates: the HM-SVM on the reference feature set (fused 12
        for images, the 21 features at the reference window for vibration), if it was evaluated.
    inputs : dict of str to Samples
        The raw inputs and folds the candidates were evaluated on (for further sweeps of the
        candidates' estimators, e.g. breaking points under degraded input).
    breaking_points : dict or None
        Filled by a breaking-point study of the candidates (:mod:`tactile_torch.robustness`) before
        :func:`~.output.write_outputs`: ``{"rows": [...], "figures": [paths]}`` and anything
        JSON-serialisable; written to ``tradeoff.json`` and as a table and charts in ``tradeoff.md``.
    target : float or None
        The accuracy a deployment needs (``--target``), if given.
    chance : float
        ``1 / n_classes``.
    baselines : dict of str to dict
        The trivial baseline (majority class of each training fold) per raw input: ``accuracy``
        (mean over units), ``accuracy_low``, ``accuracy_high``, ``interval``, ``unit``, ``n_units``.
    warnings : list of str
        One line each (e.g. too few units for an interval).
    deployed : list of dict
        The candidates refitted on all the data and written (:func:`~.deploy.deploy_candidate`): name,
        files (``recommended.onnx``, ``recommended.npz``, ...), samples, agreement, notes.
    incomplete : list of dict
        The late stages that failed (``stage``, ``error``): an internal error (a bug) after the
        candidates were measured, in the deployment, the breaking points or a chart. What is complete
        is still written; ``tradeoff.json`` and ``tradeoff.md`` say what is missing, and the command
        ends with status 1 (:meth:`mark_incomplete`).
    references : dict of str to FeatureRecipe
        Per raw input, its reference feature set (:class:`~.execution.TradeoffPlan`).
    touch_time : dict of str to TouchTime
        Frame data: accuracy against time into the touch of the recommended candidate and the
        runner-up, with the early-decision rule their held-out touches calibrate (:mod:`.touch_time`).
    """

    data: TradeoffData
    results: list[CandidateResult]
    rows: list[dict]
    recommended: str | None
    runner_up: str | None
    splits: dict[str, str]
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    exports: int = 0
    study_model: str | None = None
    inputs: dict[str, Samples] = field(default_factory=dict, repr=False)
    breaking_points: dict | None = None
    target: float | None = None
    chance: float = 0.0
    baselines: dict[str, dict] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    deployed: list[dict] = field(default_factory=list)
    incomplete: list[dict] = field(default_factory=list)
    references: dict = field(default_factory=dict, repr=False)

    def mark_incomplete(self, stage: str, error: BaseException | str) -> None:
        """Record that the late stage ``stage`` failed with ``error`` (its other outputs are kept)."""
        if isinstance(error, BaseException):
            error = f"{type(error).__name__}: {' '.join(str(error).split())[:300]}"
        self.incomplete.append({"stage": stage, "error": error})

    touch_time: dict = field(default_factory=dict)

    @property
    def status(self) -> str:
        """``"recommended"``, ``"none adequate"`` (candidates were measured, none reaches the rule's bar) or
        ``"none exported"`` (no candidate could be fitted and exported)."""
        if self.recommended is not None:
            return "recommended"
        measured = any(r["decision_s"] is not None and r["accuracy"] is not None for r in self.rows)
        return "none adequate" if measured else "none exported"

    def row(self, name: str) -> dict:
        """Return the row of candidate ``name``."""
        for r in self.rows:
            if r["name"] == name:
                return r
        raise KeyError(name)

    def result(self, name: str) -> CandidateResult:
        """Return the :class:`~.candidates.CandidateResult` of candidate ``name`` (its estimator, fitted model)."""
        for res in self.results:
            if res.candidate.name == name:
                return res
        raise KeyError(name)


def _unit_warnings(inputs: dict[str, Samples]) -> list[str]:
    few = {
        k: (s.unit, len(np.unique(s.units))) for k, s in inputs.items() if len(np.unique(s.units)) < MIN_UNITS
    }
    if not few:
        return []
    where = "" if len(few) == len(inputs) else f" ({', '.join(few)})"
    words = " / ".join(dict.fromkeys(_unit_words(unit, n) for unit, n in few.values()))
    unit = next(iter(few.values()))[0]
    return [
        f"warning: only {words} in the data{where}: accuracies are given as the range over the {unit}s "
        f"(lowest, highest), not as an interval; {MIN_UNITS} or more give a 95 % interval for a new {unit}"
    ]


def _plain(params: dict) -> dict:
    """Tuned parameters as JSON values (``classifier__C`` -> ``C``)."""
    out = {}
    for k, v in params.items():
        v = v.item() if isinstance(v, np.generic) else v
        out[k.split("__")[-1]] = v if isinstance(v, str | int | float | bool | type(None)) else repr(v)
    return out


def _unit_words(unit: str, n: int) -> str:
    return f"{n} {unit}{'' if n == 1 else 's'}"


def baseline_rows(samples: dict[str, Samples]) -> dict[str, dict]:
    """The trivial baseline (each fold's majority class) of every raw input, with its per-unit interval."""
    out = {}
    for key, s in samples.items():
        predicted = majority_predictions(s.y, s.folds)
        ids, correct, count = unit_accuracy(s.y, predicted, s.units)
        u = unit_interval(correct, count, units=ids)
        out[key] = {
            "name": "majority class",
            "accuracy": u.mean,
            "accuracy_low": u.low,
            "accuracy_high": u.high,
            "interval": u.kind,
            "unit": s.unit,
            "n_units": u.n,
            "_units": u,
        }
    return out


def summarise(
    results: list[CandidateResult],
    samples: dict[str, Samples] | None = None,
    *,
    target: float | None = None,
) -> tuple[list[dict], str | None, str | None]:
    """Return the JSON rows (with ``pareto``), the recommended candidate and the runner-up (:mod:`.selection`).

    ``samples`` (the raw inputs, with their units and folds) gives the per-unit intervals and the
    trivial baseline; without it, every fold counts as a unit. ``target``: see :func:`~.selection.choose`.
    """
    baselines = baseline_rows(samples) if samples else {}
    rows = []
    for res in results:
        c = res.candidate
        row = {
            "name": c.name,
            "classifier": c.classifier,
            "features": c.features,
            "input": c.input,
            "accuracy": None,
            "accuracy_low": None,
            "accuracy_high": None,
            "accuracy_se": None,
            "interval": None,
            "unit": None,
            "n_units": None,
            "unit_accuracy": [],
            "fold_accuracy": list(res.fold_accuracy),
            "baseline_accuracy": None,
            "above_baseline": None,
            "baseline_p": None,
        }
        if res.fold_accuracy:
            s = samples[c.input] if samples else None
            if s is not None and res.predictions is not None:
                ids, correct, count = unit_accuracy(s.y, res.predictions, s.units)
                u = unit_interval(correct, count, units=ids)
                unit = s.unit
            else:  # no samples given: the folds are the units, with equal weight
                n = np.ones(len(res.fold_accuracy))
                u = unit_interval(np.asarray(res.fold_accuracy), n, units=np.arange(len(n)))
                unit = "fold"
            row.update(
                accuracy=u.mean,
                accuracy_low=u.low,
                accuracy_high=u.high,
                accuracy_se=u.se,
                interval=u.kind,
                unit=unit,
                n_units=u.n,
                unit_accuracy=[
                    {
                        "unit": s.unit_name(i) if s is not None else f"fold {int(i) + 1}",
                        "accuracy": float(a),
                        "samples": int(k),
                    }
                    for i, a, k in zip(u.units, u.accuracy, u.count, strict=True)
                ],
            )
            if c.input in baselines and not res.stopped:  # a stopped one was tested on some units only
                base = baselines[c.input]
                significant, p = above_baseline(u, base["_units"])
                row.update(baseline_accuracy=base["accuracy"], above_baseline=bool(significant), baseline_p=p)
        row.update(
            {
                "fit_s": res.fit_s if res.fold_accuracy else None,
                "tune_s": res.tune_s if res.fold_accuracy else None,
                "params": [_plain(p) for p in res.params],
                "family": res.family,
                "n_parameters": res.n_parameters,
                "quantisation": res.quantisation,
                "variant_of": res.variant_of,
                "int8_loss": None,
                "int8_degraded": None,
                "latency_ms": res.latency_ms,
                "size_bytes": res.size_bytes,
                "memory_mib": res.memory_mib,
                "decision_s": res.decision_s,
                "touch_ms": None,
                "pareto": False,
                "adequate": False,
                "timing_onnx_file": res.onnx_file,
                "onnx_agreement": res.onnx_agreement,
                "folds": len(res.fold_accuracy),
                "stopped": res.stopped,
                "notes": res.notes,
            }
        )
        if samples and res.latency_ms is not None:
            row["touch_ms"] = touch_ms(res.latency_ms, samples[c.input])
        rows.append(row)
    mark_int8_losses(rows)
    ok = [
        i
        for i, r in enumerate(rows)
        if r["decision_s"] is not None and r["accuracy"] is not None and not r["stopped"]
    ]
    if not ok:
        return rows, None, None
    acc = np.array([rows[i]["accuracy"] for i in ok])
    se = np.array([rows[i]["accuracy_se"] for i in ok])
    low = np.array([rows[i]["accuracy_low"] for i in ok])
    cost = np.array([rows[i]["decision_s"] for i in ok])
    size = np.array([rows[i]["size_bytes"] for i in ok], dtype=np.float64)
    adequate = np.array([rows[i]["above_baseline"] is not False for i in ok])
    if target is not None:
        adequate = low >= target - 1e-12
    for i, on, fit in zip(ok, pareto_front(acc, cost), adequate, strict=True):
        rows[i]["pareto"] = bool(on)
        rows[i]["adequate"] = bool(fit)
    first = choose(acc, se, low, cost, size, adequate=adequate, target=target)
    if first is None:
        return rows, None, None
    # the runner-up is another model: an int8 copy (or the float twin) of the recommended one is its variant
    model = rows[ok[first]]["variant_of"] or rows[ok[first]]["name"]
    excluded = np.array([(rows[i]["variant_of"] or rows[i]["name"]) == model for i in ok])
    second = choose(acc, se, low, cost, size, adequate=adequate, target=target, exclude=excluded)
    return rows, rows[ok[first]]["name"], None if second is None else rows[ok[second]]["name"]


def touch_ms(latency_ms: float, samples: Samples) -> float | None:
    """A frame candidate's inference per touch, at most: the end of the touch and every checkpoint of an
    early-decision rule (:func:`tactile_torch.robot.stream.early_decision.checkpoints_for`); ``None`` otherwise."""
    from ..robot.contract import FRAMES_LAYOUT, PRESSURE_LAYOUT
    from ..robot.stream.early_decision import checkpoints_for

    if samples.layout not in (PRESSURE_LAYOUT, FRAMES_LAYOUT):
        return None
    return latency_ms * (1 + len(checkpoints_for(samples.X.shape[1])))


def mark_int8_losses(rows: list[dict]) -> None:
    """Set each int8 variant's ``int8_loss`` (its float model's accuracy minus its own) and
    ``int8_degraded`` (its accuracy lies below the float model's interval, or range, over the units: it
    is not the same model any more), with a note saying so."""
    by_name = {r["name"]: r for r in rows}
    for row in rows:
        base = by_name.get(row.get("variant_of"))
        if base is None or row["accuracy"] is None or base["accuracy"] is None:
            continue
        row["int8_loss"] = base["accuracy"] - row["accuracy"]
        row["int8_degraded"] = bool(row["accuracy"] < base["accuracy_low"] - 1e-12)
        if row["int8_degraded"]:
            kind = "range" if base["interval"] == "range" else "95 % interval"
            row["notes"].append(
                f"int8 loses {row['int8_loss']:.3f} against its float model ({base['accuracy']:.3f} -> "
                f"{row['accuracy']:.3f}), below the float model's {kind} [{base['accuracy_low']:.3f}, "
                f"{base['accuracy_high']:.3f}] per {base['unit']}: quantisation changed the model"
            )


__all__ = ["TradeoffResult", "baseline_rows", "mark_int8_losses", "summarise"]
