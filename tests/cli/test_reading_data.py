"""A new user's recordings read right, and hostile data files refused in one line (issue 34, points 2, 4, 5,
12, 13): the sample rate of rounded time stamps, sessions from folders, gaps, and crafted files."""

import json
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.data import make_vibration_recordings
from tactile_torch.robot.files.data_sources import DataOptions, read_source
from tactile_torch.robot.stream.windows import window_recordings

G = 9.80665
USER_COLUMNS = ["--columns", "timestamp_ms,acc_x,acc_y,acc_z", "--units", "m/s2"]


def _user_log(path: Path, signal_g: np.ndarray, *, t0_ms: float = 1_700_000_000_000.0, t_ms=None) -> Path:
    """A logger's CSV: epoch milliseconds rounded to 0.1 ms (steps of 1.2 and 1.3 ms at 800 Hz), m/s^2."""
    t = np.round(t0_ms + np.arange(len(signal_g)) * 1.25 + 0.03, 1) if t_ms is None else t_ms
    path.parent.mkdir(parents=True, exist_ok=True)
    table = np.column_stack([t, np.asarray(signal_g, np.float64) * G])
    np.savetxt(
        path,
        table,
        delimiter=",",
        fmt=["%.1f", "%.6f", "%.6f", "%.6f"],
        header="timestamp_ms,acc_x,acc_y,acc_z",
        comments="",
    )
    return path


@pytest.fixture(scope="module")
def user(tmp_path_factory):
    """2 surfaces recorded on 2 days, one CSV per surface per day in day1/, day2/ (the issue's layout, small)."""
    root = tmp_path_factory.mktemp("user")
    rec = make_vibration_recordings(2, duration_s=3.0, n_sessions=2, random_state=0)
    paths = []
    for signal, label, session in zip(rec.signals, rec.labels, rec.session, strict=True):
        day = int(session.rsplit("/", 1)[1]) + 1
        name = ("carpet", "cork")[label]
        paths.append(_user_log(root / f"day{day}" / f"{name}.csv", signal, t0_ms=1.7e12 + day * 8.64e7))
    return root, sorted(paths), rec


def _run(argv, capsys):
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exit:  # refused by an option's parser
        status = exit.code
    out, err = capsys.readouterr()
    return status, out, err


def test_the_users_logs_train_at_800_hz_by_day_without_warnings(user, tmp_path, capsys):
    _root, paths, _ = user
    argv = [
        "train",
        "--data",
        *paths,
        *USER_COLUMNS,
        "--time-unit",
        "ms",
        "--window",
        "400",
        "--method",
        "lda",
    ]
    status, out, err = _run([*argv, "--out", tmp_path / "m.npz"], capsys)
    assert status == 0 and err == ""  # no "time steps vary" warnings, one per file
    first = f"{paths[0]} (and 3 more)"
    assert (
        f"{first}: 4 recordings at 800 Hz (from the time stamps; --rate states it), 2 sessions (folder per session)\n"
        in out
    )
    assert out.startswith(
        f"{first}: 4 files read as folder per session (the folder names (day1, day2) look like "
    )
    assert "2 folds grouped by session (none on both sides), stratified; 2 sessions: day1, day2\n" in out
    from tactile_torch.robot.files.model_file import load_model_file

    assert load_model_file(tmp_path / "m.npz").header["source"]["rate_hz"] == 800.0
    stated = read_source(
        paths,
        DataOptions(
            columns="timestamp_ms,acc_x,acc_y,acc_z", units="m/s2", time_unit="ms", sample_rate_hz=800
        ),
    )
    assert stated.rate_hz == 800.0 and list(stated.session) == ["day1", "day1", "day2", "day2"]


@pytest.mark.parametrize(
    ("option", "says"),
    [
        (
            ["--time-unit", "s"],
            "t in seconds (--time-unit s) gives 0.8 Hz, not a plausible accelerometer rate (10 Hz to 100000 Hz); "
            "t looks like milliseconds (800 Hz): pass --time-unit ms, or state the rate with --rate if it is right",
        ),
        (
            ["--time-unit", "us"],
            "t in microseconds (--time-unit us) gives 8e+05 Hz, not a plausible accelerometer rate (10 Hz to "
            "100000 Hz); t looks like milliseconds (800 Hz): pass --time-unit ms, or state the rate with --rate if "
            "it is right",
        ),
        (
            ["--time-unit", "ms", "--rate", "1000"],
            "the time stamps give 800 Hz (t in milliseconds), but --rate 1000 was stated; check the time column "
            "(--columns), its unit (--time-unit) and the rate",
        ),
    ],
)
def test_a_wrong_time_unit_or_rate_is_one_line(user, capsys, option, says):
    _, paths, _ = user
    status, out, err = _run(["train", "--data", *paths, *USER_COLUMNS, *option], capsys)
    assert status == BAD_INPUT_EXIT and out.count("\n") == 1 and "4 files read as folder per session" in out
    assert err == f"tactile-torch train: {paths[0]}: {says}\n"


