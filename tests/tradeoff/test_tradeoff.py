"""tactile_torch.tradeoff and tactile_torch.export.classifier_inference: candidates, folds, parsimony rule, ONNX, command."""

import json

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats
from sklearn.base import clone
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.neighbors import KNeighborsClassifier, NearestCentroid

from tactile_torch.cli import main
from tactile_torch.data import make_vibration_recordings
from tactile_torch.data.images import make_explorations
from tactile_torch.export.classifier_inference import inference_module
from tactile_torch.export.parts import Standardize, bind_head, export_head, head_key
from tactile_torch.tradeoff import (
    build_candidates,
    feature_sets,
    fold_interval,
    load_tradeoff_data,
    one_standard_error_choice,
    pareto_front,
)
from tactile_torch.tradeoff.evaluation import cross_validate
from tactile_torch.tradeoff.inputs import TradeoffData, exploration_samples, vibration_samples
from tests.conftest import require_shared_data


@pytest.fixture(scope="module")
def recordings():
    return make_vibration_recordings(4, duration_s=8, random_state=2)


def _blobs(n=60, f=5, c=3, seed=0):
    rng = np.random.default_rng(seed)
    y = np.arange(n) % c
    return rng.normal(size=(n, f)) + y[:, None] * 0.8, y


# ---------------------------------------------------------------------------------------- baselines
@pytest.mark.parametrize("classes", [2, 4])
def test_baseline_modules_equal_scikit_learn(classes):
    X, y = _blobs(80, 6, classes)
    x = torch.from_numpy(X[:17])
    lda = LinearDiscriminantAnalysis().fit(X, y)
    labels, scores = inference_module(lda)(x)
    np.testing.assert_array_equal(labels.numpy(), lda.predict(X[:17]))
    decision = lda.decision_function(X[:17])
    expected = np.stack([-decision, decision], 1) if classes == 2 else decision
    np.testing.assert_allclose(scores.numpy(), expected, rtol=1e-10, atol=1e-10)
    knn = KNeighborsClassifier(3, metric="cityblock", weights="distance").fit(X, y)
    labels, scores = inference_module(knn)(torch.from_numpy(X[:17]))  # queries on training samples: d = 0
    np.testing.assert_array_equal(labels.numpy(), knn.predict(X[:17]))
    np.testing.assert_allclose(scores.numpy(), knn.predict_proba(X[:17]), atol=1e-12)
    query = X[:17] + 0.1
    labels, scores = inference_module(knn)(torch.from_numpy(query))
    np.testing.assert_array_equal(labels.numpy(), knn.predict(query))
    np.testing.assert_allclose(scores.numpy(), knn.predict_proba(query), rtol=1e-10)
    ncm = NearestCentroid().fit(X, y)
    labels, scores = inference_module(ncm)(torch.from_numpy(query))
    np.testing.assert_array_equal(labels.numpy(), ncm.predict(query))
    squared = ((query[:, None] - ncm.centroids_[None]) ** 2).sum(2)
    np.testing.assert_allclose(scores.numpy(), (query**2).sum(1)[:, None] - squared, rtol=1e-9, atol=1e-9)


def test_inference_module_errors():
    X, y = _blobs()
    with pytest.raises(TypeError, match="estimator must be a fitted"):
        inference_module(object())
    with pytest.raises(ValueError, match="city-block or Euclidean"):
        inference_module(KNeighborsClassifier(metric="chebyshev").fit(X, y))
    from sklearn.exceptions import NotFittedError

    with pytest.raises(NotFittedError):
        inference_module(LinearDiscriminantAnalysis())


def test_head_template_binds_other_fits_and_runs_at_another_batch(tmp_path):
    """One exported head structure, bound to two fits of different sizes, equals the eager modules."""
    from tactile_torch.export import run_onnx
    from tactile_torch.features.transformers import ColumnSelect

    def head(seed, n, f, c):
        X, y = _blobs(n, f, c, seed)
        knn = KNeighborsClassifier(3, metric="cityblock", weights="distance").fit(X, y)
        return [ColumnSelect(np.arange(f)), Standardize(X.mean(0), X.std(0)), inference_module(knn)]

    first, second = head(0, 30, 4, 3), head(1, 50, 6, 5)
    assert head_key(first, 4) == head_key(second, 6)  # one structure
    import onnx

    template = onnx.load(str(export_head(first, 4, tmp_path / "template.onnx")))
    x = torch.randn(7, 6)  # exported at batch 2
    path = tmp_path / "bound.onnx"
    onnx.save(bind_head(template, second), str(path))
    labels, scores = run_onnx(path, x.numpy())
    with torch.no_grad():
        want = torch.nn.Sequential(*second)(x)
    np.testing.assert_array_equal(labels, want[0].numpy())
    np.testing.assert_allclose(scores, want[1].numpy(), rtol=1e-6, atol=1e-9)


@pytest.mark.slow  # 8 s on a quiet 2-core machine: keeps the default run under 10 minutes
def test_bound_one_vs_one_head_keeps_only_what_the_graph_reads(tmp_path):
    """The one-vs-one SVM's n_support (a buffer for its model file) is not bound into the ONNX head."""
    import onnx

    from tactile_torch.export import run_onnx
    from tactile_torch.svm import SVC

    X, y = _blobs(40, 4, 3, 0)
    head = [Standardize(X.mean(0), X.std(0)), SVC(gamma=0.5).fit(X, y).to_module()]
    template = onnx.load(str(export_head(head, 4, tmp_path / "template.onnx")))
    bound = bind_head(template, head)
    assert not [init.name for init in bound.graph.initializer if "n_support" in init.name]
    path = tmp_path / "bound.onnx"
    onnx.save(bound, str(path))
    x = torch.randn(5, 4, generator=torch.Generator().manual_seed(0))
    labels, _ = run_onnx(path, x.numpy())
    with torch.no_grad():
        np.testing.assert_array_equal(labels, torch.nn.Sequential(*head)(x)[0].numpy())


