"""Whole pipelines exported to one ONNX file: parity with torch, metadata, CLI export/predict/stream."""

import io
import json
import os
import threading

import numpy as np
import pytest
import serial
import torch

from tactile_torch import __version__
from tactile_torch.cli import main
from tactile_torch.data import make_vibration_recordings
from tactile_torch.data.images import make_explorations, save_explorations
from tactile_torch.data.out_of_distribution import OUT_OF_DISTRIBUTION_KINDS, out_of_distribution_signals
from tactile_torch.export.model_graph import (
    InferencePipeline,
    compare_with_runtime,
    export_pipeline,
    pipeline_from_model,
)
from tactile_torch.features.files import load_features
from tactile_torch.robot.files.model_file import load_model_file
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.training import save_model, train_classifier
from tests.conftest import require_shared_data, run_without_torch


def _assert_parity(
    pipe: InferencePipeline, bundle: OnnxPipeline, raw: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Labels identical and scores within 1e-5 between the torch pipeline and onnxruntime (the graph's
    own labels: no "unknown" applied)."""
    out = bundle.run(raw)
    labels, scores = out["labels"], out["scores"]
    with torch.no_grad():
        t_labels, t_scores = pipe(torch.from_numpy(bundle.validate(raw)))[:2]
    np.testing.assert_array_equal(labels, t_labels.numpy())
    np.testing.assert_allclose(scores, t_scores.numpy(), rtol=1e-5, atol=1e-5)
    return labels, scores


def _trained(tmp_path, data_path, method="hmsvm", **kwargs):
    features = load_features(data_path, **kwargs)
    model = train_classifier(features, method, random_state=0)
    path = save_model(tmp_path / f"{method}.npz", model, features)
    return features, model, path


@pytest.fixture(scope="module")
def vibration_npz(tmp_path_factory):
    rec = make_vibration_recordings(6, duration_s=12, random_state=3)
    return rec.save(tmp_path_factory.mktemp("vib") / "rec.npz")


def _vibration_parity(tmp_path, data_path, window, method="hmsvm"):
    features, model, model_path = _trained(tmp_path, data_path, method, window=window)
    pipe = pipeline_from_model(load_model_file(model_path))
    bundle = OnnxPipeline(export_pipeline(pipe, tmp_path / "vib.onnx", example_batch=2))
    # sealed (robot.integrity): a bit flipped in the middle of the file (the SVM's weights) is refused
    data = bytearray((tmp_path / "vib.onnx").read_bytes())
    data[len(data) // 2] ^= 1
    (tmp_path / "flipped.onnx").write_bytes(data)
    with pytest.raises(ValueError, match=r"flipped\.onnx: the bundle's digest does not match its content"):
        OnnxPipeline(tmp_path / "flipped.onnx")
    assert bundle.sealed
    data = bundle.read_npz(data_path)
    labels, _ = _assert_parity(pipe, bundle, data.raw[:13])  # exported at batch 2, run at 13
    # the graph reproduces the estimator on the features computed by the library
    np.testing.assert_array_equal(labels, model.predict(features.X[:13]))
    np.testing.assert_array_equal(data.labels, features.y)
    agreement, difference = compare_with_runtime(pipe, bundle, data.raw[:13])
    assert agreement == 1.0 and difference < 1e-5
    return bundle, features


def test_vibration_pipeline_matches_torch_and_the_estimator(tmp_path, vibration_npz):
    bundle, features = _vibration_parity(tmp_path, vibration_npz, window=400)
    meta = bundle.metadata
    assert bundle.pipeline == "vibration-hmsvm"
    assert bundle.input_shape == (None, 3, 400)
    assert bundle.class_names == list(features.class_names)
    assert int(meta["window_size"]) == 400 and float(meta["sample_rate_hz"]) == 800.0
    assert float(meta["sensor_range_g"]) == 5.0  # the ADXL345's range unless the export says otherwise
    assert meta["tactile_torch.version"] == __version__
    scale = np.array(json.loads(meta["feature_scale"]))
    assert scale.shape == (21,) and (scale > 0).all()


def test_vibration_pipeline_on_real_recordings(tmp_path):
    from tactile_torch.data import load_hapmat_imu5

    rec = load_hapmat_imu5(require_shared_data("hapmat_imu5"))
    path = rec.save(tmp_path / "hapmat.npz")
    _vibration_parity(tmp_path, path, window=100, method="svm")


def test_image_pipeline_accepts_uint8_frames_and_matches_torch(tmp_path, capsys):
    data = make_explorations(4, n_frames=6, frame_size=48, sensels=12, random_state=1)
    path = save_explorations(tmp_path / "img.npz", data)
    features, model, model_path = _trained(tmp_path, path)
    pipe = pipeline_from_model(load_model_file(model_path))
    bundle = OnnxPipeline(export_pipeline(pipe, tmp_path / "img.onnx"))
    assert bundle.pipeline == "image-hmsvm" and bundle.input_shape == (None, 6, 3, 48, 48)
    raw = bundle.read_npz(path).raw
    assert raw.dtype == np.uint8 and raw.shape == (16, 6, 3, 48, 48)
    labels, _ = _assert_parity(pipe, bundle, raw[:5])
    np.testing.assert_array_equal(labels, model.predict(features.X[:5]))
    # the graph takes the frames as uint8; float frames in [0, 1] are quantised to the same levels
    assert bundle.input_dtype == np.uint8
    np.testing.assert_array_equal(bundle.run(raw[:5].astype(np.float32) / 255)["labels"], labels)
    with pytest.raises(ValueError, match=r"raw float frames must be in \[0, 1\]"):
        bundle.predict(raw[:1].astype(np.float32))
    with pytest.raises(TypeError, match="raw must have dtype uint8"):
        bundle.predict(raw[:1].astype(np.int16))
    # the torch pipeline on [0, 1] floats gives the same labels as on uint8 frames
    np.testing.assert_array_equal(pipe(torch.from_numpy(raw[:5]).float() / 255)[0].numpy(), labels)
    # a sensor range belongs to vibration bundles only
    assert "sensor_range_g" not in bundle.metadata
    with pytest.raises(ValueError, match="applies to models of vibration windows only, got a model of image"):
        pipeline_from_model(model_path, sensor_range_g=2.0)
    with pytest.raises(ValueError, match=r"sensor_range_g must be a finite number of g > 0, got -1"):
        pipeline_from_model(model_path, sensor_range_g=-1)
    argv = ["predict", "--model", str(bundle.path), "--data", str(path), "--range", "3"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert (
        err
        == f"tactile-torch predict: --range: {bundle.path} takes no vibration windows (image-hmsvm bundle)\n"
    )


def test_pipeline_from_model_takes_model_files_only(tmp_path, vibration_npz):
    with pytest.raises(TypeError, match="model must be a ModelFile"):
        pipeline_from_model(["not", "a", "model"])
    np.savez(tmp_path / "x.npz", format=np.array("other"))
    with pytest.raises(ValueError, match="not a tactile-torch model file"):
        load_model_file(tmp_path / "x.npz")
    with pytest.raises(FileNotFoundError, match=r"missing\.npz: no such file"):
        load_model_file(tmp_path / "missing.npz")


@pytest.mark.slow  # 10 s on a quiet 2-core machine: keeps the default run under 10 minutes
def test_cli_cluster_export_predict_round_trip(tmp_path, vibration_npz, capsys):
    out = tmp_path / "cluster"
    args = ["cluster", "--data", str(vibration_npz), "--window", "400", "--out", str(out)]
    assert main([*args, "--n-iter", "60", "--burn-in", "20", "--quiet"]) == 0
    onnx_path = tmp_path / "pyp.onnx"
    assert main(["export", "--model", str(out / "model.npz"), "--out", str(onnx_path)]) == 0
    printed = capsys.readouterr().out
    assert (
        "exported vibration-pyp" in printed and "components: the point estimate of the clustering" in printed
    )
    bundle = OnnxPipeline(onnx_path)
    assert bundle.sealed  # the mixture's bundle carries its digest too
    pipe = pipeline_from_model(load_model_file(out / "model.npz"))
    data = bundle.read_npz(vibration_npz)
    labels, scores = _assert_parity(pipe, bundle, data.raw[:9])
    np.testing.assert_allclose(np.exp(scores).sum(1), 1.0, rtol=1e-5)  # log responsibilities
    with torch.no_grad():  # the novelty flag output, same in torch and onnxruntime
        np.testing.assert_array_equal(
            bundle.run(data.raw[:9])["novel"], pipe(torch.from_numpy(data.raw[:9]))[2]
        )
    # the exported point-estimate component is the one the fitted clustering gave these windows
    fitted = np.load(out / "clustering.npz")["labels"]
    assert (labels == fitted[:9]).mean() >= 8 / 9
    assert main(["predict", "--model", str(onnx_path), "--data", str(vibration_npz)]) == 0
    assert "pairwise accuracy" in capsys.readouterr().out


@pytest.mark.slow  # a fit, an export and a stream: about 20 s on a quiet 2-core machine
def test_a_model_fitted_with_sessions_exports_and_classifies_a_held_back_day(tmp_path, monkeypatch, capsys):
    # 3 surfaces on 3 days, each day's gain its own: cluster (session effects) on days 0 and 1,
    # export, and classify day 2's windows on the robot's runtime: a new session, its offset and
    # effect integrated out (docs/mixture.md, "Sessions"); the bundle decides as the estimator does.
    # Day 2's gain lies between the first two days' (a new day's shift beyond those seen is the
    # documented limit: its windows land on other surfaces or are flagged novel)
    from sklearn.metrics import adjusted_rand_score

    from tactile_torch.clustering import fit_clustering, write_clustering
    from tactile_torch.robot.files.data_sources import read_source

    rec = make_vibration_recordings(3, duration_s=12.0, n_sessions=3, random_state=1)
    day = np.array([int(s.rsplit("/", 1)[1]) for s in rec.session])
    signals = np.stack(rec.signals) * np.array([0.85, 1.2, 1.0], dtype=np.float32)[day][:, None, None]
    arrays = dict(rate_hz=rec.rate_hz, class_names=np.array(rec.class_names))
    np.savez(tmp_path / "train.npz", signals=signals[day < 2], labels=rec.labels[day < 2],
             session=np.array([f"day{k}" for k in day[day < 2]]), **arrays)  # fmt: skip
    np.savez(tmp_path / "day2.npz", signals=signals[day == 2], labels=rec.labels[day == 2], **arrays)
    clustering = fit_clustering(
        read_source([tmp_path / "train.npz"]), window=400, random_state=0,
        progress=False,
    )  # fmt: skip
    assert clustering.session_mode == "model"
    paths = write_clustering(tmp_path / "out", clustering)
    bundle = OnnxPipeline(
        export_pipeline(pipeline_from_model(load_model_file(paths["model"])), tmp_path / "c.onnx")
    )
    held = bundle.read_npz(tmp_path / "day2.npz")
    out = bundle.run(held.raw)
    day2 = load_features(tmp_path / "day2.npz", window=400)
    X = np.asarray(clustering.transform.transform(day2.X))
    decided = np.where(out["novel"], -1, out["labels"])  # the calibrated rule's novel windows: -1
    np.testing.assert_array_equal(decided, clustering.mixture.predict(X, using="point"))
    assert adjusted_rand_score(day2.y, decided) > 0.8
    # and live: the held-back day's first recording over a serial line, `stream --discover 3`: the
    # same decision per window as the bundle (no state kept for the new day), novel windows named
    from tactile_torch.robot.stream.wire import format_sample

    first = np.flatnonzero(day == 2)[0]
    n = signals.shape[1] // 400
    lines = b"".join(format_sample(s) for s in signals[first])
    with monkeypatch.context() as patch:
        patch.setattr(serial, "serial_for_url", lambda *a, **k: io.BytesIO(lines))
        capsys.readouterr()
        args = ["stream", "--model", str(tmp_path / "c.onnx"), "--port", "test://", "--step", "400"]
        assert main([*args, "--max-windows", str(n), "--json", "--discover", "3"]) == 0
    printed = capsys.readouterr().out.splitlines()
    live = [json.loads(line) for line in printed if line.startswith("{")]
    assert [r["label"] for r in live] == out["labels"][:n].tolist()
    assert sum(line.startswith("  novel window") for line in printed) == int(out["novel"][:n].sum())


def test_cli_predict_prints_a_class_report_without_torch(tmp_path, vibration_npz):
    _, model, model_path = _trained(tmp_path, vibration_npz, "svm", window=400)
    onnx_path = tmp_path / "svm.onnx"
    assert main(["export", "--model", str(model_path), "--out", str(onnx_path)]) == 0
    out = run_without_torch(
        f"""
        from tactile_torch.cli import main

        sys.exit(main(["predict", "--model", {str(onnx_path)!r}, "--data", {str(vibration_npz)!r}]))
        """
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[-1].startswith("overall accuracy")
    accuracy = float(lines[-1].split()[-1])
    features = load_features(vibration_npz, window=400)
    assert accuracy == pytest.approx((model.predict(features.X) == features.y).mean(), abs=1e-4)


@pytest.mark.slow  # 10 s on a quiet 2-core machine: keeps the default run under 10 minutes
def test_predict_refuses_data_of_the_wrong_kind(tmp_path, vibration_npz):
    data = make_explorations(1, n_frames=2, frame_size=24, sensels=6, random_state=0)
    image_path = save_explorations(tmp_path / "img.npz", data)
    _, _, model_path = _trained(tmp_path, vibration_npz, "svm", window=400)
    bundle = OnnxPipeline(
        export_pipeline(pipeline_from_model(load_model_file(model_path)), tmp_path / "v.onnx")
    )
    with pytest.raises(ValueError, match=r"does not fit this vibration-svm bundle \(input B,3,W\)"):
        bundle.read_npz(image_path)


@pytest.mark.slow  # 9 s on a quiet 2-core machine: keeps the default run under 10 minutes
def test_cli_stream_classifies_a_simulated_sensor(tmp_path, vibration_npz, capsys, monkeypatch):
    from tactile_torch.robot.stream.wire import format_sample, parse_sample, simulate_sensor

    _, _, model_path = _trained(tmp_path, vibration_npz, "svm", window=400)
    onnx_path = tmp_path / "svm.onnx"
    assert main(["export", "--model", str(model_path), "--out", str(onnx_path)]) == 0
    capsys.readouterr()
    bundle = OnnxPipeline(onnx_path)
    recording = np.load(vibration_npz)["signals"][2]
    # Open the port before the sensor starts: opening a serial port discards what it has buffered.
    master, slave = os.openpty()
    port = serial.Serial(os.ttyname(slave), timeout=2.0)
    opened = []
    monkeypatch.setattr(serial, "serial_for_url", lambda url, **kw: opened.append((url, kw)) or port)
    writer = threading.Thread(
        target=simulate_sensor,
        args=(io.FileIO(master, "wb", closefd=False), recording[:1000]),
        kwargs={"realtime": False},
        daemon=True,
    )
    writer.start()
    status = main(["stream", "--model", str(onnx_path), "--port", "/dev/robot-imu", "--max-windows", "4"])
    writer.join()
    os.close(master)
    assert opened == [("/dev/robot-imu", {"baudrate": 230400, "timeout": 0.1})]
    assert status == 0
    out = capsys.readouterr().out
    printed = [line.split()[2] for line in out.splitlines()]  # stdout: the decisions only
    # windows of 400 every 200 samples of what went over the wire, as the bundle classifies them offline
    sent = np.array([parse_sample(format_sample(s)) for s in recording[:1000]], dtype=np.float32)
    windows = np.stack([sent[s : s + 400].T for s in (0, 200, 400, 600)])
    assert printed == bundle.predict_names(windows)


# ------------------------------------------------------------------------ "unknown" as an answer
REJECTED_KINDS = [k for k in OUT_OF_DISTRIBUTION_KINDS if k != "white noise sd 0.01 g"]
"""Out-of-distribution signals asserted unknown; noise of 0.01 g looks like a smooth surface (docs/export.md)."""


def _unknown_rates(tmp_path, signals, labels, names, rate, window):
    """Train on even windows, export; return the unknown share on odd (held-in) windows and on OOD signals."""
    from tactile_torch.features.files import FeatureSet
    from tactile_torch.robot.stream.windows import window_recordings
    from tactile_torch.signal import window_features

    cut = window_recordings(signals, window, window)
    X = window_features(torch.from_numpy(cut.windows)).double().numpy()
    y = labels[cut.recording]
    held = cut.position % 2 == 1
    source = {"kind": "vibration", "window": window, "step": window, "rate_hz": float(rate)}
    train = FeatureSet(X[~held], y[~held], tuple(names), source)
    model = train_classifier(train, "hmsvm", test_size=0.2, random_state=0)
    path = save_model(tmp_path / "ood.npz", model, train)
    bundle = OnnxPipeline(export_pipeline(pipeline_from_model(path), tmp_path / "ood.onnx"))
    assert bundle.ood_threshold > 0 and float(bundle.metadata["ood_quantile"]) == 0.995
    held_in = bundle.classify(cut.windows[held])
    rng = np.random.default_rng(1)
    rates = {
        k: float(np.mean(bundle.predict(x) == -1))
        for k, x in out_of_distribution_signals(200, window, rate, rng, kinds=REJECTED_KINDS).items()
    }
    reasons = bundle.classify(np.zeros((1, 3, window), np.float32)).reasons
    return float(np.mean(held_in.labels == -1)), rates, reasons


def test_unknown_on_held_in_data_and_out_of_distribution_signals(tmp_path):
    """At most 1 % of held-in windows unknown; zeros, constants, noise, tones, square waves >= 99 %."""
    rec = make_vibration_recordings(12, duration_s=20, random_state=0)
    held_in, rates, reasons = _unknown_rates(
        tmp_path,
        [np.asarray(x) for x in rec.signals],
        np.asarray(rec.labels),
        rec.class_names,
        rec.rate_hz,
        800,
    )
    assert held_in <= 0.01, held_in
    assert all(rate >= 0.99 for rate in rates.values()), rates
    assert reasons[0].startswith("no vibration: every axis is constant")


def test_unknown_on_real_recordings(tmp_path):
    """The same measure on a second, real source (HapMat IMU, 100 Hz, windows of 1 s)."""
    from tactile_torch.data import load_hapmat_imu5

    rec = load_hapmat_imu5(require_shared_data("hapmat_imu5"))
    held_in, rates, _ = _unknown_rates(
        tmp_path, list(rec.signals), np.asarray(rec.labels), rec.class_names, rec.rate_hz, 100
    )
    assert held_in <= 0.01, held_in
    assert all(rate >= 0.99 for rate in rates.values()), rates


def test_ood_distance_in_the_graph_matches_numpy(tmp_path, vibration_npz):
    from tactile_torch.ood import OOD_ARRAYS, ood_distance

    features, _, path = _trained(tmp_path, vibration_npz, "svm", window=400)
    mf = load_model_file(path)
    bundle = OnnxPipeline(export_pipeline(pipeline_from_model(mf), tmp_path / "d.onnx"))
    raw = bundle.read_npz(vibration_npz).raw[:7]
    state = mf.part("ood")
    assert set(state) == set(OOD_ARRAYS)  # both views and the offset
    want = ood_distance(features.X[:7] / mf.arrays["scale"], **state)
    np.testing.assert_allclose(bundle.classify(raw).distance, want, rtol=1e-4)
    assert mf.header["ood"]["threshold"] == pytest.approx(bundle.ood_threshold)


def test_a_header_is_checked_against_its_graph(tmp_path, vibration_npz):
    """A crafted header (window = 5, or 24 TB of window) is refused in one line naming the file and
    the field, before any graph is built or any array allocated (issue 34)."""
    import json as json_

    from tactile_torch.robot.files.model_file import HEADER

    _, _, path = _trained(tmp_path, vibration_npz, "svm", window=400)
    arrays = dict(np.load(path))
    header = json_.loads(str(arrays.pop(HEADER)))
    for window in (5, 2 * 10**12):
        header["source"]["window"] = window
        crafted = tmp_path / "crafted.npz"
        np.savez(crafted, **{HEADER: np.array(json_.dumps(header))}, **arrays)
        with pytest.raises(
            ValueError,
            match=rf"crafted\.npz: source\.window must be a number of samples in 16 \.\. 1,048,576 .*got {window}$",
        ):
            pipeline_from_model(crafted)


@pytest.mark.slow  # trains and exports its own bundle (about 40 s); the API and predict have faster tests above
def test_out_of_distribution_windows_are_unknown_in_predict_and_stream(tmp_path, vibration_npz, capsys):
    """A pure tone through `predict` and through `stream` over a pty: "unknown" with the reason."""
    from tactile_torch.robot.stream.wire import format_sample
    from tests.stream_helpers import PtySensor

    _, _, model_path = _trained(tmp_path, vibration_npz, "svm", window=400)
    onnx_path = tmp_path / "svm.onnx"
    assert main(["export", "--model", str(model_path), "--out", str(onnx_path)]) == 0
    t = np.arange(4000) / 800.0
    tone = (np.sin(2 * np.pi * 100 * t)[:, None] * np.array([0.5, 0.2, 1.0])).astype(np.float32)
    data = tmp_path / "tone.npz"
    np.savez(data, signals=tone[None], labels=[0], class_names=["tone"], rate_hz=800.0)
    capsys.readouterr()
    assert (
        main(["predict", "--model", str(onnx_path), "--data", str(data), "--out", str(tmp_path / "p.npz")])
        == 0
    )
    out = capsys.readouterr().out
    assert "10 windows: 0 scored against their class, 10 left out: 10 out of distribution" in out
    assert (np.load(tmp_path / "p.npz")["labels"] == -1).all()
    sensor = PtySensor()
    try:
        # daemon: once the stream has its 5 windows nobody reads the pty, and a writer blocked on the full
        # pty (a close from another thread does not wake it) kept pytest from exiting after the last test
        writer = threading.Thread(
            target=sensor.write, args=(b"".join(format_sample(s) for s in tone),), daemon=True
        )
        opened = threading.Event()
        real = serial.serial_for_url

        def serial_for_url(url, **kwargs):
            port = real(url, **kwargs)
            opened.set()
            return port

        serial.serial_for_url, restore = serial_for_url, serial.serial_for_url
        try:
            threading.Thread(target=lambda: (opened.wait(30), writer.start()), daemon=True).start()
            argv = [
                "stream",
                "--model",
                str(onnx_path),
                "--port",
                sensor.path,
                "--json",
                "--max-windows",
                "5",
            ]
            assert main(argv) == 0
        finally:
            serial.serial_for_url = restore
        writer.join(30)
    finally:
        sensor.close()
    captured = capsys.readouterr()
    records = [json.loads(line) for line in captured.out.splitlines()]
    assert len(records) == 5 and all(r["label"] == -1 and r["name"] == "unknown" for r in records)
    assert all(r["reason"].startswith("out of distribution: distance") for r in records)
    assert "5 windows unknown" in captured.err.splitlines()[-1]
