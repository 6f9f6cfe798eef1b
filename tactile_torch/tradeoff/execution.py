"""Running a planned trade-off study: the candidates cross-validated fold by fold, stopped early when they
cannot be recommended, their first folds' models written as deployed and timed, the int8 variants and the
memory of every file, and the result (:func:`execute_plan`; :func:`~.runner.plan_tradeoff` makes the plan)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..export.parts import ExportPool
from ..robot.contract import SAMPLE_RATE_KEY
from .evaluation import export_and_time, submit_fronts
from .inputs import Samples, TradeoffData
from .selection import unit_accuracy
from .summary import TradeoffResult, _unit_warnings, baseline_rows, summarise
from .validation import check_target


@dataclass
class TradeoffPlan:
    """What :func:`plan_tradeoff` decided: the raw inputs with their folds and the candidates.

    Attributes
    ----------
    data : TradeoffData
    inputs : dict of str to Samples
    candidates : list of Candidate
    notes : list of str
    precomputed : dict
        Features already known (see :attr:`TradeoffData.precomputed`), by features key.
    seconds : float
        Time spent planning.
    quick : bool
    references : dict of str to FeatureRecipe
        Per raw input, its reference feature set (all features: the 21 at the window, fused 12, all
        columns), on which a learned model's "unknown" rule is measured (:mod:`.deploy`).
    """

    data: TradeoffData
    inputs: dict[str, Samples]
    candidates: list
    notes: list[str]
    precomputed: dict = field(default_factory=dict)
    seconds: float = 0.0
    quick: bool = False
    references: dict = field(default_factory=dict)


def execute_plan(
    plan: TradeoffPlan,
    pool: ExportPool,
    *,
    out_dir: str | Path,
    target: float | None = None,
    progress: bool = True,
    log: Callable[[str], None] = print,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    random_state: int = 0,
    exhaustive: bool = False,
    breaking: bool = False,
) -> TradeoffResult:
    """Cross-validate, export and time the candidates of ``plan`` (fronts already submitted to ``pool``).

    Fold by fold (:class:`~.evaluation.FoldwiseCV`): after the first fold every candidate's first-fold
    model is written as it would be deployed and timed (``out_dir / "timing"``: latency and size only,
    not for deployment), and after each fold but the last the candidates that cannot be recommended
    stop (:mod:`.stopping`; ``exhaustive=True``: none). ``target``: the accuracy a deployment needs
    (:func:`~.selection.choose`). ``backend``, ``n_jobs`` and ``scheduler`` say where the
    cross-validation tasks run (:class:`tactile_torch.model_selection.Backend`: ``"loky"``, ``"threading"``,
    ``"dask"`` with a scheduler address ...); the results do not depend on them. ``breaking``: the
    breaking points follow (only the estimate of the time left counts them).
    """
    from ..model_selection import as_backend
    from .evaluation import FoldwiseCV
    from .progress import RemainingTime, minutes
    from .stopping import EarlyStopping

    check_target(target)
    start = time.perf_counter()
    data, inputs = plan.data, plan.inputs
    submit_fronts(plan.candidates, inputs, pool)
    runner = as_backend(backend, n_jobs, scheduler)
    folds = FoldwiseCV(
        plan.candidates,
        inputs,
        precomputed=plan.precomputed,
        progress=progress,
        backend=runner,
        random_state=random_state,
    )
    n_folds = folds.n_folds
    units = {k: len(np.unique(s.units)) for k, s in inputs.items()}
    stopping = EarlyStopping(units, n_folds, target=target, enabled=not exhaustive)
    clock = RemainingTime()
    clock.plan(_planned_tasks(plan))
    log(
        f"[tradeoff] {len(plan.candidates)} candidates, {len(inputs)} raw input(s); cross-validating fold by fold "
        + (
            "(every candidate on every fold: exhaustive)"
            if exhaustive
            else "(candidates that cannot be recommended stop early)"
        )
    )
    by_name = {c.name: c for c in plan.candidates}
    results: dict[str, object] = {}
    cv_seconds = export_seconds = 0.0
    parts = 0
    with runner:
        for k in range(n_folds):
            stage = time.perf_counter()
            running = [c.name for c in plan.candidates if c.name not in stopping.stopped]
            for name, seconds in folds.run_fold(k, running).items():
                clock.finish((name, k), seconds)
                res = folds.result(by_name[name], results.get(name))
                results[name] = res
                if res.cv.error is None:
                    s = inputs[by_name[name].input]
                    test = s.folds[k][1]
                    ids, correct, count = unit_accuracy(s.y[test], res.cv.predictions[test], s.units[test])
                    stopping.record(name, by_name[name].input, [s.unit_name(i) for i in ids], correct, count)
            cv_seconds += time.perf_counter() - stage
            if k == 0:
                stage = time.perf_counter()
                parts = _export_first_folds(plan, results, pool, stopping, clock, out_dir, progress)
                export_seconds = time.perf_counter() - stage
                clock.finish(("exports",), export_seconds)
            if k < n_folds - 1:
                for name, stop in stopping.check(k + 1).items():
                    results[name].stopped = stop.reason
                    clock.drop([(name, j) for j in range(k + 1, n_folds)])
            clock.plan(_later_stages(plan, results, breaking=breaking, exhaustive=exhaustive))
            log(
                f"[tradeoff] fold {k + 1} of {n_folds}: {len(running)} candidates tested, "
                f"{len(stopping.stopped)} stopped early so far; {minutes(clock.remaining())} left"
            )
        # a candidate stopped by one that did not end above the baseline runs its other folds after all
        _resume_stopped(plan, results, folds, stopping, target, log)
    ordered = [results[c.name] for c in plan.candidates if c.name in results]
    log(
        f"[tradeoff] cross-validation: {cv_seconds:.1f} s; ONNX export and timing of the first folds' models "
        f'(written as deployed, with their "unknown" rule): {export_seconds:.1f} s ({parts} exported parts)'
    )
    stage = time.perf_counter()
    rows, recommended, runner_up = _int8_and_memory(plan, ordered, pool, out_dir, target, progress)
    log(f"[tradeoff] int8 variants and memory: {time.perf_counter() - stage:.1f} s")
    baselines = baseline_rows(inputs)
    for b in baselines.values():
        b.pop("_units")
    result = TradeoffResult(
        data=data,
        results=ordered,
        rows=rows,
        recommended=recommended,
        runner_up=runner_up,
        splits={k: s.split for k, s in inputs.items()},
        notes=plan.notes,
        seconds=plan.seconds + time.perf_counter() - start,
        exports=parts,
        study_model=_study_model(plan),
        inputs=inputs,
        target=target,
        chance=1.0 / len(data.class_names),
        baselines=baselines,
        warnings=_unit_warnings(inputs),
        references=plan.references,
    )
    result.early_stopping = stopping
    if data.kind in ("image", "pressure"):  # how long the hand must hold (docs/tradeoff.md)
        from .touch_time import accuracy_vs_time

        stage = time.perf_counter()
        result.touch_time = accuracy_vs_time(result, quick=plan.quick, log=log)
        result.seconds += time.perf_counter() - stage
    return result


def _export_first_folds(plan, results, pool, stopping, clock, out_dir, progress) -> int:
    """Write and time every candidate's first-fold model as deployed (:func:`~.evaluation.export_and_time`),
    give the stopping rule their costs and stop the ones it stops; return the number of exported parts."""
    data, n_folds = plan.data, stopping.folds
    meta_rate = data.rate_hz if data.kind in ("vibration", "image", "pressure") else None
    firsts = [results[c.name] for c in plan.candidates if c.name in results]
    parts = export_and_time(
        firsts,
        plan.inputs,
        data.class_names,
        Path(out_dir) / "timing",
        pool,
        rate_hz=meta_rate,
        references=plan.references,  # a 1-D CNN's rule on its window features, in its timing file too
        progress=progress,
    )
    for res in firsts:
        stopping.set_cost(res.candidate.name, res.decision_s if res.model is not None else None)
        stop = stopping.stopped.get(res.candidate.name)
        if stop is not None and res.model is not None:
            res.stopped = stop.reason
            clock.drop([(res.candidate.name, j) for j in range(1, n_folds)])
    return parts


def _resume_stopped(plan, results, folds, stopping, target, log) -> None:
    """Run the other folds of a candidate stopped by one that did not end above the baseline."""
    by_name = {c.name: c for c in plan.candidates}
    while True:
        rows, _, _ = summarise(
            [results[c.name] for c in plan.candidates if c.name in results], plan.inputs, target=target
        )
        adequate = {r["name"]: bool(r["adequate"]) for r in rows if not r.get("stopped")}
        resume = stopping.to_resume(adequate)
        if not resume:
            return
        log(
            f"[tradeoff] {len(resume)} candidate(s) stopped early by one that ended below the baseline: running their other folds"
        )
        for name in resume:
            results[name].stopped = None
        for k in range(1, stopping.folds):
            for name in folds.run_fold(k, resume):
                results[name] = folds.result(by_name[name], results[name])


def _int8_and_memory(plan, ordered, pool, out_dir, target, progress) -> tuple:
    """The int8 variants and the memory of the files to show; return :func:`~.summary.summarise`'s
    ``(rows, recommended, runner_up)`` with each row's ``memory_mib``."""
    from .evaluation import classical_fold_file
    from .learned import add_int8_and_memory, measure_memory

    data, inputs = plan.data, plan.inputs
    meta = {SAMPLE_RATE_KEY: data.rate_hz} if data.kind == "vibration" else {}

    def fold_file(cand, model, path):
        return classical_fold_file(pool, cand, inputs[cand.input], data.class_names, meta)(model, path)

    models_dir = Path(out_dir) / "timing"
    add_int8_and_memory(
        ordered,
        inputs,
        models_dir,
        fold_file=fold_file,
        pool=pool,
        quick=plan.quick,
        progress=progress,
        notes=plan.notes,
    )
    rows, recommended, runner_up = summarise(ordered, inputs, target=target)
    only = {r["name"] for r in rows if not r.get("stopped")}
    if plan.quick:  # a child process per file: the front, the learned and the int8 ones
        only = {
            r["name"]
            for r in rows
            if r["name"] in only and (r["pareto"] or r["family"] != "classical" or r["quantisation"])
        }
    measure_memory(ordered, inputs, models_dir, only=only, progress=progress)
    memory = {res.candidate.name: res.memory_mib for res in ordered}
    for row in rows:
        row["memory_mib"] = memory.get(row["name"])
    return rows, recommended, runner_up


