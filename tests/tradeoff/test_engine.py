"""The trade-off on the evaluation engine: nested tuning, backends, and its arguments' errors."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.cli import main
from tactile_torch.data.stylus import make_vibration_recordings
from tactile_torch.tradeoff import run_tradeoff
from tactile_torch.tradeoff.evaluation import cross_validate
from tactile_torch.tradeoff.runner import plan_tradeoff
from tactile_torch.tradeoff.summary import summarise


@pytest.fixture(scope="module")
def recordings():
    return make_vibration_recordings(4, duration_s=8, random_state=2)


def _features_file(path, seed=0, n=40):
    rng = np.random.default_rng(seed)
    y = np.repeat([0, 1, 2], n // 2)
    X = rng.normal(size=(len(y), 5)) + np.eye(3, 5)[y] * 2.0
    groups = np.arange(len(y)) // 4
    np.savez(path, features=X, labels=y, class_names=np.array(["a", "b", "c"]), groups=groups)
    return path


def _run(path, *, tune=True, **engine):
    """The trade-off's stages 1-2 (no ONNX export): its rows, and its results by name."""
    plan = plan_tradeoff(
        path,
        quick=True,
        classifiers=["svc", "lda", "knn"],
        features=["all"],
        n_folds=3,
        tune=tune,
        log=lambda s: None,
    )
    results = cross_validate(plan.candidates, plan.inputs, progress=False, **engine)
    return summarise(results)[0], {r.candidate.name: r for r in results}, plan


def test_tuned_candidates_report_their_parameters_and_tuning_time(tmp_path):
    path = _features_file(tmp_path / "feat.npz")
    rows, _, _ = _run(path)
    for row in rows:
        assert len(row["params"]) == 3 and all(row["params"])  # chosen in each of the 3 folds
        assert 0.0 < row["tune_s"] <= row["fit_s"]  # tuning counts in the fit time
    svc = next(r for r in rows if r["classifier"] == "SVC")
    assert set(svc["params"][0]) == {"C", "gamma"}
    rows, results, plan = _run(path, tune=False)
    assert all(r["tune_s"] == 0.0 and r["params"] == [{}, {}, {}] for r in rows)
    lda = results["LDA | all 5 features"].cv
    assert lda.predictions.shape == (60,) and (lda.fold >= 0).all()  # every sample tested once
    groups = plan.inputs["features"].groups  # the folds' groups, or every sample its own
    assert np.array_equal(lda.groups, np.arange(60) if groups is None else groups)


def test_trade_off_results_do_not_depend_on_the_backend(tmp_path):
    path = _features_file(tmp_path / "feat.npz", seed=1)
    local = _run(path)[0]
    threads = _run(path, backend="threading", n_jobs=2)[0]
    for a, b in zip(local, threads, strict=True):
        assert (a["name"], a["fold_accuracy"], a["params"]) == (b["name"], b["fold_accuracy"], b["params"])


def test_bad_arguments_give_one_line_naming_them(tmp_path, recordings, capsys):
    path = recordings.save(tmp_path / "rec.npz")
    with pytest.raises(ValueError, match=r"n_folds must be at most"):
        run_tradeoff(path, n_folds=1000, quick=True, out_dir=tmp_path / "o", log=lambda s: None)
    with pytest.raises(ValueError, match=r"max_per_class must be 'auto' or a whole number >= 2.*got 0"):
        run_tradeoff(path, max_per_class=0, out_dir=tmp_path / "o", log=lambda s: None)
    with pytest.raises(ValueError, match=r"frame_rate_hz must be a"):
        run_tradeoff(path, frame_rate_hz=0.0, out_dir=tmp_path / "o", log=lambda s: None)
    with pytest.raises(ValueError, match="backend must be one of"):
        run_tradeoff(path, backend="spark", out_dir=tmp_path / "o", log=lambda s: None)
    out = str(tmp_path / "o")
    for option in (["--folds", "1000"], ["--max-per-class", "0"], ["--frame-rate", "0"]):
        try:
            status = main(["tradeoff", "--data", str(path), "--out", out, "--quiet", *option])
        except SystemExit as exit:  # refused by the option's parser (tests/cli/test_options.py)
            status = exit.code
        assert status == 2
        errors = capsys.readouterr().err.strip().splitlines()
        assert len(errors) == 1 and errors[0].startswith("tactile-torch tradeoff: "), errors
        assert "internal error" not in errors[0]


def test_fold_by_fold_gives_the_one_call_results(tmp_path):
    """The study runs the folds one at a time (to stop candidates early): the seeds, predictions, fold
    numbers and tuned parameters are those of one cross-validation over every fold."""
    from tactile_torch.model_selection import cross_validate as engine_cross_validate

    path = _features_file(tmp_path / "feat.npz", seed=2)
    _, results, plan = _run(path)
    s = plan.inputs["features"]
    once = engine_cross_validate(
        {c.name: c.estimator for c in plan.candidates}, s.X, s.y, s.folds, groups=s.groups,
        tuning={c.name: c.tuning for c in plan.candidates},
    )  # fmt: skip
    for name, res in results.items():
        np.testing.assert_array_equal(res.cv.predictions, once[name].predictions)
        np.testing.assert_array_equal(res.cv.fold, once[name].fold)
        assert res.cv.params == once[name].params and res.fold_accuracy == once[name].fold_accuracy


def test_the_runner_up_is_another_model_never_the_recommended_ones_int8_copy(tmp_path):
    import dataclasses

    path = _features_file(tmp_path / "feat.npz", seed=3)
    _, results, plan = _run(path)
    ordered = list(results.values())
    for i, res in enumerate(ordered):
        res.latency_ms, res.size_bytes, res.decision_s = 0.1 + i, 1000 + i, 0.1 + i
    first = summarise(ordered, plan.inputs)[1]
    best = results[first]
    copy = dataclasses.replace(
        best,
        candidate=dataclasses.replace(best.candidate, name=f"{first} (int8)"),
        latency_ms=0.05,
        decision_s=0.05,
    )
    copy.variant_of, copy.quantisation = first, "dynamic"
    _, recommended, runner_up = summarise([*ordered, copy], plan.inputs)
    assert recommended == f"{first} (int8)"  # cheaper, as accurate
    assert runner_up is not None and runner_up not in (first, f"{first} (int8)")


@pytest.mark.slow  # two studies with their exports (one head and one distance part each): 15 s loaded
def test_early_stops_recommend_what_the_exhaustive_study_does(tmp_path):
    """A study on features where a costlier candidate is clearly worse: it stops after a few folds, and the
    recommendation is the exhaustive study's."""
    from tactile_torch.export.parts import ExportPool
    from tactile_torch.tradeoff.execution import execute_plan

    path = _features_file(tmp_path / "feat.npz", seed=4, n=120)
    chosen = {}
    for exhaustive in (False, True):
        plan = plan_tradeoff(path, classifiers=["lda", "knn"], features=["all"], log=lambda s: None)
        out = tmp_path / f"out-{exhaustive}"
        with ExportPool(out / "parts", background=False) as pool:
            result = execute_plan(
                plan, pool, out_dir=out, progress=False, log=lambda s: None, exhaustive=exhaustive
            )
        chosen[exhaustive] = result.recommended
        stopped = [r for r in result.rows if r["stopped"]]
        assert not stopped if exhaustive else all(r["folds"] < 5 for r in stopped)
    assert chosen[False] == chosen[True] is not None