# ---------------------------------------------------------------------------------------- selection
def test_fold_interval_is_students_t():
    acc = [0.8, 0.85, 0.9, 0.7, 0.75]
    mean, se, low, high = fold_interval(acc)
    lo, hi = stats.t.interval(0.95, 4, loc=np.mean(acc), scale=stats.sem(acc))
    assert mean == pytest.approx(0.8) and se == pytest.approx(stats.sem(acc))
    assert (low, high) == pytest.approx((lo, hi))
    assert fold_interval([1.0, 1.0, 1.0])[2:] == (1.0, 1.0)
    with pytest.raises(ValueError, match="at least 2 folds"):
        fold_interval([0.9])


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 20), st.integers(1, 20), st.integers(0, 5)), min_size=1, max_size=12)
)
def test_pareto_and_one_standard_error_rule(points):
    acc = np.array([p[0] / 20 for p in points])
    cost = np.array([float(p[1]) for p in points])
    se = np.array([p[2] / 100 for p in points])
    front = pareto_front(acc, cost)
    for i in range(len(acc)):  # brute force: dominated iff some j is no worse in both and better in one
        dominated = any(
            acc[j] >= acc[i] and cost[j] <= cost[i] and (acc[j] > acc[i] or cost[j] < cost[i])
            for j in range(len(acc))
        )
        assert front[i] == (not dominated)
    choice = one_standard_error_choice(acc, se, cost)
    best = max(np.flatnonzero(front), key=lambda i: (acc[i], -cost[i]))
    assert front[choice] and acc[choice] >= acc[best] - se[best] - 1e-12
    eligible = [i for i in np.flatnonzero(front) if acc[i] >= acc[best] - se[best] - 1e-12]
    assert cost[choice] <= 1.1 * min(cost[i] for i in eligible)


def test_one_standard_error_rule_prefers_the_cheaper_model_within_noise():
    acc, se, cost = np.array([0.90, 0.89, 0.70]), np.array([0.02, 0.02, 0.05]), np.array([5.0, 1.0, 0.5])
    assert one_standard_error_choice(acc, se, cost) == 1
    assert one_standard_error_choice(acc, np.array([0.001, 0.02, 0.05]), cost) == 0  # outside 1 SE
    runner = one_standard_error_choice(acc, se, cost, exclude=[False, True, False])
    assert runner == 0
    size = np.array([1.0, 9.0, 1.0])
    # costs within 10 % count as equal: the smaller file wins
    assert one_standard_error_choice([0.90, 0.89], [0.02, 0.02], [1.05, 1.0], [1.0, 9.0]) == 0
    assert one_standard_error_choice(acc, se, cost, size) == 1


# ---------------------------------------------------------------------------------------- inputs
def test_time_block_folds_never_split_neighbouring_windows(recordings):
    s = vibration_samples(recordings, 400, n_folds=4)
    ds = recordings.windows(400)
    # map kept windows back to (recording, position) through their samples
    index = {
        w.tobytes(): (int(r), int(p))
        for w, r, p in zip(ds.windows.numpy(), ds.recording, ds.position, strict=True)
    }
    where = np.array([index[w.tobytes()] for w in s.X])
    for train, test in s.folds:
        for rec in np.unique(where[:, 0]):
            tr = set(where[train][where[train][:, 0] == rec][:, 1])
            te = set(where[test][where[test][:, 0] == rec][:, 1])
            assert not any(p + 1 in te or p - 1 in te for p in tr)
        assert set(np.unique(s.y[test])) == set(range(4))  # every recording in every test fold
        assert not set(s.groups[train]) & set(s.groups[test])  # the groups say what the folds kept apart
    assert "time blocks" in s.split


def test_recording_grouped_folds(recordings):
    rec = make_vibration_recordings(3, duration_s=4, n_sessions=3, random_state=1)
    s = vibration_samples(rec, 400, n_folds=5)
    ds = rec.windows(400)
    owner = {w.tobytes(): int(r) for w, r in zip(ds.windows.numpy(), ds.recording, strict=True)}
    recs = np.array([owner[w.tobytes()] for w in s.X])
    assert len(s.folds) == 3 and "grouped by session" in s.split
    for train, test in s.folds:
        assert not set(recs[train]) & set(recs[test])
        assert not set(s.groups[train]) & set(s.groups[test])
    with pytest.raises(ValueError, match="longer than every recording of class"):
        vibration_samples(recordings, 20000, n_folds=5)


