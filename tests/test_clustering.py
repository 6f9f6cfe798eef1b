"""The clustering job of ``tactile-torch cluster`` (tactile_torch.clustering): rows, fit, results files."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.clustering import clustering_summary, fit_clustering, write_clustering
from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.robot.files.data_sources import read_source

FAST = {"n_iter": 40, "burn_in": 10, "n_chains": 1, "progress": False, "random_state": 0}


def _features(tmp_path, labels=True):
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]])
    y = np.repeat(np.arange(3), 15)
    X = centres[y] + rng.normal(0, 0.5, (45, 2))
    np.savez(tmp_path / "f.npz", features=X, **({"labels": y} if labels else {}))
    return read_source([tmp_path / "f.npz"]), y


def test_features_are_clustered_as_they_are_and_the_results_written(tmp_path):
    data, y = _features(tmp_path)
    clustering = fit_clustering(data, **FAST)
    assert clustering.transform is None and clustering.source == {"kind": "features", "n_features": 2}
    np.testing.assert_array_equal(clustering.X, data.features)
    paths = write_clustering(tmp_path / "out", clustering)
    assert sorted(paths) == ["model", "results", "summary"] and all(p.is_file() for p in paths.values())
    res = np.load(paths["results"])
    assert pairwise_accuracy(y, res["labels"]) == 1.0 and res["means"].shape == (3, 2)
    assert res["n_clusters_samples"].shape == (30,)  # 40 sweeps, 10 burnt
    summary = paths["summary"].read_text()
    assert summary == clustering_summary(clustering) + "\n"
    assert "point estimate (3 clusters) pairwise accuracy 1.0000, adjusted Rand index 1.0000" in summary


def test_without_labels_the_summary_has_no_accuracy(tmp_path):
    data, _ = _features(tmp_path, labels=False)
    assert "pairwise accuracy" not in clustering_summary(fit_clustering(data, **FAST))


def test_recordings_go_through_windows_features_and_components(tmp_path):
    from tactile_torch.data.stylus import make_vibration_recordings

    rec = make_vibration_recordings(3, duration_s=2.0, random_state=0)
    lines = []
    clustering = fit_clustering(
        read_source([rec.save(tmp_path / "rec.npz")]),
        window=400,
        components=2,
        sensor_range_g=8.0,
        name="rec.npz",
        log=lines.append,
        **FAST,
    )
    n = len(clustering.X)
    # decision (a) of issue 32: 5 components side by side, K counted and clustered on the first 2
    assert clustering.X.shape == (n, 5) and clustering.truth.shape == (n,)
    assert clustering.mixture.cluster_features == 2 and clustering.mixture.means_.shape[1] == 2
    assert clustering.mixture.density_means_.shape[1] == 5
    assert clustering.source["kind"] == "vibration" and clustering.source["sensor_range_g"] == 8.0
    assert lines == [
        f"rec.npz: {n} windows of 400 samples -> 5 principal components (K counted on the first 2), "
        "3 held out to calibrate the novelty rule"
    ]
    # novelty_components=None: one set of components for both
    same = fit_clustering(
        read_source([tmp_path / "rec.npz"]), window=400, components=2, novelty_components=None, **FAST
    )
    assert same.X.shape == (n, 2) and same.mixture.density_means_ is None


def test_images_cannot_be_clustered(tmp_path):
    frames = np.zeros((2, 3, 8, 8, 3), np.uint8)
    np.savez(tmp_path / "i.npz", frames=frames, labels=np.array([0, 1]), class_names=np.array(["a", "b"]))
    with pytest.raises(ValueError, match=r"i\.npz: data must hold vibration recordings"):
        fit_clustering(read_source([tmp_path / "i.npz"]), name="i.npz", **FAST)


# ------------------------------------------------------------------------------------------------
# the novelty rule's calibration (held-out windows) and per-session standardisation
# ------------------------------------------------------------------------------------------------
def test_holdout_rows_are_the_last_share_of_each_recording_or_a_random_share():
    from tactile_torch.clustering import holdout_rows

    recording = np.array([1, 0, 0, 1, 0, 1, 0, 0, 0, 0])
    position = np.array([2, 4, 0, 0, 1, 1, 2, 3, 5, 6])
    fitted, held = holdout_rows(10, 0.3, recording=recording, position=position)
    # recording 0 (7 windows): its last 2 (positions 5, 6); recording 1 (3 windows): its last one
    assert held.tolist() == [8, 9, 0] and fitted.tolist() == [1, 2, 3, 4, 5, 6, 7]
    fitted, held = holdout_rows(10, 0.2, random_state=0)
    assert held.size == 2 and np.union1d(fitted, held).tolist() == list(range(10))
    np.testing.assert_array_equal(holdout_rows(10, 0.2, random_state=0)[1], held)
    for bad in (0.0, 1.0, True, "0.2"):
        with pytest.raises(ValueError, match="calibrate must be a share in"):
            holdout_rows(10, bad)


def test_recordings_are_calibrated_on_their_last_windows_features_only_on_request(tmp_path):
    from tactile_torch.data.stylus import make_vibration_recordings
    from tactile_torch.robot.files.model_file import load_model_file

    rec = make_vibration_recordings(3, duration_s=8.0, random_state=0)
    data = read_source([rec.save(tmp_path / "rec.npz")])
    clustering = fit_clustering(data, window=400, components=2, **FAST)
    n = len(clustering.X)  # 3 recordings x 16 windows: the last third (5) of each held out
    assert clustering.calibration_rows.size == 15 and clustering.fitted_rows.size == n - 15
    assert clustering.mixture.labels_.shape == (n - 15,) and clustering.false_alarm == 0.02
    t = clustering.mixture.novelty_thresholds_
    assert t.shape == (10,) and np.isfinite(t).all()
    # at most 2 % of the held-out windows are novel: with 15 windows, none (the threshold is their max)
    assert not clustering.mixture.novel_after(clustering.X[clustering.calibration_rows], 1).any()
    assert "novelty: a window is novel when its score (minus its log density) exceeds" in clustering_summary(
        clustering
    )
    paths = write_clustering(tmp_path / "out", clustering)
    res = np.load(paths["results"])
    np.testing.assert_array_equal(res["calibration_rows"], clustering.calibration_rows)
    np.testing.assert_array_equal(res["fitted_rows"], clustering.fitted_rows)
    np.testing.assert_allclose(res["novelty_thresholds"], t)
    assert not res["per_session"]
    model = load_model_file(paths["model"])
    assert model.header["novelty"] == {"false_alarm": 0.02, "calibration_rows": 15}
    np.testing.assert_allclose(model.arrays["head.novelty_thresholds"], t, rtol=1e-6)
    # the head counts on 2 of the 5 components (issue 32, decision (a)); crafted shapes are refused
    from tactile_torch.robot.files.model_file import validate_model

    assert model.header["head"]["cluster_features"] == 2 and model.arrays["head.means"].shape[1] == 2
    for change, message in (
        ({"cluster_features": 5}, r"head\.cluster_features must be in 1\.\.4, got 5"),
        ({"cluster_features": 3}, r"head\.means has shape .* must be 3"),
    ):
        with pytest.raises(ValueError, match=message):
            validate_model({**model.header, "head": {**model.header["head"], **change}}, model.arrays)
    short = {**model.arrays, "head.density_means": model.arrays["head.density_means"][:, :4]}
    with pytest.raises(ValueError, match=r"head\.density_means has shape"):
        validate_model(model.header, short)
    assert fit_clustering(data, window=400, components=2, calibrate=0, **FAST).calibration_rows.size == 0
    features, _ = _features(tmp_path)
    assert fit_clustering(features, **FAST).mixture.novelty_thresholds_ is None
    held = fit_clustering(features, calibrate=0.2, **FAST)
    assert held.calibration_rows.size == 9 and held.mixture.novelty_thresholds_ is not None
    with pytest.raises(ValueError, match="leaves 45 to fit and 0 to calibrate"):
        fit_clustering(read_source([tmp_path / "f.npz"]), calibrate=0.001, **FAST)
    with pytest.raises(ValueError, match="false_alarm must be a number in"):
        fit_clustering(features, false_alarm=2.0, **FAST)


def test_per_session_models_are_recorded_and_not_exported(tmp_path, capsys):
    from tactile_torch.cli import BAD_INPUT_EXIT, main
    from tactile_torch.data.stylus import make_vibration_recordings
    from tactile_torch.export.model_graph import pipeline_from_model
    from tactile_torch.robot.files.model_file import load_model_file

    rec = make_vibration_recordings(2, duration_s=4.0, n_sessions=2, random_state=0)
    arrays = dict(signals=np.stack(rec.signals), rate_hz=rec.rate_hz, labels=rec.labels)
    arrays["class_names"] = np.array(rec.class_names)
    np.savez(tmp_path / "one.npz", **arrays, session=np.array(rec.session))  # "glass/0": one recording each
    with pytest.raises(ValueError, match="every session holds one recording"):
        fit_clustering(read_source([tmp_path / "one.npz"]), window=400, sessions="standardise", **FAST)
    np.savez(tmp_path / "none.npz", **arrays)
    with pytest.raises(ValueError, match="sessions needs recordings of at least two sessions"):
        fit_clustering(read_source([tmp_path / "none.npz"]), window=400, sessions="standardise", **FAST)
    with pytest.raises(ValueError, match="sessions='standardise' needs vibration recordings with sessions"):
        fit_clustering(_features(tmp_path)[0], sessions="standardise", **FAST)
    session = np.array([s.rsplit("/", 1)[1] for s in rec.session])  # "0", "1": both surfaces in each
    np.savez(tmp_path / "two.npz", **arrays, session=session)
    clustering = fit_clustering(
        read_source([tmp_path / "two.npz"]), window=400, sessions="standardise", **FAST
    )
    for s in ("0", "1"):  # standardised within each session
        rows = session[np.repeat(np.arange(4), len(clustering.X) // 4)] == s
        np.testing.assert_allclose(clustering.X[rows].mean(axis=0), 0.0, atol=1e-9)
    model = load_model_file(write_clustering(tmp_path / "out", clustering)["model"])
    assert model.header["per_session"] is True
    with pytest.raises(ValueError, match="standardised per session, which a robot cannot do"):
        pipeline_from_model(model)
    capsys.readouterr()
    args = ["export", "--model", str(tmp_path / "out" / "model.npz"), "--out", str(tmp_path / "m.onnx")]
    assert main(args) == BAD_INPUT_EXIT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "standardised per session" in err


def _days(tmp_path, n_days=3, duration_s=8.0, name="days.npz"):
    """3 surfaces recorded on ``n_days`` days, each day's signals scaled by its own gain: a .npz with sessions."""
    from tactile_torch.data.stylus import make_vibration_recordings

    rec = make_vibration_recordings(3, duration_s=duration_s, n_sessions=n_days, random_state=0)
    day = np.array([int(s.rsplit("/", 1)[1]) for s in rec.session])
    gains = np.array([0.8, 1.0, 1.25, 0.9, 1.1])[day]
    arrays = dict(
        signals=np.stack(rec.signals) * gains[:, None, None].astype(np.float32),
        rate_hz=rec.rate_hz,
        labels=rec.labels,
        class_names=np.array(rec.class_names),
    )
    np.savez(tmp_path / name, **arrays, session=np.array([f"day{k}" for k in day]))
    return read_source([tmp_path / name]), arrays


