"""Tests of the vibration data: synthetic generator, .npz format, CSV loader, resampling, real-set loaders
(on the shared data when present, and on small files in the same layout always), and the report section."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from tactile_torch.data import (
    VibrationRecordings,
    load_borealtc_imu,
    load_hapmat_imu5,
    load_vibration_npz,
    make_vibration_dataset,
    make_vibration_recordings,
    save_vibration_npz,
)
from tactile_torch.data.stylus import SURFACES, Surface
from tactile_torch.data.vibration import QUANTUM_G
from tactile_torch.robot.files.csv_logs import read_csv_log
from tactile_torch.robot.files.formats import read_csv_recordings
from tactile_torch.signal import clustering_features, window_features
from tests.conftest import require_shared_data

TOP_G = math.floor(5.0 / QUANTUM_G) * QUANTUM_G


@pytest.fixture(scope="module")
def recordings():
    return make_vibration_recordings(28, duration_s=4.0, random_state=3)


# --------------------------------------------------------------------------------------------
# synthetic generator
# --------------------------------------------------------------------------------------------


def test_generator_format_and_sensor_model(recordings):
    assert len(recordings) == 28 and recordings.rate_hz == 800.0
    assert recordings.class_names == tuple(s.name for s in SURFACES)
    assert recordings.labels.tolist() == list(range(28))
    for s in recordings.signals:
        assert s.shape == (3200, 3) and s.dtype == np.float32
        codes = s.astype(np.float64) / QUANTUM_G
        np.testing.assert_allclose(codes, np.round(codes), atol=1e-3)  # 3.9 mg steps
        assert np.abs(s).max() <= TOP_G + 1e-6  # ±5 g range
        mean = s.mean(0)
        assert 0.9 < mean[2] < 1.05 and 0.1 < mean[0] < 0.35 and abs(mean[1]) < 0.05  # gravity, 12° tilt


def test_generator_is_seeded_and_streams_are_per_surface(recordings):
    again = make_vibration_recordings(28, duration_s=4.0, random_state=3)
    assert all(np.array_equal(a, b) for a, b in zip(recordings.signals, again.signals, strict=True))
    other = make_vibration_recordings(2, duration_s=4.0, random_state=4)
    assert not np.array_equal(other.signals[0], recordings.signals[0])
    # surface i's recording does not depend on how many surfaces are generated
    few = make_vibration_recordings(3, duration_s=4.0, random_state=3)
    assert np.array_equal(few.signals[2], recordings.signals[2])
    torch_seeded = make_vibration_recordings(1, duration_s=1.0, random_state=torch.Generator().manual_seed(5))
    assert torch_seeded.signals[0].shape == (800, 3)


def _features(recordings, size=800):
    ds = recordings.windows(size)
    return ds, window_features(ds.windows).numpy().reshape(len(ds), 3, 7)


def _mean_feature(recordings, feats, ds, name, column, axis=2):
    return feats[ds.labels.numpy() == recordings.class_names.index(name), axis, column].mean()


def test_generator_surface_characters(recordings):
    ds, feats = _features(recordings)
    mean = lambda name, column, axis=2: _mean_feature(recordings, feats, ds, name, column, axis)  # noqa: E731
    # soft surfaces lose their high frequencies: fewer threshold crossings than hard ones
    assert mean("felt", 5) < 0.8 * mean("glass", 5) and mean("foam", 5) < 0.8 * mean("aluminium", 5)
    # impacts make heavy tails (kurtosis), stick-slip a skewed tangential axis
    assert mean("ceramic-tiles", 2) > 2 * mean("glass", 2)
    assert mean("sandpaper-p60", 2) > mean("glass", 2) + 0.5
    assert abs(mean("rubber", 1, axis=0)) > 1.0 and mean("rubber", 0, axis=0) > mean("rubber", 0, axis=1)
    # loudness spans a realistic range: sandpaper is ~20x glass in standard deviation
    assert 5 < np.sqrt(mean("sandpaper-p60", 0) / mean("glass", 0)) < 60


def test_alike_surfaces_are_close(recordings):
    # In the unsupervised feature space, each deliberately alike surface's partner is among its
    # three nearest surfaces (class means): confusable by design.
    ds, _ = _features(recordings)
    x = clustering_features(window_features(ds.windows)).numpy()
    x = (x - x.mean(0)) / x.std(0)
    labels = ds.labels.numpy()
    centres = np.stack([x[labels == c].mean(0) for c in range(28)])
    dist = np.linalg.norm(centres[:, None] - centres[None], axis=-1) + np.eye(28) * 1e9
    names = recordings.class_names
    for s in SURFACES:
        if s.alike_of:
            nearest = [names[j] for j in np.argsort(dist[names.index(s.name)])[:3]]
            assert s.alike_of in nearest, (s.name, nearest)


def test_generator_clips_and_custom_surfaces():
    loud = Surface("jackhammer", 3.0, 300, 0.8, 1.0, impacts_hz=50, impact_g=4.0)
    quiet = Surface("quiet", 0.02, 100, 1.0, 0.5, alike_of="jackhammer")
    rec = make_vibration_recordings(surfaces=[loud, quiet], duration_s=2.0, random_state=0)
    assert rec.class_names == ("jackhammer", "quiet")
    assert np.isclose(np.abs(rec.signals[0]).max(), TOP_G)  # saturates at the last code
    assert (np.abs(rec.signals[0]) >= TOP_G - 1e-6).sum() > 10
    feats = window_features(rec.windows(800).windows)
    assert torch.isfinite(feats).all() and torch.isfinite(clustering_features(feats)).all()


def test_make_vibration_dataset():
    ds = make_vibration_dataset(
        n_surfaces=3, windows_per_surface=6, window_size=200, n_sessions=2, random_state=1
    )
    assert ds.windows.shape == (18, 3, 200) and ds.windows.dtype == torch.float32
    assert ds.labels.tolist() == [0] * 6 + [1] * 6 + [2] * 6
    assert ds.position.tolist()[:6] == [0, 1, 2, 0, 1, 2] and ds.recording.tolist()[:6] == [0, 0, 0, 1, 1, 1]
    assert len(ds) == 18 and ds.class_names[:3] == ("glass", "aluminium", "steel")
    more = make_vibration_dataset(n_surfaces=30, windows_per_surface=1, window_size=100, random_state=1)
    assert more.class_names[28:] == ("glass-2", "aluminium-2")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"n_surfaces": 0}, ValueError, "n_surfaces must be > 0"),
        ({"duration_s": -1.0}, ValueError, "duration_s must be > 0"),
        ({"duration_s": 0.001}, ValueError, "at least 2 samples"),
        ({"n_sessions": 1.5}, TypeError, "n_sessions must be an integer"),
        ({"surfaces": ["glass"]}, TypeError, "sequence of Surface"),
        ({"random_state": "seed"}, TypeError, "random_state"),
    ],
)
def test_generator_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        make_vibration_recordings(**kwargs)


def test_generator_knobs():
    base = dict(n_surfaces=3, duration_s=1.0, random_state=4)
    plain = make_vibration_recordings(**base)
    same = make_vibration_recordings(
        **base, noise_lsb=1.2, session_jitter=0.04, alike_distance=1.0, wear=(-0.04, 0.01)
    )
    assert all(np.array_equal(a, b) for a, b in zip(plain.signals, same.signals, strict=True))
    noisy = make_vibration_recordings(**base, noise_lsb=40.0)
    # glass (rms 0.03 g) with 40 LSB of noise: the noise dominates its vibration
    assert np.std(noisy.signals[0][:, 1]) > 3 * np.std(plain.signals[0][:, 1])
    # steel is alike_of aluminium: at distance 0 it takes aluminium's parameters (and shares its jitter)
    from tactile_torch.data.stylus import _toward

    steel, aluminium = SURFACES[2], SURFACES[1]
    assert steel.alike_of == aluminium.name
    merged = _toward(aluminium, steel, 0.0)
    assert (
        merged.rms_g == aluminium.rms_g and merged.corner_hz == aluminium.corner_hz and merged.name == "steel"
    )
    assert _toward(aluminium, steel, 1.0) == steel
    far = make_vibration_recordings(**base, alike_distance=3.0)
    assert not np.array_equal(far.signals[2], plain.signals[2]) and np.array_equal(
        far.signals[0], plain.signals[0]
    )


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise_lsb": -1.0}, "noise_lsb must be >= 0"),
        ({"session_jitter": -0.1}, "session_jitter must be >= 0"),
        ({"alike_distance": -1.0}, "alike_distance must be >= 0"),
        ({"wear": (0.1, -0.1)}, r"wear must be a range \(low, high\)"),
    ],
)
def test_generator_knob_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_vibration_recordings(2, duration_s=0.5, **kwargs)


def test_dataset_errors():
    with pytest.raises(ValueError, match="multiple of n_sessions"):
        make_vibration_dataset(n_surfaces=2, windows_per_surface=5, window_size=100, n_sessions=2)


# --------------------------------------------------------------------------------------------
# container, .npz format, windows
# --------------------------------------------------------------------------------------------


def _small(lengths=(300, 300)):
    rng = np.random.default_rng(0)
    return VibrationRecordings(
        signals=[rng.normal(size=(n, 3)).astype(np.float32) for n in lengths],
        labels=np.arange(len(lengths)) % 2,
        class_names=("a", "b"),
        rate_hz=800.0,
        session=np.array([f"s{i}" for i in range(len(lengths))]),
    )


@pytest.mark.parametrize("lengths", [(300, 300), (300, 450)])
def test_npz_round_trip(tmp_path, lengths):
    rec = _small(lengths)
    path = save_vibration_npz(tmp_path / "rec.npz", rec)
    ragged = len(set(lengths)) > 1
    with np.load(path, allow_pickle=False) as raw:  # no pickle in either layout
        assert raw["signals"].shape == ((750, 3) if ragged else (2, 300, 3))
        assert raw["signals"].dtype == np.float32 and ("lengths" in raw.files) == ragged
        assert raw["labels"].dtype == np.int64 and raw["class_names"].dtype.kind == "U"
    back = load_vibration_npz(path)
    assert all(np.array_equal(a, b) for a, b in zip(rec.signals, back.signals, strict=True))
    assert back.labels.tolist() == rec.labels.tolist() and back.class_names == ("a", "b")
    assert back.rate_hz == 800.0 and back.session.tolist() == ["s0", "s1"]
    assert load_vibration_npz(rec.save(tmp_path / "again.npz")).class_names == ("a", "b")


def test_legacy_pickled_ragged_files_load_only_when_allowed(tmp_path):
    rec = _small((300, 450))
    signals = np.empty(2, dtype=object)
    signals[:] = rec.signals
    path = tmp_path / "old.npz"  # what tactile-torch 0.1 wrote for recordings of different lengths
    np.savez(path, signals=signals, labels=rec.labels, class_names=np.array(["a", "b"]), rate_hz=800.0)
    with pytest.raises(ValueError, match=r"old\.npz: signals is a pickled object array.*allow_pickle=True"):
        load_vibration_npz(path)
    back = load_vibration_npz(path, allow_pickle=True)
    assert [len(s) for s in back.signals] == [300, 450]
    again = load_vibration_npz(back.save(tmp_path / "new.npz"))  # re-saved: no pickle any more
    assert all(np.array_equal(a, b) for a, b in zip(rec.signals, again.signals, strict=True))


def test_npz_errors(tmp_path):
    np.savez(tmp_path / "missing.npz", signals=np.zeros((1, 10, 3)), labels=np.zeros(1, np.int64))
    with pytest.raises(ValueError, match="missing"):
        load_vibration_npz(tmp_path / "missing.npz")
    np.savez(
        tmp_path / "shape.npz",
        signals=np.zeros((10, 3)),
        labels=np.zeros(1),
        class_names=["a"],
        rate_hz=800.0,
    )
    with pytest.raises(ValueError, match=r"shape \(R, n, 3\)"):
        load_vibration_npz(tmp_path / "shape.npz")


@pytest.mark.parametrize(
    ("change", "error", "match"),
    [
        ({"signals": [np.zeros((10, 4))]}, ValueError, r"signals\[0\] must have shape \(n, 3\)"),
        ({"signals": [np.full((10, 3), np.nan)]}, ValueError, "finite"),
        ({"signals": [np.array([["a"] * 3] * 10)]}, TypeError, "numeric"),
        ({"labels": np.array([0, 1, 2])}, ValueError, "one per recording"),
        ({"labels": np.array([0.0])}, TypeError, "integers"),
        ({"labels": np.array([5])}, ValueError, "0..1"),
        ({"rate_hz": 0.0}, ValueError, "rate_hz must be > 0"),
        ({"session": np.array(["a", "b"])}, ValueError, "session must have shape"),
    ],
)
def test_recordings_validation(change, error, match):
    kwargs = {
        "signals": [np.zeros((10, 3))],
        "labels": np.array([0]),
        "class_names": ("a", "b"),
        "rate_hz": 800.0,
    }
    kwargs.update(change)
    with pytest.raises(error, match=match):
        VibrationRecordings(**kwargs)


def test_windows_of_recordings():
    rec = _small((300, 450))
    ds = rec.windows(100, 50)
    assert len(ds) == 5 + 8 and ds.windows.shape == (13, 3, 100)
    assert torch.equal(ds.windows[6], torch.from_numpy(rec.signals[1][50:150].T.copy()))
    assert ds.recording.tolist() == [0] * 5 + [1] * 8 and ds.position.tolist()[5:8] == [0, 1, 2]
    assert len(rec.windows(400)) == 1  # the short recording gives none
    assert len(rec.windows(100, max_per_recording=2)) == 4
    with pytest.raises(ValueError, match="no recording holds a window of 500 samples"):
        rec.windows(500)


def test_resample_keeps_the_signal():
    t = np.arange(1000) / 100.0
    tone = np.stack([np.sin(2 * np.pi * 5.0 * t)] * 3, axis=1).astype(np.float32)
    rec = VibrationRecordings([tone], np.array([0]), ("a",), 100.0).resample(800)
    assert rec.rate_hz == 800.0 and rec.signals[0].shape == (8000, 3)
    spectrum = np.abs(np.fft.rfft(rec.signals[0][:, 0]))
    assert np.fft.rfftfreq(8000, 1 / 800.0)[spectrum.argmax()] == pytest.approx(5.0)
    middle = rec.signals[0][800:7200, 0]  # away from the zero-padded ends
    np.testing.assert_allclose(middle, np.sin(2 * np.pi * 5.0 * np.arange(800, 7200) / 800.0), atol=2e-3)


# --------------------------------------------------------------------------------------------
# CSV
# --------------------------------------------------------------------------------------------


def _write_csv(path, rows, header="t,x,y,z"):
    lines = ([header] if header else []) + [",".join(f"{v:.6f}" for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _log(n=50, rate=100.0, scale=1.0):
    t = np.arange(n) / rate
    return np.column_stack([t, np.sin(t) * scale, np.cos(t) * scale, np.ones(n) * scale])


def test_csv_loader(tmp_path):
    a = _write_csv(tmp_path / "cork_1.csv", _log())
    b = _write_csv(tmp_path / "cork_2.csv", _log(), header=None)
    c = _write_csv(tmp_path / "felt_1.csv", _log()[:, [1, 0, 2, 3]], header="X,Time,Y,Z")
    rec = read_csv_recordings([a, b, c], class_names=["cork", "cork", "felt"])
    assert rec.rate_hz == 100.0 and rec.class_names == ("cork", "felt") and rec.labels.tolist() == [0, 0, 1]
    assert rec.session.tolist() == ["1", "2", "1"]  # the naming rule: <class>_<session>
    for s in rec.signals:
        np.testing.assert_allclose(s, _log()[:, 1:], atol=1e-6)
    single = read_csv_recordings([a])  # the same rule as the command line: cork_1.csv is class cork
    assert single.class_names == ("cork",) and single.session.tolist() == ["1"]
    signal = read_csv_log(
        _write_csv(tmp_path / "ms2.csv", _log(scale=9.80665), header="time,ax,ay,az"),
        columns=("time", "ax", "ay", "az"),
        scale=1 / 9.80665,
    ).signal
    np.testing.assert_allclose(signal, _log()[:, 1:], atol=1e-5)
    # different rates: an error naming both; read alone, each is resampled to a common rate
    d = _write_csv(tmp_path / "fast.csv", _log(100, rate=200.0))
    with pytest.raises(
        ValueError, match=r"different sample rates \(.*cork_1\.csv: 100 Hz, .*fast\.csv: 200 Hz\)"
    ):
        read_csv_recordings([a, d])
    both = [VibrationRecordings.from_arrays(read_csv_recordings([p])).resample(400.0) for p in (a, d)]
    assert [r.rate_hz for r in both] == [400.0, 400.0] and [len(r.signals[0]) for r in both] == [200, 200]


@pytest.mark.parametrize(
    ("content", "kwargs", "error", "match"),
    [
        ("", {}, ValueError, "empty file"),
        ("t,x,y\n0,1,2\n0.01,1,2\n", {}, ValueError, "no column 'z'"),
        ("0,1,2,3\n0.01,1,2,3\n", {"columns": ("t", "x", "y", "z")}, ValueError, "no header"),
        ("t,x,y,z\n0,1,2,3\n0.01,1,2\n", {}, ValueError, "every row must have the columns"),
        ("t,x,y,z\n0,1,2,3\n", {}, ValueError, "at least 2 samples"),
        ("t,x,y,z\n0,1,2,3\n0.01,1,nan,3\n", {}, ValueError, "finite"),
        ("t,x,y,z\n0,1,2,3\n0.01,1,2,3\n0.01,1,2,3\n", {}, ValueError, "strictly increase"),
        ("t,x,y,z\n0,1,2,3\n0.01,1,2,3\n", {"columns": ("t", "x")}, ValueError, "4 columns"),
    ],
)
def test_csv_errors(tmp_path, content, kwargs, error, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(error, match=match):
        read_csv_log(path, **kwargs)


def test_csv_irregular_steps_warn(tmp_path):
    rows = _log()
    rows[10:, 0] += 0.003
    with pytest.warns(UserWarning, match="uniformly spaced"):
        read_csv_recordings([_write_csv(tmp_path / "jitter.csv", rows)])


# --------------------------------------------------------------------------------------------
# real data sets (and the same code on small files in their layout)
# --------------------------------------------------------------------------------------------


def _fake_hapmat(root):
    header = "time,accel_x,accel_y,accel_z,gyro_x,gyro_y,gyro_z,rota_x,rota_y,rota_z"
    for material in ("Fabric", "Metal"):
        rows = np.column_stack([np.arange(300) / 100.0, np.random.default_rng(0).normal(0, 0.05, (300, 9))])
        _write_csv(root / f"{material}_1.csv", rows, header=header)
    return root


def _fake_borealtc(root, with_index):
    lines = ["imu_file,class_name"]
    for terrain in ("ICE", "SNOW"):
        (root / terrain).mkdir(parents=True)
        for k in (0, 2):
            rows = np.column_stack(
                [np.arange(250) / 100.0, np.zeros((250, 3)), np.tile([0.0, 0.0, 9.80665], (250, 1))]
            )
            _write_csv(root / terrain / f"imu_{k:02d}.csv", rows, header="time,wx,wy,wz,ax,ay,az")
            lines.append(f"{terrain}/imu_{k:02d}.csv,{terrain}")
    if with_index:
        (root / "index.csv").write_text("\n".join(lines) + "\n")
    return root


def test_hapmat_loader_on_files_in_its_layout(tmp_path):
    rec = load_hapmat_imu5(_fake_hapmat(tmp_path))
    assert rec.class_names == ("Fabric", "Metal") and rec.rate_hz == 100.0
    assert [s.shape for s in rec.signals] == [(300, 3), (300, 3)]
    assert load_hapmat_imu5(tmp_path, rate_hz=800).signals[0].shape == (2400, 3)


@pytest.mark.parametrize("with_index", [True, False])
def test_borealtc_loader_on_files_in_its_layout(tmp_path, with_index):
    rec = load_borealtc_imu(_fake_borealtc(tmp_path, with_index))
    assert rec.class_names == ("ICE", "SNOW") and rec.labels.tolist() == [0, 0, 1, 1]
    assert rec.session.tolist() == ["ICE/imu_00", "ICE/imu_02", "SNOW/imu_00", "SNOW/imu_02"]
    np.testing.assert_allclose(rec.signals[0].mean(0), [0.0, 0.0, 1.0], atol=1e-6)  # m/s^2 -> g


def test_real_loaders_missing_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        load_hapmat_imu5(tmp_path / "nowhere")
    with pytest.raises(FileNotFoundError, match=r"no imu_\*.csv"):
        load_borealtc_imu(tmp_path)


def test_hapmat_real():
    root = require_shared_data("hapmat_imu5")
    rec = load_hapmat_imu5(root)
    assert rec.class_names == ("Fabric", "Leather", "Metal", "Paper", "Wood") and rec.rate_hz == 100.0
    assert all(s.shape == (6001, 3) for s in rec.signals)
    stds = np.stack([s.std(0) for s in rec.signals])
    assert (stds > 0.005).all() and (stds < 0.5).all()  # PROVENANCE: std 0.015-0.14 (taken as g)
    feats = window_features(rec.windows(200).windows)
    assert torch.isfinite(feats).all() and torch.isfinite(clustering_features(feats)).all()


def test_borealtc_real():
    root = require_shared_data("borealtc_imu")
    rec = load_borealtc_imu(root)
    assert len(rec) == 15 and rec.class_names == ("ASPHALT", "FLOORING", "ICE", "SANDY_LOAM", "SNOW")
    assert rec.rate_hz == 100.0 and sum(len(s) for s in rec.signals) == 52989
    for s in rec.signals:  # gravity in g after the conversion from m/s^2
        assert 0.9 < np.linalg.norm(s.mean(0)) < 1.1
    up = load_borealtc_imu(root, rate_hz=800.0)
    assert up.rate_hz == 800.0 and len(up.signals[0]) == 8 * len(rec.signals[0])


# --------------------------------------------------------------------------------------------
# the report section (quick mode)
# --------------------------------------------------------------------------------------------


def test_study_quick(tmp_path):
    from tactile_torch.studies import run_report

    path = run_report(tmp_path, quick=True, only=["vibration_features"], log=lambda _: None)
    text = path.read_text()
    assert "Vibration windows and features" in text and "Reproduce with" in text
    for name in (
        "vibration-example-windows",
        "vibration-feature-distributions",
        "vibration-clustering-transform",
    ):
        assert (tmp_path / "figures" / f"{name}.png").stat().st_size > 10_000
    tables = json.loads((tmp_path / "report.json").read_text())["sections"][0]["tables"]
    accuracy = next(t for t in tables if "SVC accuracy" in (t["caption"] or ""))
    assert [row["W"] for row in accuracy["rows"]] == [200, 400, 800, 1600]
    assert all(0.5 < row["acc (gamma 0.0186, C 1000)"] <= 1.0 for row in accuracy["rows"])