def _logs(folder: Path, rec, *, rows=None) -> list[Path]:
    """``<class>_<n>.csv`` logs (t in s, g) of ``rec``; ``rows`` (index -> text) replaces lines of the first."""
    from tactile_torch.robot.files.csv_logs import write_csv_recording

    folder.mkdir(parents=True, exist_ok=True)
    paths = [
        write_csv_recording(folder / f"{session.replace('/', '_')}.csv", signal, rec.rate_hz)
        for signal, session in zip(rec.signals, rec.session, strict=True)
    ]  # glass_0.csv, glass_1.csv, aluminium_0.csv, ...
    if rows:
        lines = paths[0].read_text().splitlines()
        for i, text in rows.items():
            lines[i] = text
        paths[0].write_text("\n".join(lines) + "\n")
    return paths


@pytest.fixture(scope="module")
def small():
    return make_vibration_recordings(2, duration_s=2.5, n_sessions=2, random_state=1)


@pytest.mark.parametrize("value", ["1e308", "1e30"])
def test_a_huge_sample_is_one_line_whatever_its_size(small, tmp_path, capsys, value):
    paths = _logs(tmp_path, small, rows={101: f"0.125,{value},0,1"})
    status, _out, err = _run(["train", "--data", *paths], capsys)
    reads = "3.4e+38 g or more (beyond float32)" if value == "1e308" else "1e+30 g"
    assert status == BAD_INPUT_EXIT and err == (
        f"tactile-torch train: {paths[0]}: sample 100 (t = 0.125 s) reads {reads} on x, beyond the sensor's "
        "±5 g (1 samples beyond); declare the range with --sensor-range G, or the units with --units / --scale\n"
    )
    # where windows beyond the range are left out (predict), 1e308 is a finite sample like 1e30, not inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "overflow encountered in cast"
        data = read_source(paths, DataOptions(check=False))
    assert np.isfinite(data.signals[0]).all() and abs(data.signals[0][100, 0]) >= 1e30


def test_a_recording_shorter_than_a_window_is_named(small, tmp_path, capsys):
    glass_0, _, aluminium_0, aluminium_1 = _logs(tmp_path, small)
    aluminium_0.write_text("\n".join(aluminium_0.read_text().splitlines()[:301]) + "\n")  # 300 samples
    status, _out, err = _run(["train", "--data", glass_0, aluminium_0], capsys)
    assert status == BAD_INPUT_EXIT
    assert err == (
        f"tactile-torch train: {glass_0} (and 1 more): every recording of class 'aluminium' is shorter than one "
        f"window of 800 samples (1 s at 800 Hz); the longest, {aluminium_0}, has 300 samples: pass a smaller window "
        "(--window) or longer recordings\n"
    )
    # with a long recording of the class too, the short one is left out, said once
    with pytest.warns(
        UserWarning, match=r"1 of 3 recordings are shorter than one window of 800 samples and give none"
    ):
        from tactile_torch.features.files import load_features

        load_features(read_source([glass_0, aluminium_0, aluminium_1]), window=800)