def test_bad_input_gets_one_clear_line(tmp_path, recordings, capsys):
    with pytest.raises(FileNotFoundError, match="no such file"):
        load_tradeoff_data(tmp_path / "missing.npz")
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match=r"notes\.txt: expected a data file"):
        load_tradeoff_data(tmp_path / "notes.txt")
    np.savez(tmp_path / "other.npz", pictures=np.zeros(3))
    with pytest.raises(ValueError, match="expected image explorations"):
        load_tradeoff_data(tmp_path / "other.npz")
    y = np.array([0, 0, 0, 1])
    data = TradeoffData("features", ("a", "b"), "", raw=np.zeros((4, 3)), labels=y)
    with pytest.raises(ValueError, match="class 'b' has too few samples"):
        exploration_samples(data, n_folds=5)
    path = recordings.save(tmp_path / "rec.npz")
    assert main(["tradeoff", "--data", str(path), "--window", "100000", "--out", str(tmp_path / "o")]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("[tradeoff]")]
    assert len(errors) == 1 and "window: 100000 samples is longer than every recording" in errors[0]
    assert main(["tradeoff", "--data", str(tmp_path / "other.npz"), "--out", str(tmp_path / "o")]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 1 and errors[0].startswith("tactile-torch tradeoff: ")  # no traceback
    # data the study cannot compare models on, named before any work: one class, values that are not finite
    from tactile_torch.data.vibration import VibrationRecordings
    from tactile_torch.tradeoff.runner import plan_tradeoff
    from tactile_torch.tradeoff.validation import check_two_classes

    with pytest.raises(ValueError, match=r"data: f holds a single class \('a'\)"):
        check_two_classes(
            TradeoffData("features", ("a",), "f: 4 samples", raw=np.zeros((4, 3)), labels=np.zeros(4))
        )

    one = VibrationRecordings(
        recordings.signals[:1] * 2, np.array([0, 0]), ("glass",), 800.0, np.array(["1", "2"])
    )
    with pytest.raises(
        ValueError, match=r"holds a single class \('glass'\); comparing classifiers needs .* two"
    ):
        plan_tradeoff(one.save(tmp_path / "one.npz"), log=lambda s: None)
    from tactile_torch.robot.files.formats import RecordingArrays
    from tactile_torch.tradeoff.inputs import vibration_data

    signals = [np.array(s, copy=True) for s in recordings.signals]
    signals[1][7, 2] = np.inf  # 1e308 in a CSV read with --sensor-range inf, as float32
    overflow = RecordingArrays(signals, recordings.labels, recordings.class_names, 800.0)
    with pytest.raises(
        ValueError, match=r"'aluminium' holds 1 value\(s\) that are not finite .* sample 7, axis z"
    ):
        plan_tradeoff(vibration_data(overflow, "logs"), log=lambda s: None)
    signals[1][7, 2] = np.finfo(np.float32).max  # 1e308 saturated by a reader instead of overflowing
    saturated = RecordingArrays(signals, recordings.labels, recordings.class_names, 800.0)
    with pytest.raises(
        ValueError, match=r"'aluminium' holds 1 value\(s\) that are not finite .* sample 7, axis z"
    ):
        plan_tradeoff(vibration_data(saturated, "logs"), log=lambda s: None)
    signals[1][7, 2] = 1e30  # beyond any accelerometer: its features overflow float32 (status 4 before)
    huge = RecordingArrays(signals, recordings.labels, recordings.class_names, 800.0)
    huge.sources = [f"day{i}/{recordings.class_names[c]}.csv" for i, c in enumerate(recordings.labels)]
    with pytest.raises(
        ValueError,
        match=r"logs: day1/aluminium\.csv: the recording of 'aluminium' holds 1 value\(s\) .* "
        r"axis z: 1e\+30; .* beyond 1e\+15 g",
    ):
        plan_tradeoff(vibration_data(huge, "logs"), log=lambda s: None)


# ---------------------------------------------------------------------------------------- the study
def test_cached_features_equal_fitting_the_whole_pipeline(recordings):
    """Stage 1 computes stateless features once; the result equals cloning and fitting each pipeline."""
    s = vibration_samples(recordings, 400, n_folds=3)
    sets, _ = feature_sets("vibration", (), windows=[400], quick=True)
    candidates = build_candidates(sets[:2], classifiers=["LDA", "NCM"])
    results = cross_validate(candidates, {s.key: s}, progress=False)
    for res in results:
        assert len(res.params) == len(s.folds) and all(res.params)  # tuned in every fold
        for k, (train, test) in enumerate(s.folds):
            model = clone(res.candidate.estimator).set_params(**res.params[k]).fit(s.X[train], s.y[train])
            assert res.fold_accuracy[k] == pytest.approx(np.mean(model.predict(s.X[test]) == s.y[test]))


@pytest.mark.slow  # 36 s on a quiet 2-core machine: the default run stays under 10 minutes (make test-all runs it)
def test_tradeoff_command_on_vibration_recordings(tmp_path, capsys):
    rec = make_vibration_recordings(3, duration_s=6, n_sessions=2, random_state=5)
    path = rec.save(tmp_path / "rec.npz")
    out = tmp_path / "study"
    argv = [
        "tradeoff",
        "--data",
        str(path),
        "--out",
        str(out),
        "--quick",
        "--quiet",
        "--classifiers",
        "LDA,NCM",
    ]
    assert main([*argv, "--windows", "400", "--no-breaking"]) == 0  # see the next test
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("recommended: ") and printed[1].startswith("runner-up:")
    assert "95 % interval for a new session" in printed[0]  # the unit next to the interval
    assert printed[2].startswith("baselines:   chance 0.333, majority class")
    doc = json.loads((out / "tradeoff.json").read_text())
    rows = {r["name"]: r for r in doc["candidates"]}
    assert len(rows) >= 3 and doc["recommended"] in rows
    fields = (
        "accuracy",
        "accuracy_low",
        "accuracy_high",
        "fit_s",
        "latency_ms",
        "size_bytes",
        "decision_s",
        "pareto",
    )
    for r in rows.values():
        assert all(r[f] is not None for f in fields)
        assert r["accuracy_low"] <= r["accuracy"] <= r["accuracy_high"] and r["onnx_agreement"] == 1.0
        # each cost is measured on a file: the timing file's, or the deployed file's for a deployed
        # candidate (the recommended one: recommended.onnx), the timing file's then kept beside it
        timing = (out / "timing" / r["timing_onnx_file"]).stat().st_size
        assert r.get("timing_size_bytes", r["size_bytes"]) == timing
        assert (
            r["size_bytes"] == (out / r.get("measured_on", f"timing/{r['timing_onnx_file']}")).stat().st_size
        )
        assert r["unit"] == "session" and r["n_units"] == 6 and r["interval"] == "prediction"
    rec_row = rows[doc["recommended"]]
    best = max(rows.values(), key=lambda r: r["accuracy"])
    assert rec_row["pareto"] and rec_row["accuracy"] >= best["accuracy"] - best["accuracy_se"] - 1e-12
    for r in rows.values():
        assert "W = 400" in r["features"] and r["decision_s"] == pytest.approx(
            400 / 800 + r["latency_ms"] / 1e3
        )
    for chart in ("accuracy-vs-latency.png", "accuracy-vs-size.png", "accuracy-vs-decision.png"):
        assert (out / "figures" / chart).read_bytes()[:4] == b"\x89PNG"
    assert "runner-up" in (out / "tradeoff.md").read_text()
    from tactile_torch.robot.runtime import OnnxPipeline

    pipe = OnnxPipeline(out / "recommended.onnx")  # refitted on all the data
    windows = rec.windows(pipe.input_shape[-1]).windows.numpy()
    assert pipe.metadata["tactile_torch.pipeline"].startswith(
        f"tradeoff: {doc['recommended']}, fitted on all"
    )
    assert doc["deployed"][0]["onnx"] == "recommended.onnx" and doc["deployed"][0]["agreement"] == 1.0
    # the model file exports to a graph that gives the same labels
    assert (
        main(["export", "--model", str(out / "recommended.npz"), "--out", str(tmp_path / "again.onnx")]) == 0
    )
    again = OnnxPipeline(tmp_path / "again.onnx")
    np.testing.assert_array_equal(again.predict(windows), pipe.predict(windows))
    assert pipe.sealed and again.sealed  # joined front and head, and re-exported: both carry their digest


@pytest.mark.slow  # ~27 s: the sweeps themselves are tested in tests/robustness/test_robustness.py; keeps make test near 10 min
def test_tradeoff_command_writes_the_breaking_points(tmp_path, capsys):
    """The recommended and the study's model swept by tactile_torch.robustness: table and charts in DIR."""
    rec = make_vibration_recordings(3, duration_s=6, n_sessions=2, random_state=5)
    path = rec.save(tmp_path / "rec.npz")
    out = tmp_path / "study"
    argv = [
        "tradeoff",
        "--data",
        str(path),
        "--out",
        str(out),
        "--quick",
        "--quiet",
        "--classifiers",
        "LDA,HM-SVM",
    ]
    assert main([*argv, "--windows", "400", "--folds", "2"]) == 0
    doc = json.loads((out / "tradeoff.json").read_text())
    rows = doc["breaking_points"]["rows"]
    models = {r["model"] for r in rows}
    assert any(m.startswith("recommended") for m in models) and any("study's model" in m for m in models)
    assert {r["factor"] for r in rows} >= {"feature SNR", "sensor noise", "window", "training samples"}
    assert all(r["breaks at [95 % CI]"] for r in rows)
    for figure in doc["breaking_points"]["figures"]:
        assert (out / figure).read_bytes()[:4] == b"\x89PNG"
    md = (out / "tradeoff.md").read_text()
    assert "## Breaking points" in md and "breaking-sensor-noise.png" in md
    assert "drift" in str(doc["breaking_points"]["skipped"])  # no positions within recordings here


@pytest.mark.slow  # 27 s on a quiet 2-core machine: the default run stays under 10 minutes (make test-all runs it)
def test_tradeoff_on_small_taxel_arrays(tmp_path, monkeypatch):
    """Raw pressure maps of a 6 x 6 array (raw counts, resting at 200) through the same study; nothing is
    written outside ``out_dir`` (the working directory stays empty)."""
    from tactile_torch.tradeoff import run_tradeoff, write_outputs

    data = make_explorations(3, n_frames=6, frame_size=24, sensels=6, random_state=1, keep_pressure=True)
    path = tmp_path / "taxels.npz"
    np.savez(
        path,
        frames=200.0 + data.pressure.numpy(),
        labels=data.labels.numpy(),
        class_names=np.array(data.class_names),
        frame_rate_hz=10.0,  # explorations state their rate: it is never assumed (issue 42)
    )
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    result = run_tradeoff(  # the per-frame ablation runs through the same step as the fused features
        path,
        features=["fused", "per-taxel"],
        quick=True,
        out_dir=tmp_path / "o",
        classifiers=["LDA"],
        n_folds=3,
        progress=False,
        log=lambda s: None,
        background=False,
        deploy=["LDA | per-taxel 252"],
    )
    assert list(cwd.iterdir()) == []
    assert list((tmp_path / "o" / "timing").glob("*.onnx"))  # the timing files, under out_dir only
    features = [r["features"] for r in result.rows]
    assert features == ["fused 12", "per-taxel 252"]
    assert all(r["onnx_agreement"] == 1.0 for r in result.rows)
    assert "stratified" in result.splits["pressure"]
    assert result.study_model is None  # no HM-SVM among the candidates
    # the hook for the breaking-point study: its rows go into the JSON and the markdown
    result.breaking_points = {
        "rows": [{"factor": "frames", "candidate": "LDA | fused 12", "breaking point": 3.0}]
    }
    paths = write_outputs(result, tmp_path / "o")
    assert json.loads(paths["json"].read_text())["breaking_points"]["rows"][0]["breaking point"] == 3.0
    assert "## Breaking points" in paths["md"].read_text()
    _check_touch_time_and_live_metadata(result, tmp_path / "o")


def _check_touch_time_and_live_metadata(result, out):
    """Frame data: accuracy against time into the touch (held-out prefixes brought to T frames as the
    stream brings them), and the deployed bundle's touch levels, frame rate, value range and early rule."""
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.early_decision import EarlyRule
    from tactile_torch.robot.stream.touches import TouchLevels, fit_frames
    from tactile_torch.tradeoff.touch_time import (
        draw_touch_time,
        fold_scores,
        prefixes,
        touch_time,
        touch_time_markdown,
    )

    name = "LDA | per-taxel 252"
    res, s = result.result(name), result.inputs["pressure"]
    curve = touch_time(res, s, result.data.rate_hz, quick=True)
    assert [r["frames"] for r in curve.rows] == [2, 3, 4, 6] and curve.seconds[-1] == pytest.approx(0.6)
    assert curve.rows[-1]["accuracy"] == pytest.approx(result.row(name)["accuracy"])  # the study's own
    assert curve.margins.shape == (len(s.y), 3) and curve.rule.touches == len(s.y)
    # the prefix scores are those of the fold model's exported graph: its labels are the model's predict
    model, test = res.cv.models[0], s.folds[0][1]
    prefix = np.stack([fit_frames(x[:3], 6) for x in s.X[test]])
    labels, _ = fold_scores(model, prefix)
    assert np.array_equal(model.steps[-1][1].classes_[labels], model.predict(prefix))
    # a fused step's features of a stretched prefix are those of the prefix itself (the OR of repeated frames)
    fused = result.result("LDA | fused 12").cv.models[0].steps[0][1]
    stretched = np.stack([fit_frames(x[:2], 6) for x in s.X[:4]])
    assert np.allclose(fused.transform(stretched), fused.transform(prefixes(s.X[:4], 2, fused)), atol=1e-9)
    assert touch_time_markdown({name: curve}, "f.png")[0] == "## Accuracy against time into the touch"
    assert draw_touch_time({name: curve}, out / "t.png", chance=0.25).read_bytes()[:4] == b"\x89PNG"
    bundle = OnnxPipeline(out / "lda-per-taxel-252.onnx")
    meta = bundle.metadata
    assert float(meta["frame_rate_hz"]) == 10.0 and json.loads(meta["value_range"])[0] < 200.0
    levels = TouchLevels.from_metadata(meta["touch_levels"], (6, 6))
    assert levels.sign == 1.0 and levels.onset > levels.release > 0 and "training data" in levels.source
    rule = EarlyRule.from_metadata(meta["early_decision"])
    assert rule.checkpoints == (2, 3, 4) and rule.touches == len(s.y)


@pytest.mark.slow
def test_tradeoff_on_real_taxel_arrays(tmp_path):
    """The Schunk hand's 14 x 6 arrays (drimus_sdh_tactile): raw counts with a resting level."""
    from tactile_torch.tradeoff import run_tradeoff

    root = require_shared_data("drimus_sdh_tactile")
    maps, labels = [], []
    for f in sorted((root / "grasps_npz").glob("*.npz")):
        with np.load(f) as g:
            maps.append(g["ts1_f1_proximal"][-30:].astype(np.float32))
            labels.append(int(g["label"]))
    path = tmp_path / "drimus.npz"
    np.savez(
        path,
        frames=np.stack(maps),
        labels=np.array(labels),
        class_names=np.array(list("ABCDE")),
    )
    result = run_tradeoff(
        path, quick=True, frame_rate_hz=15.0, out_dir=tmp_path / "o", progress=False, log=lambda s: None
    )
    assert len(result.rows) >= 5 and result.row(result.recommended)["pareto"]


def _tiny_model(value: float, path):
    """Write a one-node ONNX model (an identity) to ``path``; the value only tags the job."""
    import onnx
    from onnx import TensorProto, helper

    graph = helper.make_graph(
        [helper.make_node("Identity", ["x"], ["y"])],
        f"g{value}",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1])],
    )
    onnx.save(helper.make_model(graph), str(path))
    return path


