"""Recordings in, checked: CSV logs with declared columns, units and time unit, the naming rule, ROS 2
bags written with rosbags' own writer (sqlite3 and MCAP), plausibility checks at train, cluster and
tradeoff, and the held-out split of ``train``."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.data import load_hapmat_imu5, load_vibration_csv, make_vibration_recordings
from tactile_torch.robot.csv_logs import class_and_session, read_csv_log
from tactile_torch.robot.data_sources import DataOptions, check_recordings, read_source
from tactile_torch.robot.ros_bags import MissingExtraError, read_bag
from tactile_torch.training import held_out_folds, load_features, train_classifier

G = 9.80665


@pytest.fixture(scope="module")
def rec():
    """Four surfaces, two 2 s recordings each (800 Hz, in g, with gravity on z)."""
    return make_vibration_recordings(4, duration_s=4.0, random_state=0)


def _log(path, signal, rate, *, header="t,x,y,z", t_factor=1.0, factor=1.0, fmt="%.9g"):
    t = np.arange(len(signal)) / rate * t_factor
    np.savetxt(
        path, np.column_stack([t, signal * factor]), delimiter=",", header=header, comments="", fmt=fmt
    )
    return path


def _logs(tmp_path, rec, **kwargs):
    """felt_1.csv, felt_2.csv ...: each recording cut in two halves, the sessions 1 and 2."""
    paths = []
    for signal, label in zip(rec.signals, rec.labels, strict=True):
        half = len(signal) // 2
        for k, part in enumerate((signal[:half], signal[half:]), start=1):
            paths.append(_log(tmp_path / f"{rec.class_names[label]}_{k}.csv", part, rec.rate_hz, **kwargs))
    return paths


# ------------------------------------------------------------------------------------------ naming
def test_naming_rule_is_the_same_in_python_and_on_the_command_line(tmp_path, rec):
    assert class_and_session("logs/felt_3.csv") == ("felt", "3")
    assert class_and_session("glass.csv") == ("glass", "glass")
    assert class_and_session("rough_wood_12.mcap") == ("rough_wood", "12")
    assert class_and_session("felt_a.csv") == ("felt_a", "felt_a")
    paths = _logs(tmp_path, rec)
    python = load_vibration_csv(paths)
    cli = read_source(paths)
    assert python.class_names == cli.class_names == tuple(sorted(rec.class_names))
    assert python.session.tolist() == cli.session.tolist() == ["1", "2"] * 4
    assert python.labels.tolist() == cli.labels.tolist()
    index = tmp_path / "index.csv"
    index.write_text(
        "file,class,session\n" + "".join(f"{p.name},surface{i % 2},{i}\n" for i, p in enumerate(paths))
    )
    indexed = read_source(paths, DataOptions(index=index))
    assert indexed.class_names == ("surface0", "surface1") and indexed.session.tolist()[:3] == ["0", "1", "2"]
    assert load_vibration_csv(paths, index=index).session.tolist() == indexed.session.tolist()


def test_index_errors(tmp_path, rec):
    paths = _logs(tmp_path, rec)
    bad = tmp_path / "bad.csv"
    bad.write_text("name,label\nfelt_1.csv,felt\n")
    with pytest.raises(ValueError, match=r"bad\.csv: an index CSV needs the columns file,class"):
        read_source(paths, DataOptions(index=bad))
    few = tmp_path / "few.csv"
    few.write_text(f"file,class\n{paths[0].name},felt\n")
    with pytest.raises(
        ValueError, match=r"few\.csv: lists no class for .*_2\.csv \(7 file\(s\) not in the index\)"
    ):
        read_source(paths, DataOptions(index=few))


# ------------------------------------------------------------------------------------------ CSV options
def test_csv_in_m_s2_with_headers_and_t_in_ms(tmp_path, rec):
    signal = rec.signals[0]
    path = _log(tmp_path / "ms2.csv", signal, 800.0, header="time,ax,ay,az", factor=G)
    with pytest.raises(ValueError, match=r"ms2\.csv: no column 'x' .*columns='time,ax,ay,az'"):
        read_csv_log(path)
    # read as g, the m/s^2 log is refused where the data come in, naming the file and the fix
    with pytest.raises(
        ValueError,
        match=r"ms2\.csv: the mean acceleration is 9\.\d+ g .*look like m/s\^2 .*; pass units='m/s2'",
    ):
        read_source([path], DataOptions(columns="time,ax,ay,az"))
    back = read_source([path], DataOptions(columns="time,ax,ay,az", units="m/s2"))
    np.testing.assert_allclose(back.signals[0], signal, atol=1e-5)
    by_index, rate = read_csv_log(path, columns=[0, 1, 2, 3], units="m/s2")
    np.testing.assert_allclose(by_index, signal, atol=1e-5)
    three, _ = read_csv_log(path, columns="ax,ay,az", units="m/s2")  # time found by name
    np.testing.assert_array_equal(three, by_index)
    assert rate == 800.0
    ms = _log(tmp_path / "ms.csv", signal, 800.0, t_factor=1e3)
    with pytest.raises(
        ValueError,
        match=r"t looks like milliseconds: a step of 1\.25 s would be 0\.8 Hz; pass time_unit='ms'",
    ):
        read_csv_log(ms)
    assert read_csv_log(ms, time_unit="ms")[1] == 800.0
    us = _log(tmp_path / "us.csv", signal, 800.0, t_factor=1e6)
    with pytest.raises(ValueError, match="t looks like microseconds"):
        read_csv_log(us)
    assert read_csv_log(us, time_unit="us")[1] == 800.0
    # a declared unit is checked as "auto" is (issue 34): 0.8 Hz and 800 kHz are refused, naming the fix
    with pytest.raises(
        ValueError, match=r"t in seconds \(time_unit='s'\) gives 0\.8 Hz, .*pass time_unit='ms'"
    ):
        read_csv_log(ms, time_unit="s")
    with pytest.raises(ValueError, match=r"t in microseconds \(time_unit='us'\) gives 8e\+05 Hz"):
        read_csv_log(ms, time_unit="us")
    assert read_csv_log(ms, time_unit="s", sample_rate_hz=0.8)[1] == 0.8  # a stated rate: taken as said


def test_integer_counts_csv_and_npz_alike(tmp_path, rec):
    counts = np.round(rec.signals[0] / 0.0039).astype(np.int16)
    path = _log(tmp_path / "counts.csv", counts, 800.0, fmt=["%.9g", "%d", "%d", "%d"])
    npz = tmp_path / "counts.npz"
    np.savez(npz, signals=counts[None], labels=np.array([0]), class_names=np.array(["a"]), rate_hz=800.0)
    message = r"accelerations must be in g or m/s\^2, got .* \(raw sensor counts\?\); declare the scale"
    for source in ([path], npz):
        with pytest.raises(ValueError, match=message):
            read_source(source)
        back = read_source(source, DataOptions(scale=0.0039))
        np.testing.assert_allclose(back.signals[0], counts * 0.0039, atol=1e-6)


def test_hapmat_as_shipped_loads_with_columns(tmp_path, shared_data):
    try:
        root = shared_data("hapmat_imu5")
        files = sorted(root.glob("*.csv"))
    except pytest.skip.Exception:  # the same layout, synthetic: time,accel_x..,gyro_x..
        rng = np.random.default_rng(0)
        files = []
        for name in ("Fabric_1", "Wood_1"):
            table = np.column_stack([np.arange(600) / 100, rng.normal(0, 0.05, (600, 9))])
            header = "time,accel_x,accel_y,accel_z,gyro_x,gyro_y,gyro_z,rota_x,rota_y,rota_z"
            files.append(tmp_path / f"{name}.csv")
            np.savetxt(files[-1], table, delimiter=",", header=header, comments="", fmt="%.6f")
    with pytest.raises(ValueError, match="columns='time,accel_x,accel_y,accel_z'"):
        read_source(files)
    data = read_source(files, DataOptions(columns="time,accel_x,accel_y,accel_z"))
    assert data.rate_hz == 100.0 and data.class_names[0] == "Fabric" and set(data.session) == {"1"}
    if len(files) == 5:
        assert data.class_names == load_hapmat_imu5(files[0].parent).class_names


# ------------------------------------------------------------------------------------------ plausibility
@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda s: s * G, r"look like m/s\^2"),
        (
            lambda s: s.__setitem__((1234, 2), 1e30) or s,
            r"sample 1234 \(t = 1\.542 s\) reads 1e\+30 g on z, beyond the sensor's ±5 g",
        ),
        (lambda s: s.__setitem__((10, 0), -7.5) or s, r"sample 10 .* reads -7\.5 g on x"),
        (lambda s: np.ones_like(s), r"all 3200 samples are equal \(1, 1, 1 g\): no vibration"),
    ],
)
def test_implausible_recordings_are_refused_naming_file_and_sample(rec, change, match):
    signals = [s.copy() for s in rec.signals]
    signals[2] = change(signals[2])
    names = [f"rec_{i}.csv" for i in range(4)]
    with pytest.raises(
        ValueError, match=rf"rec_2\.csv: .*{match}" if "look" in match else rf"rec_2\.csv: {match}"
    ):
        check_recordings(signals, names, 800.0)
    check_recordings(rec.signals, names, 800.0)  # the simulator's recordings pass
    if "-7.5" in match:  # a wider sensor, declared
        check_recordings(signals, names, 800.0, sensor_range_g=8.0)


@pytest.mark.parametrize("command", ["train", "cluster", "tradeoff"])
def test_commands_refuse_implausible_recordings_in_one_line(tmp_path, rec, capsys, command):
    paths = _logs(tmp_path, rec)
    spiked = np.loadtxt(paths[3], delimiter=",", skiprows=1)
    spiked[100, 1] = 1e30
    np.savetxt(paths[3], spiked, delimiter=",", header="t,x,y,z", comments="", fmt="%.9g")
    argv = [command, "--data", *map(str, paths), "--out", str(tmp_path / "out")]
    assert main(argv) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tactile-torch {command}: {paths[3]}: sample 100"), err
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
    from tactile_torch.robot.model_file import load_model_file

    assert load_model_file(out).header["source"]["rate_hz"] == 800.0


# ------------------------------------------------------------------------------------------ train's split
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


def test_bags_without_rosbags_get_one_line_naming_the_extra(tmp_path, monkeypatch, capsys):
    bag = tmp_path / "run"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)  # as without the extra
    with pytest.raises(
        MissingExtraError, match=r"needs the optional extra 'ros' .*pip install 'tactile-torch\[ros\]'"
    ):
        read_bag(bag)
    assert main(["train", "--data", str(bag)]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'tactile-torch[ros]'" in err


def test_declared_sensor_range_reaches_the_exported_bundle(tmp_path, rec, capsys):
    from tactile_torch.pipeline import pipeline_from_model
    from tactile_torch.robot.model_file import load_model_file

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


def test_data_options_are_written_back_into_the_command_line():
    from tactile_torch.cli import build_parser
    from tactile_torch.cli._options import data_option_words, data_options

    argv = [
        "tradeoff",
        "--data",
        "a.csv",
        "--columns",
        "time,ax,ay,az",
        "--units",
        "m/s2",
        "--time-unit",
        "ms",
    ]
    argv += ["--sensor-range", "16", "--shape", "4,5", "--scale", "0.0039", "--index", "i.csv"]
    args = build_parser().parse_args(argv)
    words = " ".join(data_option_words(args)).split()
    again = build_parser().parse_args(["tradeoff", "--data", "a.csv", *words])
    assert data_options(again) == data_options(args)
    assert data_options(args).sensor_range_g == 16.0 and data_options(args).shape == (4, 5)
    assert data_option_words(build_parser().parse_args(["tradeoff", "--data", "a.csv"])) == []