def test_no_window_spans_a_gap_in_the_time_stamps(small, tmp_path, capsys):
    paths = _logs(tmp_path, small)
    lines = paths[0].read_text().splitlines()
    t = np.arange(len(lines) - 1) / 800.0
    t[1000:] += 1.0  # the logger paused for 1 s after sample 1000
    paths[0].write_text(
        "\n".join(
            [lines[0], *(f"{ti:.9g},{ln.split(',', 1)[1]}" for ti, ln in zip(t, lines[1:], strict=True))]
        )
        + "\n"
    )
    with pytest.warns(UserWarning, match="1 gap"):
        data = read_source(paths)
    assert data.gaps[0].tolist() == [1000] and all(g.size == 0 for g in data.gaps[1:])
    cut = window_recordings(data.signals, 300, gaps=data.gaps)
    starts = cut.position[cut.recording == 0] * 300
    assert (cut.recording == 0).sum() == 1000 // 300 + 1000 // 300  # 3 windows before the gap, 3 after
    np.testing.assert_array_equal(cut.windows[cut.recording == 0][3], data.signals[0][1000:1300].T)
    assert starts.size == 6
    status, out, err = _run(["train", "--data", *paths, "--window", "300", "--method", "ncm"], capsys)
    assert status == 0 and err == (
        f"tactile-torch train: warning: 1 gap(s) in the time stamps of 1 of 4 file(s) (steps longer than 1.5 "
        f"sample periods; the longest, a 1 s gap 1.25 s into {paths[0]}): no window spans a gap\n"
    )
    assert "24 samples x 21 features" in out  # 6 + 3 x 6: without the gap's split, 7 + 18 = 25


def test_non_utf8_text_is_one_line_naming_the_field(tmp_path, capsys):
    rec = make_vibration_recordings(2, duration_s=1.5, random_state=0)
    np.savez(
        tmp_path / "latin.npz",
        signals=np.stack(rec.signals),
        labels=rec.labels,
        class_names=np.array([b"caf\xe9", b"felt"]),
        rate_hz=800.0,
    )
    status, _, err = _run(["train", "--data", tmp_path / "latin.npz"], capsys)
    assert status == BAD_INPUT_EXIT and err == (
        f"tactile-torch train: {tmp_path / 'latin.npz'}: class_names must be UTF-8 text, got b'caf\\xe9' at index 0 "
        "(byte 0xe9 at position 3 is not UTF-8)\n"
    )
    log = tmp_path / "caf.csv"
    log.write_bytes(b"t,x,y,z\xe9\n0,0,0,1\n")
    status, _out, err = _run(["train", "--data", log], capsys)
    assert status == BAD_INPUT_EXIT and err == (
        f"tactile-torch train: {log}: not UTF-8 text (byte 0xe9 at offset 7); a CSV log is text: t,x,y,z numbers, "
        "comma-separated\n"
    )


def _flip(path: Path, member: str, at: int) -> bytes:
    """The archive's bytes with byte ``at`` of ``member``'s compressed data inverted."""
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo(member)
    local = info.header_offset
    start = (
        local
        + 30
        + int.from_bytes(raw[local + 26 : local + 28], "little")
        + int.from_bytes(raw[local + 28 : local + 30], "little")
    )
    raw[start + at] ^= 0xFF
    return bytes(raw)


