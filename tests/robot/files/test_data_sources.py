"""Recordings in, checked: CSV logs with declared columns, units and time unit, the naming rule, the
plausibility checks, ROS 2 bags without their extra. Torch-free, as on the robot (the training commands
reading the same data: tests/cli/test_training_inputs.py)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.robot.files.csv_logs import read_csv_log
from tactile_torch.robot.files.data_sources import DataOptions, check_recordings, read_source
from tactile_torch.robot.files.naming import class_and_session
from tactile_torch.robot.ros2.bags import read_bag
from tactile_torch.robot.ros2.message_types import MissingExtraError
from tests.robot_data import surface_recordings
from tests.robot_data import write_log as _log
from tests.robot_data import write_logs as _logs
from tests.stream_helpers import energy_bundle

G = 9.80665


@pytest.fixture(scope="module")
def rec():
    """Four surfaces, one 4 s recording each (800 Hz, in g, with gravity on z)."""
    return surface_recordings(4, 4.0)


# ------------------------------------------------------------------------------------------ naming
def test_naming_rule_is_the_same_in_python_and_on_the_command_line(tmp_path, rec):
    assert class_and_session("logs/felt_3.csv") == ("felt", "3")
    assert class_and_session("glass.csv") == ("glass", "glass")
    assert class_and_session("rough_wood_12.mcap") == ("rough_wood", "12")
    assert class_and_session("felt_a.csv") == ("felt_a", "felt_a")
    paths = _logs(tmp_path, rec)
    cli = read_source(paths)  # the Python loader reads the same: tests/cli/test_training_inputs.py
    assert cli.class_names == tuple(sorted(rec.class_names))
    assert cli.session.tolist() == ["1", "2"] * 4
    assert [cli.class_names[label] for label in cli.labels] == [p.stem.split("_")[0] for p in paths]
    index = tmp_path / "index.csv"
    index.write_text(
        "file,class,session\n" + "".join(f"{p.name},surface{i % 2},{i}\n" for i, p in enumerate(paths))
    )
    indexed = read_source(paths, DataOptions(index=index))
    assert indexed.class_names == ("surface0", "surface1") and indexed.session.tolist()[:3] == ["0", "1", "2"]


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
    by_index = read_csv_log(path, columns=[0, 1, 2, 3], units="m/s2")
    np.testing.assert_allclose(by_index.signal, signal, atol=1e-5)
    three = read_csv_log(path, columns="ax,ay,az", units="m/s2")  # time found by name
    np.testing.assert_array_equal(three.signal, by_index.signal)
    assert by_index.rate_hz == 800.0 and by_index.t[1] == 1 / 800.0  # the stamps as logged, in seconds
    ms = _log(tmp_path / "ms.csv", signal, 800.0, t_factor=1e3)
    with pytest.raises(
        ValueError,
        match=r"t looks like milliseconds: a step of 1\.25 s would be 0\.8 Hz; pass time_unit='ms'",
    ):
        read_csv_log(ms)
    assert read_csv_log(ms, time_unit="ms").rate_hz == 800.0
    us = _log(tmp_path / "us.csv", signal, 800.0, t_factor=1e6)
    with pytest.raises(ValueError, match="t looks like microseconds"):
        read_csv_log(us)
    assert read_csv_log(us, time_unit="us").rate_hz == 800.0
    # a declared unit is checked as "auto" is (issue 34): 0.8 Hz and 800 kHz are refused, naming the fix
    with pytest.raises(
        ValueError, match=r"t in seconds \(time_unit='s'\) gives 0\.8 Hz, .*pass time_unit='ms'"
    ):
        read_csv_log(ms, time_unit="s")
    with pytest.raises(ValueError, match=r"t in microseconds \(time_unit='us'\) gives 8e\+05 Hz"):
        read_csv_log(ms, time_unit="us")
    assert read_csv_log(ms, time_unit="s", sample_rate_hz=0.8).rate_hz == 0.8  # a stated rate: taken as said


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
    check_recordings(rec.signals, names, 800.0)  # the recordings as made pass
    if "-7.5" in match:  # a wider sensor, declared
        check_recordings(signals, names, 800.0, sensor_range_g=8.0)


def test_bags_without_rosbags_get_one_line_naming_the_extra(tmp_path, monkeypatch, capsys):
    bag = tmp_path / "run"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)  # as without the extra
    with pytest.raises(
        MissingExtraError, match=r"needs the optional extra 'ros' .*pip install 'tactile-torch\[ros\]'"
    ):
        read_bag(bag)
    model = energy_bundle(tmp_path / "m.onnx")  # predict reads --data as train does, on the robot
    assert main(["predict", "--model", str(model), "--data", str(bag)]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'tactile-torch[ros]'" in err


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