def test_export_pool_runs_jobs_once_and_survives_a_dead_background_process(tmp_path):
    from tactile_torch.export.parts import ExportPool

    calls = []

    def failing(path):
        calls.append(path)
        raise RuntimeError("cannot export this")

    with ExportPool(tmp_path / "parts", background=False) as pool:
        pool.submit("bad", failing)
        for _ in range(2):  # the error again, without a second attempt
            with pytest.raises(RuntimeError, match="cannot export this"):
                pool.result("bad")
        assert len(calls) == 1
    with ExportPool(tmp_path / "parts", background=True) as pool:
        pool._process.kill()
        pool._process.wait()
        pool.submit("job", _tiny_model, 1.0)  # cannot reach the background process: runs here
        assert pool.result("job").graph.name == "g1.0"
        assert pool.result("job") is pool.result("job")
    assert not (tmp_path / "parts").exists()


@pytest.mark.slow
def test_report_section_smoke_run(tmp_path):
    from tactile_torch.studies import run_report

    text = run_report(tmp_path, quick=True, only=["tradeoff"], log=lambda s: None).read_text()
    # one verdict per method: the vibration part recommends; the quick image set (12 explorations in 3 folds)
    # has no candidate significantly above the baseline, and says so
    assert text.count("**recommended: ") == 1 and text.count("**no recommendation: ") == 1
    assert (
        text.index("**recommended: ") < text.index("### Tactile images") < text.index("**no recommendation: ")
    )
    assert "accuracy-vs-decision.png" in text
    assert json.loads((tmp_path / "tradeoff" / "vibration" / "tradeoff.json").read_text())["recommended"]