def test_a_byte_flipped_inside_a_compressed_member_is_one_line(tmp_path, capsys):
    rec = make_vibration_recordings(2, duration_s=1.5, random_state=0)
    good = tmp_path / "good.npz"
    np.savez_compressed(
        good,
        signals=np.stack(rec.signals),
        labels=rec.labels,
        class_names=np.array(rec.class_names),
        rate_hz=800.0,
    )
    with zipfile.ZipFile(good) as archive:
        size = archive.getinfo("signals.npy").compress_size
    causes = set()
    for at in range(size // 7, size, size // 7):  # a flip breaks the deflate stream or its CRC-32
        bad = tmp_path / f"flip_{at}.npz"
        bad.write_bytes(_flip(good, "signals.npy", at))
        status, _out, err = _run(["train", "--data", bad], capsys)
        assert status == BAD_INPUT_EXIT and err.count("\n") == 1, err
        prefix = f"tactile-torch train: {bad}: signals.npy is corrupt ("
        suffix = "): the data file (.npz of docs/formats.md) was damaged (a flipped bit, a cut copy); copy or write it again\n"
        assert err.startswith(prefix) and err.endswith(suffix), err
        causes.add(err[len(prefix) :].split(" ")[0])
    assert {"Error", "Bad"} <= causes  # zlib's "Error -3 while decompressing" and "Bad CRC-32" both seen


@pytest.mark.parametrize("window", [5, 2 * 10**12])
def test_a_model_header_declaring_a_window_train_never_makes_is_refused(tmp_path, capsys, window):
    from tactile_torch.features.files import load_features
    from tactile_torch.robot.files.model_file import HEADER
    from tactile_torch.training import save_model, train_classifier

    rec = make_vibration_recordings(2, duration_s=2.0, n_sessions=2, random_state=0)
    features = load_features(read_source(_logs(tmp_path / "logs", rec)), window=200)
    path = save_model(tmp_path / "m.npz", train_classifier(features, "ncm", random_state=0), features)
    arrays = dict(np.load(path))
    header = json.loads(str(arrays.pop(HEADER)))
    header["source"]["window"] = window
    np.savez(tmp_path / "crafted.npz", **{HEADER: np.array(json.dumps(header))}, **arrays)
    status, _out, err = _run(
        ["export", "--model", tmp_path / "crafted.npz", "--out", tmp_path / "c.onnx"], capsys
    )
    assert status == BAD_INPUT_EXIT and not (tmp_path / "c.onnx").exists()
    assert err == (
        f"tactile-torch export: {tmp_path / 'crafted.npz'}: source.window must be a number of samples in 16 .. "
        f"1,048,576 (what train makes), got {window}\n"
    )


def test_cluster_refuses_sessions_of_one_surface_before_any_work(tmp_path, capsys, monkeypatch):
    import tactile_torch.features.files

    rec = make_vibration_recordings(2, duration_s=2.0, n_sessions=2, random_state=0)
    session = np.array([rec.class_names[label] for label in rec.labels])  # every session one surface
    np.savez(
        tmp_path / "s.npz",
        signals=np.stack(rec.signals),
        labels=rec.labels,
        class_names=np.array(rec.class_names),
        rate_hz=800.0,
        session=session,
    )

    def no_work(*args, **kwargs):
        raise AssertionError("features were computed before the sessions were checked")

    monkeypatch.setattr(tactile_torch.features.files, "load_features", no_work)
    status, _out, err = _run(
        ["cluster", "--data", tmp_path / "s.npz", "--sessions", "standardise", "--out", tmp_path / "k"],
        capsys,
    )
    assert status == BAD_INPUT_EXIT and err == (
        f"tactile-torch cluster: {tmp_path / 's.npz'}: 2 of 2 sessions hold a single surface (session "
        f"'{min(rec.class_names)}': 2 recording(s), all '{min(rec.class_names)}'); standardising within such a session "
        "would remove its surface (sessions must each hold the same mix of surfaces: one folder per session, or an "
        "index CSV, --index)\n"
    )


def test_a_time_block_split_says_why_in_words_the_data_bear_out():
    from tactile_torch.features.files import FeatureSet
    from tactile_torch.training import held_out_folds

    # 2 classes, each 2 recordings of one session ("a", "b"): not a single recording per class
    recording = np.repeat(np.arange(4), 10)
    y = np.repeat([0, 0, 1, 1], 10)
    position = np.tile(np.arange(10), 4)
    features = FeatureSet(
        np.zeros((40, 21)),
        y,
        ("a", "b"),
        {"kind": "vibration", "window": 100, "step": 100},
        groups=np.repeat(["a", "a", "b", "b"], 10),
        recording=recording,
        position=position,
    )
    _, _, split = held_out_folds(features, 5, random_state=0)
    assert "(2 of 2 classes have a single session (the 2 recordings of 'a' are one session))" in split
    assert "a class has a single recording" not in split


def test_simulate_sensor_plays_the_users_csv_at_its_rate(user, monkeypatch, capsys):
    import io

    import serial

    from tactile_torch.robot.stream.wire import parse_sample

    _, paths, rec = user
    wire = io.BytesIO()
    wire.close = lambda: None
    monkeypatch.setattr(serial, "serial_for_url", lambda url, **kw: wire)
    argv = [
        "simulate-sensor",
        "--data",
        paths[0],
        *USER_COLUMNS,
        "--time-unit",
        "ms",
        "--port",
        "x",
        "--fast",
    ]
    status, out, err = _run(argv, capsys)
    assert status == 0 and err == ""
    assert f"writing {len(rec.signals[0])} samples at 800 Hz ({paths[0]}; their own t) to x\n" in out
    sent = np.array([parse_sample(line) for line in wire.getvalue().splitlines()])
    np.testing.assert_allclose(sent, rec.signals[0], atol=2e-5)  # m/s^2 with 6 decimals, 5 on the wire
    status, out, err = _run([*argv, "--rate", "1000"], capsys)
    assert status == BAD_INPUT_EXIT and err == (
        f"tactile-torch simulate-sensor: {paths[0]}: the time stamps give 800 Hz (t in milliseconds), but --rate "
        "1000 was stated; check the time column (--columns), its unit (--time-unit) and the rate\n"
    )
