"""The clustering job of ``tactile-torch cluster`` (tactile_torch.clustering): rows, fit, results files."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.clustering import clustering_summary, fit_clustering, write_clustering
from tactile_torch.metrics import pairwise_accuracy
from tactile_torch.robot.data_sources import read_source

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
    assert "pairwise accuracy: point estimate 1.0000" in summary


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
    assert clustering.X.shape == (n, 2) and clustering.truth.shape == (n,)
    assert clustering.source["kind"] == "vibration" and clustering.source["sensor_range_g"] == 8.0
    assert lines == [f"rec.npz: {n} windows of 400 samples -> 2 principal components"]


def test_images_cannot_be_clustered(tmp_path):
    frames = np.zeros((2, 3, 8, 8, 3), np.uint8)
    np.savez(tmp_path / "i.npz", frames=frames, labels=np.array([0, 1]), class_names=np.array(["a", "b"]))
    with pytest.raises(ValueError, match=r"i\.npz: data must hold vibration recordings"):
        fit_clustering(read_source([tmp_path / "i.npz"]), name="i.npz", **FAST)