# ------------------------------------------------------------------------- honest intervals (issue 19)
def test_unit_interval_is_a_t_prediction_interval_over_units():
    from tactile_torch.tradeoff.selection import unit_interval

    correct, count = np.array([45, 40, 48, 30, 44, 38]), np.full(6, 50)
    acc = correct / count
    u = unit_interval(correct, count)
    half = stats.t.ppf(0.975, 5) * acc.std(ddof=1) * np.sqrt(1 + 1 / 6)
    assert u.kind == "prediction" and u.mean == pytest.approx(acc.mean())
    assert (u.low, u.high) == pytest.approx((acc.mean() - half, min(1.0, acc.mean() + half)))
    assert u.se == pytest.approx(acc.std(ddof=1) / np.sqrt(6))
    # wider than the confidence interval of the mean by sqrt(g + 1)
    assert (u.high - u.low) > 2 * stats.t.ppf(0.975, 5) * u.se * 2


def test_unit_interval_never_claims_certainty_and_gives_the_range_below_five_units():
    from tactile_torch.tradeoff.selection import MIN_UNITS, unit_interval

    perfect = unit_interval(np.full(6, 20), np.full(6, 20))  # every unit at 1.0: binomial floor on the spread
    assert perfect.kind == "prediction" and perfect.low < 0.95 and perfect.high == 1.0
    few = unit_interval([20, 20, 20], [20, 20, 20])
    assert few.kind == "range" and (few.low, few.high) == (1.0, 1.0) and MIN_UNITS == 5
    spread = unit_interval([10, 15, 20], [20, 20, 20])
    assert spread.kind == "range" and (spread.low, spread.high) == (0.5, 1.0)
    with pytest.raises(ValueError, match="count must be > 0"):
        unit_interval([1], [0])


