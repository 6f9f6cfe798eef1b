"""What the training commands read: recordings through the robot's readers (tactile_torch.robot.files.data_sources,
whose own tests, torch-free, are in tests/robot/), the held-out split of ``train`` on them, and model files
(tactile_torch.robot.files.model_file) at ``export``. These need the training extra, so they are not robot tests."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.data import VibrationRecordings, load_hapmat_imu5, make_vibration_recordings
from tactile_torch.features.files import load_features
from tactile_torch.robot.files.data_sources import DataOptions, read_source
from tactile_torch.robot.files.formats import read_csv_recordings
from tactile_torch.robot.files.model_file import FORMAT, load_model_file
from tactile_torch.training import held_out_folds, train_classifier
from tests.robot_data import write_logs as _logs

G = 9.80665


@pytest.fixture(scope="module")
def rec():
    """Four surfaces of the stylus simulator, one 4 s recording each (800 Hz, in g, with gravity on z)."""
    return make_vibration_recordings(4, duration_s=4.0, random_state=0)


def test_the_python_loader_reads_logs_as_the_command_line_does(tmp_path, rec):
    paths = _logs(tmp_path, rec)
    python = VibrationRecordings.from_arrays(read_csv_recordings(paths))  # the one CSV reader
    cli = read_source(paths)
    assert python.class_names == cli.class_names == tuple(sorted(rec.class_names))
    assert python.session.tolist() == cli.session.tolist() == ["1", "2"] * 4
    assert python.labels.tolist() == cli.labels.tolist()
    index = tmp_path / "index.csv"
    index.write_text(
        "file,class,session\n" + "".join(f"{p.name},surface{i % 2},{i}\n" for i, p in enumerate(paths))
    )
    indexed = read_source(paths, DataOptions(index=index))
    assert read_csv_recordings(paths, index=index).session.tolist() == indexed.session.tolist()


def test_the_hapmat_loader_and_columns_agree(shared_data):
    root = shared_data("hapmat_imu5")  # the real set as shipped
    files = sorted(root.glob("*.csv"))
    data = read_source(files, DataOptions(columns="time,accel_x,accel_y,accel_z"))
    assert data.class_names == load_hapmat_imu5(root).class_names


@pytest.mark.parametrize("command", ["train", "cluster", "tradeoff"])
def test_commands_refuse_implausible_recordings_in_one_line(tmp_path, rec, capsys, command):
    paths = _logs(tmp_path, rec)
    spiked = np.loadtxt(paths[3], delimiter=",", skiprows=1)
    spiked[100, 1] = 1e30
    np.savetxt(paths[3], spiked, delimiter=",", header="t,x,y,z", comments="", fmt="%.9g")
    argv = [command, "--data", *map(str, paths), "--out", str(tmp_path / "out")]
    assert main(argv) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    *layout, line = (
        err.splitlines()
    )  # tradeoff says how it reads the files on stderr first, the others on stdout
    assert len(layout) == (command == "tradeoff") and all("8 files read as file names" in s for s in layout)
    assert line.startswith(f"tactile-torch {command}: {paths[3]}: sample 100"), err
    assert "reads 1e+30 g on x, beyond the sensor's ±5 g" in err
    assert not (tmp_path / "out").exists()


def test_cli_reads_m_s2_logs_in_ms_with_options(tmp_path, rec, capsys):
    paths = _logs(tmp_path, rec, header="time_ms,ax,ay,az", t_factor=1e3, factor=G)
    argv = ["train", "--data", *map(str, paths), "--window", "200", "--columns", "time_ms,ax,ay,az"]
    assert main(argv) == BAD_INPUT_EXIT
    assert (
        "t looks like milliseconds: a step of 1.25 s would be 0.8 Hz; pass --time-unit ms"
        in capsys.readouterr().err
    )
    assert main([*argv, "--time-unit", "ms"]) == BAD_INPUT_EXIT
    assert "pass --units m/s2" in capsys.readouterr().err
    out = tmp_path / "model.npz"
    assert main([*argv, "--time-unit", "ms", "--units", "m/s2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "grouped by session" in text and "overall accuracy" in text
    from tactile_torch.robot.files.model_file import load_model_file

    assert load_model_file(out).header["source"]["rate_hz"] == 800.0


def test_train_holds_out_whole_sessions_or_time_blocks(tmp_path, rec):
    grouped = load_features(_logs(tmp_path, rec), window=200)
    keep, folds, split = held_out_folds(grouped, 5, random_state=0)
    assert "2 folds grouped by session" in split and len(keep) == len(grouped.y)
    for train, test in folds:  # no session on both sides
        assert not set(grouped.groups[keep][train]) & set(grouped.groups[keep][test])
    # one recording per class, windows overlapping by 3/4: time blocks with 4 guard windows
    path = tmp_path / "one.npz"
    rec.save(path)
    single = load_features(path, window=200, step=50)
    keep, folds, split = held_out_folds(single, 5, random_state=0)
    assert "5 folds of consecutive time blocks" in split and "the first 4 windows" in split
    start = single.position[keep] * 50
    for train, test in folds:
        for r in range(4):
            a = start[train][single.recording[keep][train] == r]
            b = start[test][single.recording[keep][test] == r]
            assert np.abs(a[:, None] - b[None, :]).min() >= 200  # no shared sample
    model = train_classifier(single, "svm", random_state=0)
    assert model.split == split and len(model.fold_accuracy) == 5


def test_declared_sensor_range_reaches_the_exported_bundle(tmp_path, rec, capsys):
    from tactile_torch.export.model_graph import pipeline_from_model
    from tactile_torch.robot.files.model_file import load_model_file

    paths = _logs(tmp_path, rec)
    table = np.loadtxt(paths[0], delimiter=",", skiprows=1)
    table[10, 3] = 6.5  # a 16 g sensor's sample, beyond the default ±5 g
    np.savetxt(paths[0], table, delimiter=",", header="t,x,y,z", comments="", fmt="%.9g")
    argv = ["train", "--data", *map(str, paths), "--method", "svm", "--window", "400"]
    assert main(argv) == BAD_INPUT_EXIT
    assert "sample 10 (t = 0.0125 s) reads 6.5 g on z" in capsys.readouterr().err
    out = tmp_path / "model.npz"
    assert main([*argv, "--sensor-range", "16", "--out", str(out)]) == 0
    model = load_model_file(out)
    assert model.source["sensor_range_g"] == 16.0
    assert pipeline_from_model(model).extra_metadata["sensor_range_g"] == 16.0  # export's default
    assert pipeline_from_model(model, sensor_range_g=8.0).extra_metadata["sensor_range_g"] == 8.0


def test_cli_trains_on_bags_written_outside(tmp_path, rec, capsys):
    from tests.robot.ros2.test_bags import write_imu_bag  # skips without the extra 'ros'

    bags = []
    for k, (signal, label) in enumerate(zip(rec.signals, rec.labels, strict=True)):
        for half, part in enumerate((signal[:1600], signal[1600:]), start=1):
            name = f"{rec.class_names[label]}_{half}"
            bags.append(write_imu_bag(tmp_path / name, part, 800.0, storage="mcap" if k % 2 else "sqlite3"))
    argv = ["train", "--data", *map(str, bags), "--topic", "/imu", "--window", "400"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "32 samples x 21 features (vibration), 4 classes" in text and "2 folds grouped by session" in text
    assert main([*argv[:-2], "--window", "400", "--topic", "/nope"]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no topic '/nope'; the bag has /imu (sensor_msgs/msg/Imu)" in err


class _RunsCode:
    """Unpickling this creates ``path``: a stand-in for whatever code a crafted pickle would run."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_export_runs_nothing_of_a_crafted_torch_save_file(tmp_path, capsys):
    crafted = tmp_path / "model.pt"
    torch.save({"format": FORMAT, "payload": _RunsCode(str(tmp_path / "ran"))}, crafted)
    # the file is genuinely malicious: the loader tactile-torch 0.1 used runs its code
    proof = tmp_path / "proof.pt"
    torch.save({"payload": _RunsCode(str(tmp_path / "ran-before"))}, proof)
    torch.load(proof, weights_only=False)
    assert (tmp_path / "ran-before").exists()
    with pytest.raises(ValueError, match=r"model\.pt: a torch\.save \(pickle\) file.*no longer unpickled"):
        load_model_file(crafted)
    assert main(["export", "--model", str(crafted), "--out", str(tmp_path / "m.onnx")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tactile-torch export: ") and "model.pt" in err
    assert not (tmp_path / "ran").exists() and not (tmp_path / "m.onnx").exists()
