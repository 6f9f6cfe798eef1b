"""A hand trains and exports: a continuous taxel log cut into the live stream's touches, per-taxel features, every
method on small data or one line, the unknown rule never in the way, early decisions calibrated (issue 42, 2-3)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.export.model_graph import pipeline_from_model
from tactile_torch.features import load_features
from tactile_torch.robot.contract import EARLY_RULE_KEY, TOUCH_LEVELS_KEY
from tactile_torch.robot.files.data_sources import read_source
from tactile_torch.robot.files.frame_recordings import FrameRecording, write_frame_recording
from tactile_torch.robot.files.model_file import load_model_file
from tactile_torch.robot.stream.recorded_touches import recorded_touches

REGIONS = (np.s_[:, :2, :2], np.s_[:, :2, 2:], np.s_[:, 2:, :])  # each object presses its own taxels
NAMES = ("can", "sponge", "bottle")


def hand_log(n_grasps: int, seed: int, *, t0: float = 1_762_430_000.0) -> FrameRecording:
    """A 4 x 4 array's log at 20 frames/s: rest, a grasp of 12 frames, rest ..., each frame labelled."""
    rng = np.random.default_rng(seed)
    parts, labels = [], []
    for i in range(n_grasps):
        grasp = rng.normal(10.0, 0.5, (12, 4, 4))
        grasp[REGIONS[i % 3]] += np.linspace(5, 30, 12)[:, None, None] * rng.uniform(0.8, 1.2)
        parts += [rng.normal(10.0, 0.5, (10, 4, 4)), grasp]
        labels += [-1] * 10 + [i % 3] * 12
    frames = np.concatenate([*parts, rng.normal(10.0, 0.5, (10, 4, 4))]).astype(np.float32)
    return FrameRecording(frames, t0 + np.arange(len(frames)) / 20, np.array(labels + [-1] * 10), NAMES)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    root = tmp_path_factory.mktemp("hand")
    return [
        write_frame_recording(root / f"day{d}.npz", hand_log(18, seed=d, t0=1.76e9 + d * 86400))
        for d in (1, 2)
    ]


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_train_on_a_hands_logs_keeps_what_the_stream_will_cut(logs, tmp_path, capsys):
    status, out, err = _run(
        ["train", "--data", *logs, "--method", "lda", "--out", tmp_path / "m.npz"], capsys
    )
    assert status == 0, err
    lines = out.splitlines()
    assert (
        "2 files read as frame recordings labelled frame by frame" in lines[0]
        and "2 sessions (day1, day2)" in lines[0]
    )
    assert "36 touches of 2 recording(s) at 20 frames/s (from t), cut by the live stream" in lines[1]
    assert "36 samples x 112 features (pressure), 3 classes" in out  # per-taxel: 7 x 16, the default here
    assert "held-out accuracy from 36 touches; 2 folds grouped by session" in out
    assert "early decisions: " in out
    model = load_model_file(tmp_path / "m.npz")
    source = model.source
    assert (
        source["kind"] == "pressure" and source["features"] == "per-taxel" and source["frame_rate_hz"] == 20.0
    )
    assert model.header["format_version"] == 3 and EARLY_RULE_KEY in source
    touches = recorded_touches(read_source(logs))
    assert source[TOUCH_LEVELS_KEY]["onset"] == pytest.approx(
        touches.levels.onset
    )  # the levels it was cut at
    # the graph export builds from the file classifies the training touches as the trained model does
    features = load_features(logs)
    pipe = pipeline_from_model(model)
    with torch.no_grad():
        labels = pipe(torch.from_numpy(features.raw))[0].numpy()
    assert (labels == features.y).mean() == 1.0 and pipe.input_layout == "B,T,H,W"
    assert json.loads(pipe.metadata()[EARLY_RULE_KEY])["touches"] == 36


@pytest.mark.parametrize("method", ["hmsvm", "svc", "lda", "knn", "ncm"])
def test_every_method_trains_on_four_touches_per_class(tmp_path, capsys, method):
    grasps = np.stack([hand_log(1, seed=s).frames[10:22] for s in range(12)])  # 12 grasps of 12 frames
    for k, grasp in enumerate(grasps):
        grasp[REGIONS[k % 3]] += 5.0
    np.savez(
        tmp_path / "g.npz",
        frames=grasps,
        labels=np.arange(12) % 3,
        class_names=list(NAMES),
        frame_rate_hz=20.0,
    )
    argv = [
        "train",
        "--data",
        tmp_path / "g.npz",
        "--method",
        method,
        "--folds",
        "2",
        "--out",
        tmp_path / "m.npz",
    ]
    status, out, err = _run(argv, capsys)
    assert status == 0, err
    assert "12 samples x 112 features (pressure)" in out and load_model_file(tmp_path / "m.npz").method in (
        method,
        "svm",
    )


