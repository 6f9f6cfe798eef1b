"""The data formats (tactile_torch.robot.files.formats): round trips, no pickle, one error per documented bad input.

Torch-free, as on the robot (the data package's loaders through these formats, and the real data sets:
tests/data/test_files.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.lib.stride_tricks import sliding_window_view

from tactile_torch.robot.files.csv_logs import read_csv_log, write_csv_recording
from tactile_torch.robot.files.formats import (
    ExplorationArrays,
    FeatureArrays,
    RecordingArrays,
    read_data,
    read_explorations,
    read_features,
    read_recordings,
    write_explorations,
    write_features,
    write_recordings,
)
from tactile_torch.robot.files.naming import csv_class_name
from tactile_torch.robot.files.npz import read_npz, write_npz
from tactile_torch.robot.stream.windows import window_recordings
from tests.conftest import run_without_torch


def _recordings(lengths=(500, 800), seed=0):
    rng = np.random.default_rng(seed)
    return RecordingArrays(
        [rng.normal(size=(n, 3)).astype(np.float32) for n in lengths],
        np.arange(len(lengths)) % 2,
        ("cork", "felt"),
        800.0,
        np.array([f"run{i}" for i in range(len(lengths))]),
    )


def _same(a: RecordingArrays, b: RecordingArrays) -> None:
    assert len(a.signals) == len(b.signals)
    for x, y in zip(a.signals, b.signals, strict=True):
        np.testing.assert_array_equal(x, y)
    assert a.labels.tolist() == b.labels.tolist() and a.class_names == b.class_names
    assert a.rate_hz == b.rate_hz and list(a.session) == list(b.session)


# ------------------------------------------------------------------------------------ round trips
@pytest.mark.parametrize("lengths", [(600, 600, 600), (500, 800, 1201)])
def test_recordings_round_trip_without_pickle(tmp_path, lengths):
    rec = _recordings(lengths)
    path = write_recordings(tmp_path / "rec", rec)  # .npz appended, as numpy.savez does
    assert path.name == "rec.npz"
    with np.load(path, allow_pickle=False) as raw:
        assert all(raw[k].dtype != object for k in raw.files)
    back = read_data(path)
    assert back.kind == "vibration"
    _same(rec, back)


def test_image_and_feature_files_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    frames = rng.integers(0, 256, (3, 2, 5, 6, 3), dtype=np.uint8)
    images = ExplorationArrays(frames, None, np.array([0, 1, 1]), ("dots", "grid"), np.array([4, 4, 7]))
    back = read_data(write_explorations(tmp_path / "img.npz", images))
    assert back.kind == "image" and back.pressure is None
    np.testing.assert_array_equal(back.frames, frames)
    assert back.labels.tolist() == [0, 1, 1] and back.groups.tolist() == [4, 4, 7]
    pressure = ExplorationArrays(
        None, rng.random((2, 3, 4, 4)).astype(np.float32), np.array([1, 0]), ("a", "b")
    )
    back = read_explorations(write_explorations(tmp_path / "p.npz", pressure))
    np.testing.assert_array_equal(back.pressure, pressure.pressure)
    feats = FeatureArrays(rng.normal(size=(7, 4)), np.array([0, 1, 2, 0, 1, 2, 0]), ("x", "y", "z"))
    back = read_features(write_features(tmp_path / "f.npz", feats))
    np.testing.assert_array_equal(back.features, feats.features)
    assert back.class_names == ("x", "y", "z") and back.labels.tolist() == feats.labels.tolist()


def test_feature_labels_without_class_names_may_be_strings(tmp_path):
    np.savez(tmp_path / "f.npz", features=np.eye(3), labels=np.array(["glass", "cork", "glass"]))
    data = read_features(tmp_path / "f.npz")
    assert data.class_names == ("cork", "glass") and data.labels.tolist() == [1, 0, 1]
    np.savez(tmp_path / "u.npz", features=np.eye(3))  # unlabelled: clustering and prediction take it
    assert read_features(tmp_path / "u.npz").labels is None
    with pytest.raises(ValueError, match=r"u\.npz: missing 'labels'"):
        read_features(tmp_path / "u.npz", require_labels=True)


def test_csv_round_trip_and_class_names(tmp_path):
    rec = _recordings((400,))
    path = write_csv_recording(tmp_path / "cork_3.csv", rec.signals[0], 800.0)
    assert path.read_text().splitlines()[0] == "t,x,y,z"
    log = read_csv_log(path)
    np.testing.assert_array_equal(log.signal, rec.signals[0])
    assert log.rate_hz == 800.0 and csv_class_name(path) == "cork"
    write_csv_recording(tmp_path / "felt.csv", rec.signals[0][:300], 800.0)
    both = read_data([path, tmp_path / "felt.csv"])
    assert both.kind == "vibration" and both.class_names == ("cork", "felt")
    assert [len(s) for s in both.signals] == [400, 300] and list(both.session) == ["3", "felt"]
    write_csv_recording(tmp_path / "slow.csv", rec.signals[0], 100.0)
    with pytest.raises(ValueError, match="different sample rates"):
        read_data([path, tmp_path / "slow.csv"])


def test_write_npz_is_exact_and_atomic(tmp_path):
    path = write_npz(tmp_path / "model.bin", {"a": np.arange(3)})
    assert path == tmp_path / "model.bin" and read_npz(path)["a"].tolist() == [0, 1, 2]
    with pytest.raises(TypeError, match="plain"):
        write_npz(tmp_path / "model.bin", {"a": np.array([{}], dtype=object)})
    assert read_npz(path)["a"].tolist() == [0, 1, 2]  # the failed write left the old file intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.bin"]  # and no temporary file


# ------------------------------------------------------------------------------------ legacy files
def test_legacy_object_arrays_need_allow_pickle_and_never_run_code(tmp_path):
    rec = _recordings((300, 450))
    signals = np.empty(2, dtype=object)
    signals[:] = rec.signals
    arrays = {"labels": rec.labels, "class_names": np.array(rec.class_names), "rate_hz": 800.0}
    np.savez(tmp_path / "old.npz", signals=signals, **arrays)
    with pytest.raises(ValueError, match=r"old\.npz: signals is a pickled object array"):
        read_recordings(tmp_path / "old.npz")
    back = read_recordings(tmp_path / "old.npz", allow_pickle=True)
    assert [len(s) for s in back.signals] == [300, 450]
    # a crafted object array: refused before anything is unpickled
    marker = tmp_path / "ran"
    evil = np.empty(1, dtype=object)
    evil[0] = _RunsCode(str(marker))
    np.savez(tmp_path / "evil.npz", signals=evil, **arrays)
    with pytest.raises(ValueError, match="pickled object array"):
        read_data(tmp_path / "evil.npz")
    assert not marker.exists()


class _RunsCode:
    """Unpickling this creates a file: what a crafted pickle could do instead."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


