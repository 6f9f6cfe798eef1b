"""The command line fails in one line: every documented bad input names the file, the field and what was
expected, exits with status 2, and shows a traceback only with --debug."""

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import torch

from tactile_torch import cli
from tactile_torch.cli import BAD_INPUT_EXIT, TRAIN_MODULES, main
from tactile_torch.data import make_vibration_recordings
from tactile_torch.runtime import OnnxPipeline, sensor_range_g

from .conftest import run_without_torch


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Good and bad files, and a vibration bundle (800 Hz, W = 100) exported once for the module."""
    d = tmp_path_factory.mktemp("cli")
    rec = make_vibration_recordings(4, duration_s=2, random_state=0)
    good = rec.save(d / "rec.npz")
    vib = {"labels": np.array([0, 1]), "class_names": np.array(["a", "b"]), "rate_hz": np.float64(800.0)}
    np.savez(d / "shape.npz", signals=np.zeros((2, 50, 2), np.float32), **vib)
    np.savez(d / "counts.npz", signals=np.zeros((2, 500, 3), np.int16), **vib)
    nan = np.zeros((2, 500, 3), np.float32)
    nan[1, 7, 2] = np.nan
    np.savez(d / "nan.npz", signals=nan, **vib)
    short = np.random.default_rng(0).normal(0, 0.1, (2, 50, 3)).astype(np.float32)
    np.savez(d / "short.npz", signals=short, **vib)
    np.savez(
        d / "labels.npz", signals=np.zeros((2, 500, 3), np.float32), **{**vib, "labels": np.array([0.0, 1.0])}
    )
    np.savez(d / "keys.npz", recordings=np.zeros((2, 500, 3)))
    (d / "empty.npz").write_bytes(b"")
    data = good.read_bytes()
    (d / "cut.npz").write_bytes(data[: len(data) // 2])
    legacy = np.empty(2, dtype=object)
    legacy[:] = [np.zeros((500, 3), np.float32), np.zeros((600, 3), np.float32)]
    np.savez(d / "legacy.npz", signals=legacy, **vib)
    rng = np.random.default_rng(0)
    X = rng.normal(size=(30, 4))
    y = np.repeat([0, 1, 2], 10)
    names = np.array(["cork", "felt", "glass"])
    np.savez(d / "feat_nan.npz", features=np.where(np.eye(30, 4) > 0, np.nan, X), labels=y, class_names=names)
    y_one = y.copy()
    y_one[-9:] = 1  # 'glass' keeps one sample
    np.savez(d / "one.npz", features=X, labels=y_one, class_names=names)
    frames = np.zeros((2, 3, 8, 8, 3), np.uint8)
    np.savez(d / "images.npz", frames=frames, labels=np.array([0, 1]), class_names=np.array(["a", "b"]))
    assert (
        main(["train", "--data", str(good), "--method", "svm", "--window", "100", "--out", str(d / "m.npz")])
        == 0
    )
    assert main(["export", "--model", str(d / "m.npz"), "--out", str(d / "m.onnx")]) == 0
    model = (d / "m.npz").read_bytes()
    (d / "m_cut.npz").write_bytes(model[: len(model) - 100])
    spike = np.load(good)
    signals = spike["signals"].copy()
    signals[1, 250, 0] = -6.0  # one sample beyond the ADXL345's ±5 g: window 16 + 2 (W = 100)
    np.savez(d / "spike.npz", **{**{k: spike[k] for k in spike.files}, "signals": signals})
    slow = make_vibration_recordings(4, duration_s=2, random_state=1)
    slow.rate_hz = 100.0  # the same numbers declared as a 100 Hz recording
    slow.save(d / "slow.npz")
    return d


CASES = [
    # (command, file arguments, what the one line must say)
    ("train", ["--data", "missing.npz"], "missing.npz: no such file"),
    ("train", ["--data", "empty.npz"], r"empty.npz: empty file (0 bytes), expected a data file"),
    ("train", ["--data", "cut.npz"], "cut.npz: truncated or corrupt data file"),
    (
        "train",
        ["--data", "keys.npz"],
        "keys.npz: expected image explorations ('frames'), vibration recordings",
    ),
    ("train", ["--data", "shape.npz"], "shape.npz: signals must have shape (R, n, 3)"),
    ("train", ["--data", "labels.npz"], "labels.npz: labels must be integers of shape (2,), got float64"),
    (
        "train",
        ["--data", "counts.npz"],
        "counts.npz: signals: accelerations must be in g or m/s^2, got int16 (raw sensor counts?)",
    ),
    (
        "train",
        ["--data", "nan.npz"],
        "nan.npz: signals must be finite, got 1 NaN/inf value(s) (first at index (1, 7, 2))",
    ),
    ("train", ["--data", "feat_nan.npz"], "feat_nan.npz: features must be finite"),
    (
        "train",
        ["--data", "short.npz"],
        "short.npz: no recording holds a window of 800 samples (longest: 50 samples)",
    ),
    ("train", ["--data", "one.npz"], "one.npz: labels: every class needs at least 2 samples"),
    ("train", ["--data", "legacy.npz"], "legacy.npz: signals is a pickled object array"),
    (
        "train",
        ["--data", "rec.npz", "--method", "lda", "--out", "lda.npz"],
        "--out: method 'lda' has no exportable",
    ),
    ("cluster", ["--data", "images.npz"], "images.npz: --data must hold vibration recordings"),
    ("cluster", ["--data", "feat_nan.npz"], "feat_nan.npz: features must be finite"),
    ("export", ["--model", "missing.npz"], "missing.npz: no such file"),
    ("export", ["--model", "rec.npz"], "rec.npz: not a tactile-torch model file (no 'header'"),
    (
        "export",
        ["--model", "m.onnx"],
        "m.onnx: expected a tactile-torch model file (.npz), found not a zip archive",
    ),
    ("export", ["--model", "m_cut.npz"], "m_cut.npz: truncated or corrupt tactile-torch model file"),
    (
        "predict",
        ["--model", "m.npz", "--data", "rec.npz"],
        "m.npz: not an ONNX bundle onnxruntime can load (a .npz",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "images.npz"],
        "images.npz holds image data (frames), which does not fit",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "counts.npz"],
        "counts.npz: signals: accelerations must be in g or m/s^2, got int16 (raw sensor counts?)",
    ),
    ("predict", ["--model", "m.onnx", "--data", "missing.npz"], "missing.npz: no such file"),
    ("predict", ["--model", "missing.onnx", "--data", "rec.npz"], "missing.onnx"),
    (
        "export",
        ["--model", "m.npz", "--sensor-range", "0"],
        "--sensor-range must be a finite number of g > 0, got '0'",
    ),
    (
        "export",
        ["--model", "m.npz", "--sensor-range", "inf"],
        "--sensor-range must be a finite number of g > 0, got 'inf'",
    ),
    (
        "export",
        ["--model", "m.npz", "--sensor-range", "5g"],
        "--sensor-range must be a finite number of g > 0, got '5g'",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "rec.npz", "--range", "-2"],
        "--range must be a number of g > 0 ('inf': no check), got '-2'",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "rec.npz", "--range", "nan"],
        "--range must be a number of g > 0 ('inf': no check), got 'nan'",
    ),
    (
        "stream",
        ["--model", "m.onnx", "--port", "/dev/null", "--range", "0"],
        "--range must be a number of g > 0 ('inf': no check), got '0'",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "rec.npz", "--range", "0.001"],
        "rec.npz: all 64 windows have samples beyond ±0.001 g, so none was classified",
    ),
]


@pytest.mark.parametrize(("command", "arguments", "says"), CASES, ids=[f"{c[0]}-{c[1][1]}" for c in CASES])
def test_bad_input_gets_one_line_and_status_2(files, tmp_path, capsys, command, arguments, says):
    argv = [command, *(str(files / a) if a.endswith((".npz", ".onnx")) else a for a in arguments)]
    if command in ("cluster", "export"):
        argv += ["--out", str(tmp_path / ("out" if command == "cluster" else "out.onnx"))]
    assert main(argv) == BAD_INPUT_EXIT
    captured = capsys.readouterr()
    err = captured.err
    assert err.count("\n") == 1 and err.startswith(f"tactile-torch {command}: "), err
    assert says in err, err
    assert "Traceback" not in err + captured.out


def test_debug_shows_the_traceback(files, capsys):
    with pytest.raises(ValueError, match="signals: accelerations must be in g or m/s"):
        main(["train", "--data", str(files / "counts.npz"), "--debug"])
    with pytest.raises(ValueError, match="signals: accelerations must be in g or m/s"):
        main(["--debug", "predict", "--model", str(files / "m.onnx"), "--data", str(files / "counts.npz")])


def test_the_console_script_prints_no_traceback(files):
    argv = ["predict", "--model", str(files / "m.onnx"), "--data", str(files / "shape.npz")]
    out = subprocess.run([sys.executable, "-m", "tactile_torch.cli", *argv], capture_output=True, text=True)
    assert out.returncode == BAD_INPUT_EXIT
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
    assert "shape.npz: signals must have shape (R, n, 3)" in out.stderr


def test_an_unexpected_error_is_one_line_with_status_1(monkeypatch, capsys):
    def broken(args):
        raise RuntimeError("something\nwent wrong")

    monkeypatch.setattr(cli, "_train", broken)
    assert main(["train", "--data", "x.npz"]) == cli.INTERNAL_ERROR_EXIT
    err = capsys.readouterr().err
    assert err == (
        "tactile-torch train: internal error: RuntimeError: something went wrong (rerun with --debug for "
        "the traceback, and please report it)\n"
    )
    with pytest.raises(RuntimeError):
        main(["train", "--data", "x.npz", "--debug"])


def test_legacy_recordings_load_with_allow_pickle(files, capsys):
    assert (
        main(
            [
                "predict",
                "--model",
                str(files / "m.onnx"),
                "--data",
                str(files / "legacy.npz"),
                "--allow-pickle",
            ]
        )
        == 0
    )
    assert "11 samples of" in capsys.readouterr().out  # 5 + 6 windows of 100


def test_predict_warns_on_another_sample_rate_and_still_predicts(files, capsys):
    assert main(["predict", "--model", str(files / "m.onnx"), "--data", str(files / "slow.npz")]) == 0
    captured = capsys.readouterr()
    assert captured.err == (
        f"tactile-torch predict: warning: {files / 'slow.npz'}: the data are sampled at 100 Hz but this "
        "vibration-svm bundle was trained at 800 Hz (a window of 100 samples lasts 1 s here, 0.125 s in "
        "training); predictions may be meaningless: resample the data or retrain\n"
    )
    assert captured.out.splitlines()[-1].startswith("overall accuracy")  # the predictions, all the same
    assert main(["predict", "--model", str(files / "m.onnx"), "--data", str(files / "rec.npz")]) == 0
    assert capsys.readouterr().err == ""


def test_export_keeps_the_sensor_range_in_the_bundle(files, tmp_path, capsys):
    assert OnnxPipeline(files / "m.onnx").metadata["sensor_range_g"] == "5.0"  # default: the ADXL345's ±5 g
    wide = tmp_path / "wide.onnx"
    assert main(["export", "--model", str(files / "m.npz"), "--out", str(wide), "--sensor-range", "8"]) == 0
    assert sensor_range_g(OnnxPipeline(wide).metadata) == 8.0
    capsys.readouterr()
    # predict takes the bundle's range: the -6 g sample is in range of this sensor
    assert main(["predict", "--model", str(wide), "--data", str(files / "spike.npz")]) == 0
    assert capsys.readouterr().err == ""


def _predicted(files, tmp_path, data, *options):
    out = tmp_path / f"{data}{''.join(options)}.npz"
    assert (
        main(
            [
                "predict",
                "--model",
                str(files / "m.onnx"),
                "--data",
                str(files / data),
                "--out",
                str(out),
                *options,
            ]
        )
        == 0
    )
    return np.load(out)


def test_predict_does_not_classify_a_window_beyond_the_sensor_range(files, tmp_path, capsys):
    clean = _predicted(files, tmp_path, "rec.npz")
    capsys.readouterr()
    spiked = _predicted(files, tmp_path, "spike.npz")
    out, err = capsys.readouterr()
    assert err == (
        f"tactile-torch predict: warning: {files / 'spike.npz'}: 1 of 64 windows have samples beyond ±5 g "
        "and were not classified\n"
    )
    assert "1 windows with samples beyond ±5 g were not classified and are left out" in out
    window = 16 + 250 // 100  # recording 1 (16 windows of 100 samples), sample 250
    assert spiked["labels"][window] == -1 and spiked["names"][window] == "not classified: beyond ±5 g"
    others = np.arange(64) != window
    np.testing.assert_array_equal(spiked["labels"][others], clean["labels"][others])
    np.testing.assert_array_equal(spiked["names"][others], clean["names"][others])
    # --range overrides the bundle's: at ±7 g every window is classified, without a warning
    wider = _predicted(files, tmp_path, "spike.npz", "--range", "7")
    assert capsys.readouterr().err == "" and (wider["labels"] >= 0).all()


def test_commands_that_need_the_training_extra_say_so(files):
    out = run_without_torch(
        f"""
        from tactile_torch.cli import main

        status = [main(argv) for argv in (["train", "--data", {str(files / "rec.npz")!r}], ["export",
                  "--model", "m.npz", "--out", "m.onnx"], ["cluster", "--data", "x.npz"])]
        print(status)
        """
    )
    assert out.stdout.strip() == "[2, 2, 2]", out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == 3
    for line, command in zip(lines, ("train", "export", "cluster"), strict=True):
        assert line.startswith(
            f"tactile-torch {command}: needs the training extra, which is not installed here"
        )
        assert "missing: torch" in line and line.endswith("pip install 'tactile-torch[train]'")


def test_train_modules_match_the_train_extra():
    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    project = pyproject["project"]
    module_of = {"scikit-learn": "sklearn"}

    def names(requirements):
        return {
            module_of.get(n, n) for n in (r.split(">")[0].split("=")[0].split("<")[0] for r in requirements)
        }

    assert names(project["optional-dependencies"]["train"]) == set(TRAIN_MODULES)
    assert names(project["dependencies"]) == {"numpy", "onnxruntime", "pyserial"}
    assert not set(TRAIN_MODULES) & names(project["dependencies"])
    torch_pin = [r for r in project["optional-dependencies"]["train"] if r.startswith("torch")]
    assert torch_pin == [f"torch=={torch.__version__.split('+')[0]}"]  # never let pip pick another torch


def test_simulate_sensor_plays_any_layout(tmp_path, monkeypatch, capsys):
    import io

    import serial

    from tactile_torch.formats import RecordingArrays, write_recordings
    from tactile_torch.stream import parse_sample

    rng = np.random.default_rng(0)
    signals = [rng.normal(0, 0.1, (n, 3)).astype(np.float32) for n in (300, 450)]
    path = write_recordings(
        tmp_path / "ragged.npz", RecordingArrays(signals, np.array([0, 1]), ("a", "b"), 800.0)
    )
    wire = io.BytesIO()
    wire.close = lambda: None
    monkeypatch.setattr(serial, "serial_for_url", lambda url, **kw: wire)
    argv = ["simulate-sensor", "--data", str(path), "--recording", "1", "--port", "x", "--fast"]
    assert main(argv) == 0
    sent = np.array([parse_sample(line) for line in wire.getvalue().splitlines()])
    np.testing.assert_allclose(sent, signals[1], atol=5e-6)  # 5 decimals on the wire
    assert main([*argv[:4], "2", *argv[5:]]) == BAD_INPUT_EXIT
    assert "--recording must be in 0..1" in capsys.readouterr().err