def test_baseline_and_the_choice_with_and_without_a_target():
    from tactile_torch.tradeoff.selection import above_baseline, choose, majority_predictions, unit_interval

    y = np.array([0, 0, 0, 1, 1, 2] * 4)
    folds = [
        (np.flatnonzero(np.arange(24) // 6 != k), np.flatnonzero(np.arange(24) // 6 == k)) for k in range(4)
    ]
    assert (majority_predictions(y, folds) == 0).all()
    base = unit_interval(np.array([3, 3, 3, 3, 3]), np.full(5, 6))
    good = unit_interval(np.array([5, 6, 5, 6, 5]), np.full(5, 6))
    poor = unit_interval(np.array([3, 4, 2, 3, 3]), np.full(5, 6))
    assert above_baseline(good, base)[0] and not above_baseline(poor, base)[0]
    acc, se = np.array([0.9, 0.88, 0.6]), np.array([0.02, 0.02, 0.02])
    low, cost = np.array([0.8, 0.7, 0.5]), np.array([3.0, 1.0, 0.5])
    assert choose(acc, se, low, cost) == 1  # one standard error: the cheaper of the two best
    assert choose(acc, se, low, cost, adequate=[True, False, True]) == 0
    assert choose(acc, se, low, cost, adequate=[False, False, False]) is None
    assert choose(acc, se, low, cost, target=0.75) == 0  # only its lower end reaches 0.75
    assert choose(acc, se, low, cost, target=0.65) == 1  # the cheapest that does
    assert choose(acc, se, low, cost, target=0.85) is None
    with pytest.raises(ValueError, match="target must be an accuracy in"):
        choose(acc, se, low, cost, target=1.5)


def test_csv_sessions_come_from_the_trailing_number(tmp_path):
    from tactile_torch.robot.files.csv_logs import write_csv_recording

    rng = np.random.default_rng(0)
    paths = [
        write_csv_recording(tmp_path / f"{name}_{k}.csv", rng.normal(size=(400, 3)).astype(np.float32), 800.0)
        for name in ("felt", "cork")
        for k in (1, 2, 3)
    ]
    data = load_tradeoff_data(paths)
    assert sorted(data.recordings.session.tolist()) == ["1", "1", "2", "2", "3", "3"]
    s = vibration_samples(data.recordings, 100, n_folds=5)
    assert s.unit == "session" and sorted(set(s.units.tolist())) == [0, 1, 2]
    from tactile_torch.tradeoff.summary import _unit_warnings

    (line,) = _unit_warnings({s.key: s})  # three sessions: one line, the range instead of an interval
    assert line.startswith("warning: only 3 sessions in the data: accuracies are given as the range")
    assert "3 folds grouped by session" in s.split
    from tactile_torch.tradeoff.runner import plan_tradeoff

    with pytest.raises(ValueError, match=r"n_folds: 4 folds asked, but the data allow 3"):
        plan_tradeoff(paths, n_folds=4, exact_folds=True, windows=[100], log=lambda s: None)
    from tactile_torch.robot.files.data_sources import DataOptions

    by_file = load_tradeoff_data(paths, options=DataOptions(session_from="recording"))
    assert sorted(by_file.recordings.session.tolist())[0] == "cork_1"


def test_units_of_explorations_and_time_blocks(recordings):
    s = vibration_samples(recordings, 400, n_folds=4)  # one recording per class: time blocks
    assert s.unit == "time block" and sorted(set(s.units.tolist())) == [0, 1, 2, 3]
    for k, (_, test) in enumerate(s.folds):
        assert (s.units[test] == k).all()
    X, y = _blobs(40, 4, 2)
    plain = exploration_samples(TradeoffData("features", ("a", "b"), "blobs", raw=X, labels=y), n_folds=4)
    assert plain.unit == "fold" and sorted(set(plain.units.tolist())) == [0, 1, 2, 3]


# ------------------------------------------------------------------- feature files, atomic output
@pytest.mark.parametrize(
    "dtype",
    # 21 s each on a quiet 2-core machine: both slow, so the default run stays under 10 minutes
    [pytest.param(np.float32, marks=pytest.mark.slow), pytest.param(np.float64, marks=pytest.mark.slow)],
)
def test_tradeoff_on_a_feature_file_exports_and_recommends(tmp_path, capsys, dtype):
    from tactile_torch.robot.runtime import OnnxPipeline

    X, y = _blobs(90, 5, 3, seed=1)
    path = tmp_path / "feat.npz"
    np.savez(path, features=X.astype(dtype), labels=y)
    out = tmp_path / "o"
    argv = [
        "tradeoff",
        "--data",
        str(path),
        "--out",
        str(out),
        "--quick",
        "--quiet",
        "--classifiers",
        "LDA,NCM",
        "--no-breaking",  # the breaking points have their own test
    ]
    assert main(argv) == 0
    doc = json.loads((out / "tradeoff.json").read_text())
    assert doc["status"] == "recommended" and all(r["onnx_agreement"] == 1.0 for r in doc["candidates"])
    pipe = OnnxPipeline(out / "recommended.onnx")
    assert np.mean(pipe.predict(X) == y) > 0.8
    assert main(["export", "--model", str(out / "recommended.npz"), "--out", str(tmp_path / "m.onnx")]) == 0
    np.testing.assert_array_equal(OnnxPipeline(tmp_path / "m.onnx").predict(X), pipe.predict(X))
    assert pipe.sealed and OnnxPipeline(tmp_path / "m.onnx").sealed


@pytest.mark.slow  # 17 s on a quiet 2-core machine: the default run stays under 10 minutes (make test-all runs it)
def test_a_failed_run_leaves_the_previous_result_intact(tmp_path, monkeypatch, capsys):
    from tactile_torch.tradeoff import output

    X, y = _blobs(60, 4, 3, seed=2)
    path = tmp_path / "feat.npz"
    np.savez(path, features=X, labels=y)
    out = tmp_path / "o"
    argv = ["tradeoff", "--data", str(path), "--out", str(out), "--quick", "--quiet", "--classifiers", "NCM"]
    argv += ["--no-breaking", "--no-tune"]  # what is written, not what is measured, is under test
    (out / "timing").mkdir(parents=True)  # a previous result (a successful run's is checked above)
    (out / "tradeoff.json").write_text('{"previous": true}')
    (out / "timing" / "NCM.onnx").write_bytes(b"previous graph")
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}

    def broken(result, out_dir, **kwargs):  # dies half-way through writing the outputs
        (output.Path(out_dir) / "tradeoff.json").write_text("{half")
        raise RuntimeError("killed while writing")

    monkeypatch.setattr("tactile_torch.tradeoff.write_outputs", broken)
    assert main(argv) == 1
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before
    assert not list(tmp_path.glob(".o.partial-*"))  # the staging directory is gone


@pytest.mark.slow  # a subprocess (torch import, a study): the default run has the simulated failure above
def test_a_killed_run_leaves_the_previous_result_intact(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time

    X, y = _blobs(60, 4, 3, seed=3)
    path = tmp_path / "feat.npz"
    np.savez(path, features=X, labels=y)
    out = tmp_path / "o"
    (out / "timing").mkdir(parents=True)
    (out / "tradeoff.json").write_text('{"previous": true}')
    argv = [sys.executable, "-m", "tactile_torch.cli", "tradeoff", "--data", str(path), "--out", str(out)]
    proc = subprocess.Popen([*argv, "--quick", "--quiet", "--classifiers", "NCM,LDA"], env=os.environ.copy())
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".o.partial-*/timing")) and time.monotonic() < deadline:
        time.sleep(0.05)  # wait until it writes into its staging directory
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert (out / "tradeoff.json").read_text() == '{"previous": true}'
    assert sorted(p.name for p in out.iterdir()) == ["timing", "tradeoff.json"]
    from tactile_torch.tradeoff.output import staged_output

    with staged_output(out):  # the next run removes what the killed one left
        pass
    assert not list(tmp_path.glob(".o.partial-*"))