# ------------------------------------------------------------------------------------ windowing
@settings(max_examples=30, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 90), min_size=1, max_size=4),
    size=st.integers(2, 40),
    step=st.integers(1, 25),
)
def test_window_recordings_equals_a_sliding_window_view_per_recording(lengths, size, step):
    rng = np.random.default_rng(sum(lengths) + size * step)
    signals = [rng.normal(size=(n, 3)).astype(np.float32) for n in lengths]
    if max(lengths) < size:
        with pytest.raises(ValueError, match=f"no recording holds a window of {size} samples"):
            window_recordings(signals, size, step)
        return
    cut = window_recordings(signals, size, step)
    # numpy's sliding windows (the torch ones, signal.sliding_windows, are tested against the same:
    # tests/data/test_files.py)
    reference = [sliding_window_view(s, size, axis=0)[::step] for s in signals if len(s) >= size]
    np.testing.assert_array_equal(cut.windows, np.concatenate(reference))
    assert cut.windows.flags.c_contiguous and cut.windows.dtype == np.float32
    for w, r, p in zip(cut.windows, cut.recording, cut.position, strict=True):
        np.testing.assert_array_equal(w, signals[r][p * step : p * step + size].T)


# ------------------------------------------------------------------------------------ errors
def _vib(**change):
    arrays = {
        "signals": np.zeros((2, 50, 3), np.float32),
        "labels": np.array([0, 1]),
        "class_names": np.array(["a", "b"]),
        "rate_hz": np.float64(800.0),
    }
    arrays.update(change)
    return {k: v for k, v in arrays.items() if v is not None}