def test_sessions_shared_by_surfaces_become_session_effects_by_default(tmp_path):
    from tactile_torch.robot.files.model_file import load_model_file

    data, arrays = _days(tmp_path)
    clustering = fit_clustering(data, window=400, sessions_from="the file's session array", **FAST)
    assert clustering.session_mode == "model" and clustering.mixture.n_sessions_ == 3
    assert clustering.mixture.session_scale_ > 0
    summary = clustering_summary(clustering)
    assert (
        "sessions: 3 from the file's session array (day0, day1, day2); K counts surfaces across them"
        in summary
    )
    assert "against the data's labels (3 classes, " in summary and "adjusted Rand index" in summary
    paths = write_clustering(tmp_path / "out", clustering)
    res = np.load(paths["results"])
    assert str(res["session_mode"]) == "model" and res["sessions"].shape == (len(clustering.X),)
    header = load_model_file(paths["model"]).header
    assert header["sessions"]["names"] == ["day0", "day1", "day2"] and header["sessions"]["scale"] > 0
    # the other uses of the sessions, and what cannot use them
    assert fit_clustering(data, window=400, sessions="none", **FAST).session_mode == "none"
    assert "; not used: K counts blobs" in clustering_summary(
        fit_clustering(data, window=400, sessions="none", **FAST)
    )
    np.savez(
        tmp_path / "own.npz", **arrays, session=np.array([f"r{i}" for i in range(len(arrays["labels"]))])
    )
    own = read_source([tmp_path / "own.npz"])
    assert (
        fit_clustering(own, window=400, **FAST).session_mode == "none"
    )  # auto: each recording its own session
    with pytest.raises(
        ValueError, match="each of the 9 sessions holds a single recording; a session effect is told"
    ):
        fit_clustering(own, window=400, sessions="model", **FAST)
    with pytest.raises(
        ValueError, match="sessions must be one of 'auto', 'model', 'standardise', 'none', got True"
    ):
        fit_clustering(data, window=400, sessions=True, **FAST)
