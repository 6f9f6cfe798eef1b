"""``predict`` counts each window once, with its one reason (issue 42, point 5), and says why a class is not
the model's (a tree read the other way)."""

from __future__ import annotations

import re

import numpy as np

from tactile_torch.cli import main
from tests.robot_data import surface_recordings, write_log
from tests.stream_helpers import energy_bundle


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_every_window_is_counted_once_with_its_reason(tmp_path, capsys):
    model = energy_bundle(tmp_path / "m.onnx", window=64)
    rec = surface_recordings(1, 0.64)
    constant = np.tile([0.0, 0.0, 1.0], (320, 1)).astype(np.float32)  # 5 windows of no vibration
    spike = rec.signals[0][:320].copy()
    spike[70] = [30.0, 0.0, 1.0]  # one window beyond the sensor's 5 g
    paths = [
        write_log(tmp_path / "x_1.csv", rec.signals[0][:320], 800.0),  # 5 windows classified
        write_log(
            tmp_path / "y_1.csv", constant, 800.0, fmt="%.4f"
        ),  # 5 constant: unknown, whatever the class
        write_log(tmp_path / "unseen_1.csv", rec.signals[0][:320], 800.0),  # 5 of a class the model lacks
        write_log(tmp_path / "z_1.csv", spike, 800.0),  # 1 beyond the range, 4 classified
    ]
    status, out, err = _run(["predict", "--model", model, "--data", *paths], capsys)
    assert status == 0, err
    counted = re.search(r"20 windows: (\d+) scored against their class, (\d+) left out: (.*)$", out, re.M)
    assert counted, out
    assert counted[1] == "9" and counted[2] == "11"
    reasons = counted[3]
    assert "5 no vibration (every axis constant)" in reasons
    assert "1 beyond the sensor's range ±5 g" in reasons
    assert "5 of a class the model does not know (unseen; it knows x, y, z)" in reasons
    # each window once: no second line counts the same windows again
    assert out.count("left out") == 1 and "samples are unknown" not in out


def test_classes_of_a_tree_read_the_other_way_are_named_with_the_fix(tmp_path, capsys):
    model = energy_bundle(tmp_path / "m.onnx", window=64)  # classes x, y, z
    rec = surface_recordings(1, 0.16)
    paths = []
    for axis in ("x", "y", "z"):  # a folder per class, dated files: the tree rule reads it right
        for date in ("2026-11-02", "2026-11-03"):
            (tmp_path / "by_date" / date).mkdir(parents=True, exist_ok=True)
            paths.append(write_log(tmp_path / "by_date" / date / f"{axis}.csv", rec.signals[0], 800.0))
    status, out, err = _run(["predict", "--model", model, "--data", *paths, "--class-from", "folder"], capsys)
    assert status == 0
    assert re.search(
        r"left out: 12 of classes the model does not know \(2026-11-02, 2026-11-03; it knows x, y, z\): "
        r"--class-from file reads the files the other way",
        out,
    ), out
    assert "read as folder per class" in err.splitlines()[0]  # the decision first, before any window