@pytest.mark.parametrize(
    ("arrays", "match"),
    [
        (
            _vib(rate_hz=None),
            r"missing 'rate_hz'; vibration recordings need signals, labels, class_names, rate_hz",
        ),
        (
            _vib(signals=np.zeros((2, 50, 2), np.float32)),
            r"signals must have shape \(R, n, 3\).*got \(2, 50, 2\)",
        ),
        (
            _vib(signals=np.zeros((2, 50, 3), np.int16)),
            r"signals: accelerations must be in g or m/s\^2, got int16 \(raw sensor counts\?\); declare the scale",
        ),
        (_vib(signals=np.full((2, 50, 3), np.nan)), r"signals must be finite, got 300 NaN/inf value\(s\)"),
        (_vib(labels=np.array([0.0, 1.0])), r"labels must be integers of shape \(2,\), got float64"),
        (_vib(labels=np.array([0, 5])), r"labels must index class_names \(0\.\.1\), got values 0\.\.5"),
        (_vib(class_names=np.array([1, 2])), "class_names must be a 1-D array of strings, got int64"),
        (_vib(rate_hz=np.float64(-1.0)), "rate_hz must be one number > 0"),
        (
            _vib(signals=np.zeros((90, 3), np.float32), lengths=np.array([40, 40])),
            "lengths must add up to the 90 samples of signals, got 80",
        ),
        (_vib(session=np.array(["s"])), r"session must have shape \(2,\)"),
    ],
)
def test_recording_errors_name_file_and_field(tmp_path, arrays, match):
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ValueError, match=r"bad\.npz: " + match):
        read_recordings(tmp_path / "bad.npz")


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"", r"empty file \(0 bytes\), expected a data file"),
        (b"PK\x03\x04 cut short", "truncated or corrupt data file"),
        (b"\x93NUMPY\x01\x00", r"expected a data file .*found a single \.npy array"),
        (b"ir_version: 8 (an onnx model, say)", "expected a data file .*found not a zip archive"),
    ],
)
def test_unreadable_files_get_one_line(tmp_path, content, match):
    (tmp_path / "bad.npz").write_bytes(content)
    with pytest.raises(ValueError, match=r"bad\.npz: " + match) as err:
        read_data(tmp_path / "bad.npz")
    assert "\n" not in str(err.value)


def test_truncated_real_archive_and_other_errors(tmp_path):
    path = write_recordings(tmp_path / "rec.npz", _recordings())
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=r"cut\.npz: truncated or corrupt"):
        read_data(tmp_path / "cut.npz")
    with pytest.raises(FileNotFoundError, match=r"nothing\.npz: no such file"):
        read_data(tmp_path / "nothing.npz")
    np.savez(tmp_path / "keys.npz", frames_=np.zeros(2))
    with pytest.raises(
        ValueError, match=r"keys\.npz: expected image explorations .* found keys \['frames_'\]"
    ):
        read_data(tmp_path / "keys.npz")
    np.savez(tmp_path / "feat.npz", features=np.array([[1.0, np.inf]]))
    with pytest.raises(
        ValueError,
        match=r"feat\.npz: features must be finite, got 1 NaN/inf value\(s\) \(first at index \(0, 1\)\)",
    ):
        read_data(tmp_path / "feat.npz")
    np.savez(
        tmp_path / "img.npz", frames=np.zeros((1, 2, 4, 4, 3), np.float32), labels=[0], class_names=["a"]
    )
    with pytest.raises(ValueError, match=r"img\.npz: frames must be uint8 RGB"):
        read_data(tmp_path / "img.npz")
    with pytest.raises(ValueError, match=r"one \.npz file or one or more \.csv logs"):
        read_data([path, path])


def test_formats_import_without_torch(tmp_path):
    path = write_recordings(tmp_path / "rec.npz", _recordings())
    out = run_without_torch(
        f"""
        from tactile_torch.robot.files.formats import read_data
        from tactile_torch.robot.stream.windows import window_recordings

        data = read_data({str(path)!r})
        print(window_recordings(data.signals, 400, 200).windows.shape)
        """
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(4, 3, 400)"  # 500 samples: 1 window, 800: 3


def test_labelled_input_has_one_home_that_the_runtime_uses():
    """``LabelledInput`` is ``robot.files.labelled``'s; the runtime's readers return that class."""
    from tactile_torch.robot import runtime
    from tactile_torch.robot.files import labelled

    assert runtime.LabelledInput is labelled.LabelledInput
    item = labelled.LabelledInput(np.zeros((2, 3, 4), np.float32), np.array([0, -1]), ["a"])
    assert item.rate_hz is None and item.note is None and item.labels.tolist() == [0, -1]