@pytest.mark.slow  # 16 s on a quiet 2-core machine: the default run stays under 10 minutes (make test-all runs it)
def test_no_adequate_candidate_recommends_nothing(tmp_path, capsys):
    from tactile_torch.cli import NO_RECOMMENDATION_EXIT

    rng = np.random.default_rng(4)
    path = tmp_path / "noise.npz"
    np.savez(path, features=rng.normal(size=(60, 4)), labels=np.arange(60) % 3)
    out = tmp_path / "o"
    argv = [
        "tradeoff",
        "--data",
        str(path),
        "--out",
        str(out),
        "--quick",
        "--quiet",
        "--classifiers",
        "NCM,LDA",
    ]
    assert main([*argv, "--target", "0.95"]) == NO_RECOMMENDATION_EXIT
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("no recommendation: no candidate's interval reaches the target 0.950")
    doc = json.loads((out / "tradeoff.json").read_text())
    assert doc["status"] == "none adequate" and doc["recommended"] is None and doc["target"] == 0.95
    assert not (out / "recommended.onnx").exists()


# --------------------------------------------------------------------------- train every method
@pytest.mark.parametrize(  # svc and hmsvm: 6 s each, slow (the default run stays under 10 minutes)
    "method",
    [
        "lda",
        "knn",
        "ncm",
        pytest.param("svc", marks=pytest.mark.slow),
        pytest.param("hmsvm", marks=pytest.mark.slow),
    ],
)
def test_train_writes_every_catalogue_method_and_export_reproduces_it(tmp_path, capsys, method):
    from tactile_torch.features.files import load_features
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.training import load_model, train_classifier

    X, y = _blobs(60, 6, 3, seed=5)
    data = tmp_path / "feat.npz"
    np.savez(data, features=X, labels=y)
    model_path, onnx_path = tmp_path / "m.npz", tmp_path / "m.onnx"
    argv = ["train", "--data", str(data), "--method", method, "--select", "4", "--out", str(model_path)]
    assert main(argv) == 0
    assert load_model(model_path).method == ("svm" if method == "svc" else method)
    assert main(["export", "--model", str(model_path), "--out", str(onnx_path)]) == 0
    trained = train_classifier(load_features(data), method, select=4, random_state=0)
    np.testing.assert_array_equal(OnnxPipeline(onnx_path).predict(X), trained.predict(X))