def test_features_that_never_vary_are_one_line_and_a_degenerate_unknown_rule_a_warning(tmp_path, capsys):
    grasps = np.stack([hand_log(1, seed=s).frames[10:22] for s in range(6)])
    np.savez(
        tmp_path / "g.npz", frames=grasps, labels=np.arange(6) % 2, class_names=["a", "b"], frame_rate_hz=20.0
    )
    status, _, err = _run(
        ["train", "--data", tmp_path / "g.npz", "--method", "lda", "--features", "fused"], capsys
    )
    assert status == BAD_INPUT_EXIT and err.count("\n") == 1
    assert "g.npz: features: all 12 image features are the same for every sample, so there is nothing" in err
    assert err.strip().endswith("choose other features (--features per-taxel for a small taxel array)")
    from tactile_torch.ood import fit_rule

    with pytest.warns(
        UserWarning, match=r"the training features lie at one point .* answers unknown to any other"
    ):
        rule = fit_rule(np.ones((6, 3)), np.arange(6) % 2, scale=np.ones(3))
    assert 0 < rule["threshold"] < 1e-30  # a model file that loads: every other input is unknown


@pytest.mark.slow
def test_train_export_predict_and_tradeoff_on_a_hands_logs(logs, tmp_path, capsys):
    """The whole path on the command line: train + export decide early in the stream's own touches; the
    trade-off deploys a per-taxel bundle and its model file, both with the levels the logs were cut at."""
    assert (
        main(["train", "--data", *map(str, logs), "--method", "hmsvm", "--out", str(tmp_path / "m.npz")]) == 0
    )
    assert main(["export", "--model", str(tmp_path / "m.npz"), "--out", str(tmp_path / "m.onnx")]) == 0
    session = write_frame_recording(tmp_path / "session.npz", hand_log(6, seed=9))
    capsys.readouterr()
    assert main(["predict", "--model", str(tmp_path / "m.onnx"), "--data", str(session)]) == 0
    out = capsys.readouterr().out
    assert "overall accuracy 1.0000" in out and "6 of 6 touches decided early" in out
    argv = ["tradeoff", "--data", *map(str, logs), "--out", str(tmp_path / "study"), "--quick", "--quiet",
            "--classifiers", "lda", "--no-breaking"]  # fmt: skip
    assert main(argv) == 0
    study = load_model_file(tmp_path / "study" / "recommended.npz")
    levels = recorded_touches(read_source(logs)).levels
    assert study.source["kind"] == "pressure" and study.source[TOUCH_LEVELS_KEY]["onset"] == pytest.approx(
        levels.onset
    )


def test_predict_cuts_the_touches_of_a_days_logs_each_of_its_files_class(tmp_path, capsys):
    """Several frame recordings at once, one class per file from the layout (folder per class)."""
    from tests.stream_helpers import frame_bundle

    weights = np.zeros((4, 4, 3), np.float32)
    for c, region in enumerate(REGIONS):
        weights[..., c][region[1:]] = 1.0  # the mean pressure over each object's taxels
    levels = {"onset": 40.0, "release": 20.0, "min_frames": 2, "rest": 10.0}
    model = frame_bundle(tmp_path / "m.onnx", weights, n_frames=4, class_names=list(NAMES), metadata={
        "frame_rate_hz": 20.0, TOUCH_LEVELS_KEY: levels})  # fmt: skip
    paths = []
    for c, name in enumerate(NAMES):
        log = hand_log(9, seed=c)
        keep = np.isin(log.labels, [-1, c])  # this object's grasps and the rest between them
        one = FrameRecording(log.frames[keep], 1.76e9 + np.arange(keep.sum()) / 20)
        paths.append(write_frame_recording(tmp_path / name / "2026-11-02.npz", one))
    status, out, err = _run(["predict", "--model", model, "--data", *paths], capsys)
    assert status == 0, err
    assert "3 files read as folder per class" in err.splitlines()[0]
    assert out.count(" frames read, 3 touches") == 3 and "overall accuracy 1.0000" in out
