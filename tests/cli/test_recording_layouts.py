"""Every data command reads a folder per class and a folder per session alike, says so before any work, and
refuses a tree it cannot tell in one line (issue 42, point 1)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.data import make_vibration_recordings
from tactile_torch.robot.files.csv_logs import write_csv_recording
from tactile_torch.robot.files.data_sources import DataOptions, read_source

DATES = ("2026-11-02", "2026-11-03", "2026-11-05")


@pytest.fixture(scope="module")
def trees(tmp_path_factory):
    """3 surfaces of the stylus generator x 3 days, as <surface>/<date>.csv and as <date>/<surface>.csv."""
    root = tmp_path_factory.mktemp("trees")
    rec = make_vibration_recordings(3, duration_s=1.0, n_sessions=3, random_state=0)
    per_class, per_session = [], []
    for signal, label, session in zip(rec.signals, rec.labels, rec.session, strict=True):
        date, surface = DATES[int(session.rsplit("/", 1)[1])], rec.class_names[label]
        per_class.append(write_csv_recording(root / "a" / surface / f"{date}.csv", signal, rec.rate_hz))
        per_session.append(write_csv_recording(root / "b" / date / f"{surface}.csv", signal, rec.rate_hz))
    return per_class, per_session, rec.class_names


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_train_reads_both_trees_alike_and_says_how_first(trees, capsys):
    per_class, per_session, names = trees
    reports = []
    for paths, layout in ((per_class, "folder per class"), (per_session, "folder per session")):
        status, out, err = _run(["train", "--data", *paths, "--method", "lda", "--window", "200"], capsys)
        assert status == 0, err
        first, second = out.splitlines()[:2]
        assert f"9 files read as {layout}" in first and f"3 classes ({', '.join(sorted(names))})" in first
        assert f"3 sessions ({', '.join(DATES)})" in first and "recordings at 800 Hz" in second
        reports.append(out[out.index("\nclass ") :])
    assert reports[0] == reports[1]  # the same recordings, the same classes and sessions: the same report


def test_the_sessions_cluster_gets_are_the_days_in_both_trees(trees):
    from tactile_torch.clustering import check_sessions

    for paths in trees[:2]:
        data = read_source(paths)
        assert sorted(set(data.session.tolist())) == list(DATES)
        check_sessions(data)  # every day holds every surface: standardisable within a day
    upside_down = read_source(trees[0], DataOptions(class_from="file"))
    assert upside_down.class_names == DATES  # what --class-from file says, as the tree was read before


@pytest.mark.parametrize("command", ["train", "cluster", "tradeoff", "predict"])
def test_an_ambiguous_tree_is_refused_before_any_work(tmp_path, capsys, command):
    rec = make_vibration_recordings(2, duration_s=0.5, random_state=0)
    paths = [
        write_csv_recording(tmp_path / f"day{d}" / f"run{r}.csv", rec.signals[r], rec.rate_hz)
        for d in (1, 2)
        for r in (0, 1)
    ]
    model = ["--model", tmp_path / "none.onnx"] if command == "predict" else []
    status, out, err = _run([command, "--data", *paths, *model, "--out", tmp_path / "out"], capsys)
    assert status == BAD_INPUT_EXIT and out == ""
    assert err.count("\n") == 1 and "cannot tell the classes from the sessions" in err
    assert "say where the classes are: --class-from folder (day1/run0.csv: class day1, session run0)" in err
    assert "or give an index CSV (--index, columns file,class,session)" in err
    assert not (tmp_path / "out").exists()


def test_class_from_reads_an_ambiguous_tree(tmp_path, capsys):
    rec = make_vibration_recordings(2, duration_s=1.0, random_state=0)
    paths = [
        write_csv_recording(tmp_path / f"day{d}" / f"run{r}.csv", rec.signals[r][200 * d :], rec.rate_hz)
        for d in (1, 2)
        for r in (0, 1)
    ]
    status, out, err = _run(["train", "--data", *paths, "--class-from", "file", "--window", "200"], capsys)
    assert status == 0, err
    assert "read as folder per session (as told: --class-from file, --session-from folder)" in out
    assert np.isin(["run0", "run1"], out.split()).all()