def _later_stages(plan: TradeoffPlan, results: dict, *, breaking: bool, exhaustive: bool) -> list:
    """The stages after the cross-validation, as tasks whose seconds come from the folds so far: the
    deployment (tuning and a fit on all the data: about two folds of the leading candidate) and the
    breaking points (:func:`~.breaking.refits` fits of the leader and of the study's model)."""
    from ..robustness.sweeps import infer_kind
    from .breaking import refits
    from .progress import Task

    done = [r for r in results.values() if r.fold_accuracy and r.model is not None and not r.stopped]
    if not done:
        return []
    leader = max(done, key=lambda r: float(np.mean(r.fold_accuracy)))

    def fit(res: object) -> float:
        return float(np.mean(res.cv.fit_seconds)) if res is not None and res.cv.fit_seconds else 0.0

    tasks = [Task(("deploy",), "deploy", "deploy", expected=2.0 * fit(leader))]
    if breaking:
        study = results.get(plan.candidates[0].name) if plan.candidates else None
        kind = infer_kind(plan.inputs[leader.candidate.input].X)
        n = refits(kind, quick=plan.quick or not exhaustive)
        tasks.append(Task(("breaking",), "breaking", "breaking", expected=n * (fit(leader) + fit(study))))
    return tasks


def _planned_tasks(plan: TradeoffPlan) -> list:
    """The study's cross-validation and export tasks, for the estimate of the time left (:mod:`.progress`)."""
    from .. import catalogue
    from .progress import Task

    tasks = []
    for cand in plan.candidates:
        s = plan.inputs[cand.input]
        family = (
            catalogue.entry(cand.key).family
            if cand.key in catalogue.LEARNED
            else ("svm" if cand.key in ("hmsvm", "svc") else "classical")
        )
        for k, (train, _) in enumerate(s.folds):
            tasks.append(Task((cand.name, k), cand.name, family, float(len(train))))
    tasks.append(Task(("exports",), "exports", "export", float(len(plan.candidates))))
    return tasks


def _study_model(plan: TradeoffPlan) -> str | None:
    reference = plan.candidates[0].features if plan.candidates else None
    for cand in plan.candidates:
        if cand.classifier == "HM-SVM" and cand.features == reference:
            return cand.name
    return None


__all__ = ["TradeoffPlan", "execute_plan"]
