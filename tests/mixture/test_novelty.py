"""New surfaces (issue 22, point 3): the calibrated novelty rule, over one window and N, in the estimator, the graph and the stream."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from tactile_torch.mixture import PitmanYorGMM
from tactile_torch.mixture._novelty import calibrate_thresholds, novel_after, window_means
from tactile_torch.robot.stream.discovery import SurfaceDiscovery


def _three_known_one_new(seed=0, per=60):
    """Rows in time order: 3 known Gaussian clusters in D = 3 and a fourth, new one, 3 sd from its nearest."""
    rng = np.random.default_rng(seed)
    centres = np.array([[0.0, 0.0, 0.0], [6.0, 0.0, 0.0], [0.0, 6.0, 0.0], [3.0, 3.0, 0.0]])
    X = np.concatenate([rng.normal(c, 1.0, size=(per, 3)) for c in centres])
    return X, np.repeat(np.arange(4), per)


@pytest.fixture()
def fitted():
    X, y = _three_known_one_new()
    known = y < 3
    first = np.tile(np.arange(60), 4) < 30  # first half of each cluster: training
    model = PitmanYorGMM(n_iter=200, burn_in=50, n_chains=2, random_state=0, progress=False)
    model.fit(X[known & first])
    return model, X, y, first


def test_window_means_and_thresholds_on_known_values():
    score = np.array([0.0, 1.0, 2.0, 3.0, 10.0, 20.0])
    groups = np.array([0, 0, 0, 0, 1, 1])
    np.testing.assert_allclose(window_means(score, 2, groups), [np.nan, 0.5, 1.5, 2.5, np.nan, 15.0])
    np.testing.assert_allclose(window_means(score, 1), score)
    t = calibrate_thresholds(score, 0.5, 5, groups)
    assert t[0] == 3.0 and t[1] == 2.5  # the sample value just above the median: at most half above
    assert t[4] == t[3] == 1.5  # no group of 5: the threshold of the largest N that has runs
    assert novel_after(score, t, 2, groups).tolist() == [False, False, False, False, False, True]


def test_calibrated_rule_sets_the_false_alarms_and_finds_the_new_cluster(fitted):
    model, X, y, first = fitted
    assert model.novelty_thresholds_ is None  # the model's own rule until calibrated
    own = model.predict(X, using="point") == -1
    np.testing.assert_array_equal(model.novel_after(X, 1), own)
    np.testing.assert_array_equal(model.novel_after(X, 2)[1:], own[1:] & own[:-1])  # 2 in a row
    calibration = (y < 3) & ~first
    model.calibrate_novelty(X[calibration], false_alarm=0.05, max_windows=5, groups=y[calibration])
    assert model.novelty_thresholds_.shape == (5,)
    flags = model.novel_after(X[calibration], 1)
    assert flags.mean() <= 0.05  # set on these windows by construction
    assert np.mean(model.predict(X[calibration], using="point") == -1) == flags.mean()
    new = y == 3
    one = model.novel_after(X[new], 1).mean()
    five = model.novel_after(X[new], 5)[4:].mean()
    assert one > 0.5 and five >= one  # averaging 5 windows finds the new cluster more often


def test_graph_onnx_and_stream_make_the_estimators_decision(fitted, tmp_path):
    from tactile_torch.export import export_onnx, run_onnx

    model, X, y, first = fitted
    calibration = (y < 3) & ~first
    model.calibrate_novelty(X[calibration], false_alarm=0.05, max_windows=5, groups=y[calibration])
    module = model.to_module()
    path = export_onnx(module, (torch.zeros(2, 3),), tmp_path / "m.onnx", input_names=["features"])
    stream = np.concatenate([X[y == 0][-20:], X[y == 3][:20]])  # a known cluster, then the new one
    _, _, novel, score = run_onnx(path, torch.as_tensor(stream, dtype=torch.float32))  # batch 40, exported 2
    np.testing.assert_allclose(score, model.novelty_score(stream), rtol=1e-4, atol=1e-3)
    np.testing.assert_array_equal(novel, model.novel_after(stream, 1))
    # the stream's N-window decision (numpy, on the robot) = the estimator's
    d = SurfaceDiscovery(3, thresholds=module.novelty_thresholds.tolist())
    verdicts = [d.update(0, bool(f), float(s)) for f, s in zip(novel, score, strict=True)]
    # equal, except where the float32 scores' mean ties the threshold (within their rounding)
    tie = (
        np.abs(np.nan_to_num(window_means(score.astype(np.float64), 3)) - module.novelty_thresholds[2].item())
        < 1e-3
    )
    assert tie.sum() <= 2
    np.testing.assert_array_equal(
        np.array([v.novel for v in verdicts])[~tie], model.novel_after(stream, 3)[~tie]
    )
    last = d.proposals[-1]  # the new cluster, proposed once its windows fill the mean, named to the end
    assert 18 <= last["first_window"] <= 22 and last["first_window"] + last["windows"] == 40


def test_surface_discovery_with_thresholds_proposes_on_the_first_window_mean_above_it():
    d = SurfaceDiscovery(2, known_names=["a"], thresholds=[0.0, 1.0])
    out = [d.update(0, False, s) for s in (0.0, 3.0, 0.5, -5.0)]
    assert [v.novel for v in out] == [False, True, True, False]
    assert [v.proposed for v in out] == [False, True, False, False]
    assert out[1].name == out[2].name == "new surface 1" and out[3].name == "a"
    assert d.proposals == [{"name": "new surface 1", "first_window": 0, "windows": 3}]


def test_novelty_arguments_are_checked(fitted):
    model, X, _, _ = fitted
    with pytest.raises(ValueError, match="false_alarm must be a number in"):
        model.calibrate_novelty(X, false_alarm=1.5)
    with pytest.raises(ValueError, match="max_windows must be an int >= 1"):
        model.calibrate_novelty(X, max_windows=0)
    with pytest.raises(ValueError, match="groups must have one entry per row"):
        model.calibrate_novelty(X, groups=[0, 1])
    with pytest.raises(ValueError, match="n_windows must be an int >= 1"):
        model.novel_after(X, 0)
    with pytest.raises(ValueError, match="thresholds must be a non-empty list of finite"):
        SurfaceDiscovery(3, thresholds=[float("nan")])
    with pytest.raises(ValueError, match="needs each window's novelty score"):
        SurfaceDiscovery(3, thresholds=[0.0]).update(0, True)


@pytest.mark.slow
def test_novelty_study_reports_every_rule_on_the_bundled_data():
    from tactile_torch.studies.clustering_experiments import have_vibration_features
    from tactile_torch.studies.novelty import RULES, SHIPPED, novelty_rows

    if not have_vibration_features():
        pytest.skip("tactile_torch.signal is not installed")
    rows = novelty_rows("bundled", windows=(1, 3), n_iter=150, burn_in=50, n_chains=1, n_components=5)
    assert {r["rule"] for r in rows} == set(RULES)
    shipped = {r["N"]: r for r in rows if r["rule"] == SHIPPED}
    own = {r["N"]: r for r in rows if r["rule"] == "new component"}
    # calibrated on known windows, the rule finds more of the withheld surfaces than the model's own rule
    assert shipped[3]["recall"] > own[3]["recall"] and shipped[3]["recall"] >= 0.5
    assert all(0.0 <= r["false alarms"] <= 1.0 for r in rows)


def test_calibrated_thresholds_travel_through_the_model_file_to_the_bundle(fitted, tmp_path):
    from tactile_torch.clustering_model import save_clustering_model
    from tactile_torch.export.model_graph import export_pipeline, pipeline_from_model
    from tactile_torch.robot.contract import NOVELTY_THRESHOLDS_KEY
    from tactile_torch.robot.runtime import OnnxPipeline

    model, X, y, first = fitted
    calibration = (y < 3) & ~first
    model.calibrate_novelty(X[calibration], false_alarm=0.05, max_windows=4, groups=y[calibration])
    path = save_clustering_model(tmp_path / "m.npz", model, source={"kind": "features", "n_features": 3})
    bundle = OnnxPipeline(export_pipeline(pipeline_from_model(path), tmp_path / "m.onnx"))
    got = json.loads(bundle.metadata[NOVELTY_THRESHOLDS_KEY])
    np.testing.assert_allclose(got, model.novelty_thresholds_, rtol=1e-6)


def test_per_component_thresholds_need_enough_calibration_runs():
    from tactile_torch.studies.novelty import per_component_decisions

    # one recording: 120 calibration windows (component 0: scores 0..99, component 1: 20 windows at 50),
    # then 4 test windows
    score = np.r_[np.arange(100.0), np.full(20, 50.0), [97.5, 97.5, 99.5, 99.5]]
    component = np.r_[np.zeros(100, int), np.ones(20, int), [0, 1, 0, 1]]
    recording, position = np.zeros(124, int), np.arange(124)
    calibration, test = position < 120, position >= 120
    agg, threshold, last = per_component_decisions(
        score, component, recording, position, calibration, test, 1, 0.02
    )
    # component 0 has 100 >= 1 / 0.02 runs: its own 98 % quantile (98); component 1 has 20: the global one (97)
    assert last.tolist() == [120, 121, 122, 123] and threshold.tolist() == [98.0, 97.0, 98.0, 97.0]
    assert (agg > threshold).tolist() == [False, True, True, True]
    agg, threshold, last = per_component_decisions(
        score, component, recording, position, calibration, test, 1, 0.2
    )
    # at 20 %: component 0 its own quantile (80), component 1 its own (50; 20 >= 1 / 0.2 runs)
    assert threshold.tolist() == [80.0, 50.0, 80.0, 50.0]


def test_counting_on_leading_columns_and_scoring_novelty_on_all_of_them(tmp_path):
    # issue 32, decision (a): cluster_features=3 of 5 columns; the graph computes both side by side
    X, y = _three_known_one_new()
    extra = np.random.default_rng(1).normal(0.0, 1.0, size=(len(X), 2))
    extra[y == 3] += 6.0  # the new cluster stands apart in the last 2 columns
    X5 = np.hstack([X, extra])
    known = y < 3
    model = PitmanYorGMM(
        n_iter=150, burn_in=50, n_chains=2, cluster_features=3, random_state=0, progress=False
    )
    model.fit(X5[known])
    assert model.n_features_in_ == 5 and model.means_.shape[1] == 3 and model.density_means_.shape[1] == 5
    # the clusters come from the first 3 columns only; the novelty density from all 5
    shifted = X5[known] + [0.0, 0.0, 0.0, 9.0, 9.0]
    np.testing.assert_array_equal(
        model.predict(X5[known], using="point"), model.predict(shifted, using="point")
    )
    assert model.novelty_score(X5[y == 3]).mean() > model.novelty_score(X5[known]).mean() + 10
    # the torch graph (what export traces; ONNX parity of the sliced input: tests/export/test_model_graph.py's round trip)
    rows = X5[known][::5]
    labels, _, _, score = model.to_module().double()(torch.as_tensor(rows))
    np.testing.assert_allclose(score.numpy(), model.novelty_score(rows), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(labels.numpy(), model.predict(rows, using="point"))
    with pytest.raises(ValueError, match="cluster_features must be at most the number of columns of X"):
        PitmanYorGMM(n_iter=5, burn_in=1, cluster_features=6, progress=False).fit(X5)
