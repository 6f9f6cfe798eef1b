"""Tests of ``tactile-torch cluster``: the clustering it writes and its one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.metrics import pairwise_accuracy
from tests.mixture_data import blobs

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


# ------------------------------------------------------------------------------------------------
# command line and report
# ------------------------------------------------------------------------------------------------
def test_cli_cluster_writes_the_clustering(tmp_path, capsys):
    from tactile_torch.cli import main

    X, y = blobs(n_clusters=3, per=15, dim=2)
    np.savez(tmp_path / "f.npz", features=X, labels=y)
    out = tmp_path / "out"
    args = [
        "cluster",
        "--data",
        str(tmp_path / "f.npz"),
        "--out",
        str(out),
        "--n-iter",
        "40",
        "--burn-in",
        "10",
    ]
    assert main([*args, "--quiet", "--seed", "3", "--chains", "2"]) == 0
    res = np.load(out / "clustering.npz")
    assert pairwise_accuracy(y, res["labels"]) == 1.0 and res["means"].shape == (3, 2)
    assert res["n_clusters_samples"].shape == (60,)  # 2 chains x 30 sweeps after burn-in
    summary = (out / "summary.txt").read_text()
    assert summary.splitlines()[1].startswith("K, posterior: mode 3")
    assert "point estimate (3 clusters) pairwise accuracy 1.0000, adjusted Rand index 1.0000" in summary
    assert (out / "model.npz").is_file()  # for tactile-torch export (tests/export/test_model_graph.py)
    np.savez(tmp_path / "bad.npz", X=X)
    assert main(["cluster", "--data", str(tmp_path / "bad.npz"), "--out", str(out)]) == 2
    assert "or a feature matrix ('features'), found keys ['X']" in capsys.readouterr().err


def test_cli_cluster_says_in_one_line_what_a_recordings_file_lacks(tmp_path, capsys):
    from tactile_torch.cli import BAD_INPUT_EXIT, main
    from tactile_torch.data.stylus import make_vibration_recordings

    rec = make_vibration_recordings(3, duration_s=1.0, random_state=0)
    signals = np.stack(rec.signals)
    common = ["--window", "400", "--n-iter", "30", "--burn-in", "10", "--quiet", "--out", str(tmp_path / "o")]
    for name, arrays, missing in (
        ("nolabels.npz", dict(signals=signals, rate_hz=rec.rate_hz), "'labels', 'class_names'"),
        ("norate.npz", dict(signals=signals, labels=rec.labels, class_names=rec.class_names), "'rate_hz'"),
    ):
        np.savez(tmp_path / name, **arrays)
        assert main(["cluster", "--data", str(tmp_path / name), *common]) == BAD_INPUT_EXIT
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f"missing {missing}" in err, err


def test_cli_cluster_budgets_default_to_the_estimators():
    from tactile_torch.cli import ARGUMENT_FLAGS, build_parser, with_flags
    from tactile_torch.mixture import PitmanYorGMM

    args = build_parser().parse_args(["cluster", "--data", "x.npz"])
    defaults = PitmanYorGMM()
    assert (args.max_iter, args.max_seconds) == (defaults.max_iter, defaults.max_seconds)
    args = build_parser().parse_args(
        ["cluster", "--data", "x.npz", "--max-seconds", "60", "--max-iter", "900"]
    )
    assert (args.max_iter, args.max_seconds) == (900, 60.0)
    # the budget warning names the argument; the command line shows the option
    flags = {k: v for k, v in ARGUMENT_FLAGS.items() if k in ("max_iter", "max_seconds")}
    assert with_flags("raise it, e.g. max_seconds=600", flags) == "raise it, e.g. --max-seconds 600"


@pytest.mark.slow
def test_cluster_export_predict_and_stream_share_the_calibrated_novelty_rule(tmp_path, capsys):
    # ~20 s: cluster (held-out windows calibrate the thresholds) -> export -> predict; ONNX at batch 7 and 9
    import json

    import torch

    from tactile_torch.cli import main
    from tactile_torch.data.stylus import SURFACES, make_vibration_recordings
    from tactile_torch.export.model_graph import pipeline_from_model
    from tactile_torch.robot.contract import NOVELTY_THRESHOLDS_KEY
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.discovery import SurfaceDiscovery

    rec = make_vibration_recordings(
        surfaces=[SURFACES[0], SURFACES[5], SURFACES[7]], duration_s=10.0, random_state=0
    )
    rec.save(tmp_path / "rec.npz")
    out, onnx = tmp_path / "cl", tmp_path / "cl.onnx"
    common = ["--window", "400", "--n-iter", "100", "--burn-in", "30", "--chains", "2", "--quiet"]
    assert main(["cluster", "--data", str(tmp_path / "rec.npz"), "--out", str(out), *common]) == 0
    assert "novelty: a window is novel when its score" in capsys.readouterr().out
    assert main(["export", "--model", str(out / "model.npz"), "--out", str(onnx)]) == 0
    res = np.load(out / "clustering.npz")
    thresholds = res["novelty_thresholds"]
    held_out = res["calibration_rows"].size  # a third of each recording's windows (cluster's default)
    assert held_out == 21
    assert (
        f"exceeds {thresholds[0]:.4g}, set for 2.0% false alarms on {held_out} held-out windows"
        in capsys.readouterr().out
    )
    bundle = OnnxPipeline(onnx)
    np.testing.assert_allclose(json.loads(bundle.metadata[NOVELTY_THRESHOLDS_KEY]), thresholds, rtol=1e-6)
    raw = bundle.read_npz([tmp_path / "rec.npz"]).raw
    assert len(raw) == res["fitted_rows"].size + res["calibration_rows"].size == 60
    pipeline = pipeline_from_model(out / "model.npz")
    with torch.no_grad():
        _, _, t_novel, t_novelty = pipeline(torch.from_numpy(raw))
    for batch in (7, 9):  # the export traced a batch of 2
        got = [bundle.run(raw[i : i + batch]) for i in range(0, len(raw), batch)]
        novelty = np.concatenate([g["novelty"] for g in got])
        novel = np.concatenate([g["novel"] for g in got])
        np.testing.assert_allclose(novelty, t_novelty.numpy(), rtol=1e-4, atol=1e-3)
        np.testing.assert_array_equal(novel, t_novel.numpy())
    np.testing.assert_array_equal(novel, novelty > np.float32(thresholds[0]))
    # the held-out windows decide as calibrated: at most 2 % of them novel (of 21: none)
    assert not novel[res["calibration_rows"]].any()
    # predict reports the graph's novel windows; a new surface is flagged
    unseen = make_vibration_recordings(surfaces=[SURFACES[27]], duration_s=4.0, random_state=1)
    unseen.save(tmp_path / "new.npz")
    capsys.readouterr()
    assert main(["predict", "--model", str(onnx), "--data", str(tmp_path / "new.npz"), "--batch", "7"]) == 0
    printed = capsys.readouterr().out
    new_novel = bundle.run(bundle.read_npz([tmp_path / "new.npz"]).raw)["novel"]
    assert (
        f"{int(new_novel.sum())} of {len(new_novel)} samples are novel" in printed and new_novel.mean() > 0.5
    )
    # the stream's decision after 3 windows: the mean of the last 3 scores against threshold 3
    d = SurfaceDiscovery(3, thresholds=json.loads(bundle.metadata[NOVELTY_THRESHOLDS_KEY]))
    flags = [d.update(0, False, float(s)).novel for s in novelty]
    means = np.convolve(novelty, np.ones(3) / 3, mode="valid")
    # the bundle's thresholds (float32 in its metadata): a window whose mean lies within float32's
    # rounding of the threshold may go either way, and is left out of the comparison
    stream_threshold = d.threshold
    assert stream_threshold == pytest.approx(thresholds[2], rel=1e-6)
    clear = np.abs(means - stream_threshold) > 1e-6 * stream_threshold
    assert clear.sum() >= len(means) - 1
    np.testing.assert_array_equal(np.asarray(flags[2:])[clear], (means > stream_threshold)[clear])