# -------------------------------------------------------------------------------------- charts
def _synthetic_rows(n, seed=0):
    rng = np.random.default_rng(seed)
    classifiers = ["HM-SVM", "SVC", "LDA", "kNN", "NCM"]
    features = [
        "21 features, W = 200",
        "21 features, W = 800",
        "top 7 of 21, W = 800",
        "top 3 of 21, W = 800",
    ]
    rows = []
    for i in range(n):
        acc = float(np.clip(rng.normal(0.85, 0.08), 0.3, 0.99))
        rows.append(
            {
                "name": f"{classifiers[i % 5]} | {features[(i // 5) % 4]} #{i}",
                "classifier": classifiers[i % 5],
                "features": features[(i // 5) % 4],
                "accuracy": acc,
                "accuracy_low": max(0.0, acc - 0.1),
                "accuracy_high": min(1.0, acc + 0.06),
                "unit": "session",
                "latency_ms": float(rng.uniform(0.12, 0.26)),
                "size_bytes": int(rng.uniform(8e3, 3e6)),
                "decision_s": float(rng.choice([0.25, 1.0, 2.0])) + 1e-4,
            }
        )
    return rows


@pytest.mark.parametrize("n", [5, 15, 40])
def test_charts_for_5_to_40_candidates(tmp_path, n):
    from tactile_torch.tradeoff.charts import CHARTS, draw_chart, feature_family

    rows = _synthetic_rows(n)
    for which in CHARTS:
        path = draw_chart(
            rows,
            which,
            tmp_path / f"{which}-{n}.png",
            recommended=rows[1]["name"],
            runner_up=rows[2]["name"],
            chance=0.2,
            baseline=0.25,
            target=0.8,
        )
        assert path.read_bytes()[:4] == b"\x89PNG"
    # every subset size has its own marker (top 3 and top 7 apart), windows apart
    assert {feature_family(r["features"]).split(",")[0] for r in rows} <= {"all features", "top 7", "top 3"}


def test_charts_draw_every_point_at_its_cost_and_zoom_into_dense_ranges(tmp_path, monkeypatch):
    """Points are never moved: equal costs are shown side by side in a zoomed panel of their range."""
    import matplotlib
    import matplotlib.pyplot as plt

    matplotlib.use("Agg")
    from tactile_torch.tradeoff.charts import DENSE_MIN, dense_ranges, draw_chart

    x = np.array([0.2001, 0.2003, 0.2002, 0.2004, 0.2005, 0.8001, 0.8002, 1.6])
    ranges = dense_ranges(x, log=True)
    assert [sorted(r.tolist()) for r in ranges] == [[0, 1, 2, 3, 4]]  # 0.8 s holds 2 < DENSE_MIN
    assert dense_ranges(x[: DENSE_MIN - 1], log=False) == []
    rows = _synthetic_rows(20)
    kept = []
    monkeypatch.setattr(plt, "close", kept.append)
    draw_chart(rows, "decision", tmp_path / "d.png", recommended=rows[0]["name"], runner_up=rows[1]["name"])
    fig = kept[-1]
    main = fig.axes[0]
    costs = {round(r["decision_s"], 9) for r in rows}
    drawn = {
        round(float(v), 9)
        for line in main.get_lines()
        if line.get_marker() not in ("None", "", None)
        for v in line.get_xdata()
    }
    assert drawn <= costs  # every marker of the main panel sits at a measured cost
    assert len(fig.axes) >= 2  # the three windows' candidates share a cost: zoomed, not spread


def test_an_int8_variant_below_its_float_interval_is_flagged_in_rows_lines_and_chart(tmp_path, monkeypatch):
    """mark_int8_losses: the loss and the flag, the note, the one-line description, the chart's legend."""
    import matplotlib

    matplotlib.use("Agg")
    from tactile_torch.tradeoff.charts import draw_chart
    from tactile_torch.tradeoff.output import describe
    from tactile_torch.tradeoff.summary import mark_int8_losses

    base = _synthetic_rows(2)
    for r in base:
        r.update(accuracy=0.9, accuracy_low=0.85, accuracy_high=0.95, interval="range", n_units=4, notes=[])
    close = dict(
        base[0], name=base[0]["name"] + " (int8)", variant_of=base[0]["name"], accuracy=0.86, notes=[]
    )
    lost = dict(
        base[1], name=base[1]["name"] + " (int8)", variant_of=base[1]["name"], accuracy=0.80, notes=[]
    )
    for r in (close, lost):
        r["quantisation"] = "dynamic"
    rows = [*base, close, lost]
    mark_int8_losses(rows)
    assert (
        close["int8_degraded"] is False and close["notes"] == [] and close["int8_loss"] == pytest.approx(0.04)
    )
    assert lost["int8_degraded"] is True and lost["int8_loss"] == pytest.approx(0.10)
    assert "below the float model's range [0.850, 0.950] per session" in lost["notes"][0]
    assert "int8 loses 0.100 against its float model" in describe(lost) and "int8 loses" not in describe(
        close
    )
    assert "int8_loss" not in base[0]  # float models are left as they are
    import matplotlib.axes

    fig_calls, original = [], matplotlib.axes.Axes.legend

    def spy(self, *args, **kwargs):
        fig_calls.append([h.get_label() for h in kwargs.get("handles", [])])
        return original(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.axes.Axes, "legend", spy)
    draw_chart(rows, "latency", tmp_path / "int8.png", chance=0.2)
    assert any("int8 below its float interval" in labels for labels in fig_calls)
    assert (tmp_path / "int8.png").read_bytes()[:4] == b"\x89PNG"


def test_an_interval_of_the_whole_range_is_said_and_notes_are_said_once():
    from tactile_torch.tradeoff.output import grouped_notes, whole_range, why_whole_range

    row = {
        "accuracy_low": 0.0, "accuracy_high": 1.0, "interval": "range", "unit": "session", "n_units": 3,
        "baseline_p": 0.03, "unit_accuracy": [{"accuracy": 0.0}, {"accuracy": 1.0}, {"accuracy": 1.0}],
    }  # fmt: skip
    assert whole_range(row) and not whole_range({**row, "accuracy_low": 0.2})
    why = why_whole_range(row)
    assert "its 3 sessions score 0.00 to 1.00" in why and "fewer than 5 sessions give their range" in why
    assert "p = 0.03" in why and "more sessions narrow it" in why
    notes = grouped_notes(
        [
            {"name": "A", "notes": ["tuned on 3 grouped folds of each training fold"]},
            {"name": "B", "notes": ["tuned on 3 grouped folds of each training fold", "its own"]},
            {"name": "C", "notes": ["tuned on 3 grouped folds of each training fold"]},
        ]
    )
    assert notes == ["tuned on 3 grouped folds of each training fold (3 candidates: A, B, C)", "B: its own"]


def test_breaking_points_doubted_where_a_degradation_helps_or_a_range_below_gravity_costs_nothing():
    from types import SimpleNamespace

    from tactile_torch.robustness.degradations import FACTORS
    from tactile_torch.tradeoff.breaking import plausibility_notes

    factor = {f.name: f for f in FACTORS}
    X = np.zeros((4, 3, 50), dtype=np.float32)
    X[:, 2] = 1.0  # gravity on z
    X[:, 0] = np.sin(np.arange(50))[None] * 0.01  # small vibration on x
    curves = [
        SimpleNamespace(
            factor=factor["saturation"], model="LDA", levels=(0.5, 0.02), accuracy=np.array([0.9, 0.9]),
            low=np.array([0.85, 0.85]), clean=0.9, clean_low=0.85,
        ),
        SimpleNamespace(
            factor=factor["sample rate"], model="CNN", levels=(2, 4), accuracy=np.array([0.99, 0.7]),
            low=np.array([0.97, 0.6]), clean=0.94, clean_low=0.9,
        ),
    ]  # fmt: skip
    notes = plausibility_notes(curves, X)
    assert any(
        n.startswith("saturation at ±0.02 g, below the data's own level") and "z: 100%" in n for n in notes
    )
    assert any(n.startswith("sample rate at") and "above its clean 0.940" in n for n in notes)
    assert len(notes) == 2  # one per curve: the harshest range that costs nothing (±0.5 g costs nothing too)
