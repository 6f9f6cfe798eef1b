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
from tactile_torch.cli import train as train_command
from tactile_torch.data import make_vibration_recordings
from tactile_torch.robot.runtime import OnnxPipeline, sensor_range_g
from tests.conftest import run_without_torch


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
    np.savez(d / "feat.npz", features=X + y[:, None], labels=y, class_names=names)
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
    e30 = signals.copy()
    e30[2, 10, 0] = 1e30  # a corrupted sample in recording 2, window 0
    np.savez(d / "e30.npz", **{**{k: spike[k] for k in spike.files}, "signals": e30})
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
        "short.npz: every recording of class 'a' is shorter than one window of 800 samples (1 s at 800 Hz)",
    ),
    ("train", ["--data", "one.npz"], "one.npz: labels: every class needs at least 2 samples"),
    ("train", ["--data", "legacy.npz"], "legacy.npz: signals is a pickled object array"),
    (
        "train",
        ["--data", "rec.npz", "--select", "0"],
        "argument --select: expected a whole number >= 1, got '0'",
    ),
    (
        "tradeoff",
        ["--data", "feat.npz", "--folds", "1000"],
        "--folds must be at most 10 here",
    ),
    (
        "tradeoff",
        ["--data", "feat.npz", "--folds", "1"],
        "argument --folds: expected a whole number >= 2, got '1'",
    ),
    (
        "tradeoff",
        ["--data", "feat.npz", "--max-per-class", "0"],
        "argument --max-per-class: expected 'auto' or a whole number >= 2, got '0'",
    ),
    (
        "tradeoff",
        ["--data", "feat.npz", "--frame-rate", "0"],
        "argument --frame-rate: expected a finite number > 0, got '0'",
    ),
    (
        "tradeoff",
        ["--data", "feat.npz", "--target", "1.5"],
        "argument --target: expected a finite number in (0, 1], got '1.5'",
    ),
    ("tradeoff", ["--data", "feat.npz", "--deploy", "nonsense"], "--deploy must name a candidate"),
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
        "argument --sensor-range: expected a finite number of g > 0, got '0'",
    ),
    (
        "export",
        ["--model", "m.npz", "--sensor-range", "inf"],
        "argument --sensor-range: expected a finite number of g > 0, got 'inf'",
    ),
    (
        "export",
        ["--model", "m.npz", "--sensor-range", "5g"],
        "argument --sensor-range: expected a finite number of g > 0, got '5g'",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "rec.npz", "--range", "-2"],
        "argument --range: expected a number of g > 0 (inf: no check), got '-2'",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "rec.npz", "--range", "nan"],
        "argument --range: expected a number of g > 0 (inf: no check), got 'nan'",
    ),
    (
        "stream",
        ["--model", "m.onnx", "--port", "/dev/null", "--range", "0"],
        # parsed once the bundle says samples or frames (frames take LOW,HIGH)
        "--range must be a number of g > 0 ('inf': no check), got '0'",
    ),
    (
        "train",
        ["--data", "e30.npz", "--window", "100", "--sensor-range", "inf"],  # past the reading checks
        "e30.npz: 1 window(s) hold samples out of range (window 32 of recording 2 reaches 1e+30 g)",
    ),
    (
        "predict",
        ["--model", "m.onnx", "--data", "rec.npz", "--batch", "0"],
        "argument --batch: expected a whole number >= 1, got '0'",
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
    if command in ("cluster", "export", "tradeoff"):
        argv += ["--out", str(tmp_path / ("out.onnx" if command == "export" else "out"))]
    if command == "tradeoff":
        argv += ["--quiet", "--quick", "--no-breaking", "--classifiers", "NCM"]
    try:
        status = main(argv)
    except SystemExit as exit:  # a value the option's parser refuses: argparse exits
        status = exit.code
    assert status == BAD_INPUT_EXIT
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

    monkeypatch.setattr(train_command, "run_train", broken)
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
    assert "11 windows of" in capsys.readouterr().out  # 5 + 6 windows of 100


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
    assert err == ""  # counted once, with its reason, in the one line of what was left out
    assert "64 windows: 63 scored against their class, 1 left out: 1 beyond the sensor's range ±5 g\n" in out
    window = 16 + 250 // 100  # recording 1 (16 windows of 100 samples), sample 250
    assert spiked["labels"][window] == -1
    assert spiked["names"][window] == "unknown: a sample of 6 g, beyond the sensor's range ±5 g"
    others = np.arange(64) != window
    np.testing.assert_array_equal(spiked["labels"][others], clean["labels"][others])
    np.testing.assert_array_equal(spiked["names"][others], clean["names"][others])
    # --range overrides the bundle's: at ±7 g no window is refused for its range, without a warning
    wider = _predicted(files, tmp_path, "spike.npz", "--range", "7")
    assert capsys.readouterr().err == "" and (wider["labels"][others] >= 0).all()
    # ... but a -6 g spike lies far from the training windows: "unknown", out of distribution
    assert wider["labels"][window] == -1 and wider["names"][window].startswith("unknown: out of distribution")


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
    pyproject = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
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

    from tactile_torch.robot.files.formats import RecordingArrays, write_recordings
    from tactile_torch.robot.stream.wire import parse_sample

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


# ---------------------------------------------------------------------------------- bounded reads
def _declared_npz(path, shape, *, pad=64):
    """A .npz whose 'signals' header declares ``shape`` float32 but holds only ``pad`` bytes of data."""
    import io
    import zipfile

    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f4", "fortran_order": False, "shape": tuple(shape)}
    )
    vib = {"labels": np.array([0]), "class_names": np.array(["a"]), "rate_hz": np.float64(800.0)}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("signals.npy", header.getvalue() + b"\0" * pad)
        for key, value in vib.items():
            buf = io.BytesIO()
            np.save(buf, value)
            z.writestr(f"{key}.npy", buf.getvalue())
    return path


def _zip_bomb(path, mib):
    """A real zip bomb: ``mib`` MiB of zeros as (n, 800, 3) float32 signals, deflated to about 1/1000."""
    import zipfile

    n = mib * 2**20 // (800 * 3 * 4)
    header = {"descr": "<f4", "fortran_order": False, "shape": (n, 800, 3)}
    vib = {"labels": np.zeros(n, np.int64), "class_names": np.array(["a"]), "rate_hz": np.float64(800.0)}
    chunk = bytes(800 * 3 * 4 * 64)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        with z.open("signals.npy", "w", force_zip64=True) as member:
            np.lib.format.write_array_header_1_0(member, header)
            for start in range(0, n, 64):
                member.write(chunk[: min(64, n - start) * 800 * 3 * 4])
        for key, value in vib.items():
            with z.open(f"{key}.npy", "w") as member:
                np.save(member, value)
    return path


@pytest.mark.parametrize("command", ["train", "predict", "simulate-sensor"])
def test_a_huge_declared_shape_is_refused_before_reading(files, tmp_path, capsys, command):
    bomb = _declared_npz(tmp_path / "huge.npz", (10**7, 800, 3))  # 89 GiB declared in a 1 kB file
    argv = {
        "train": ["train", "--data", str(bomb)],
        "predict": ["predict", "--model", str(files / "m.onnx"), "--data", str(bomb)],
        "simulate-sensor": ["simulate-sensor", "--data", str(bomb), "--port", "loop://"],
    }[command]
    assert main(argv) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "huge.npz: signals.npy declares shape (10000000, 800, 3)" in err, err


def test_a_zip_bomb_is_refused_under_a_memory_cap(files, tmp_path):
    """An 8 MiB-class zip bomb through predict, in a process that may not map more than 1.5 GiB."""
    bomb = _zip_bomb(tmp_path / "bomb.npz", 1100)  # 1.1 GiB of zeros, ~1 MiB on disk
    assert bomb.stat().st_size < 4 * 2**20
    code = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29))\n"
        "from tactile_torch.cli import main\n"
        f"sys.exit(main(['predict', '--model', {str(files / 'm.onnx')!r}, '--data', {str(bomb)!r}]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == BAD_INPUT_EXIT, out.stderr
    assert out.stderr.count("\n") == 1 and "more than the read limit of 1,024 MiB" in out.stderr, out.stderr


def test_the_read_limit_option_lowers_and_raises_the_bound(files, capsys):
    argv = ["predict", "--model", str(files / "m.onnx"), "--data", str(files / "rec.npz")]
    assert main([*argv, "--max-read-mb", "0.01"]) == BAD_INPUT_EXIT
    assert "more than the read limit of 0 MiB" in capsys.readouterr().err
    assert main([*argv, "--max-read-mb", "64"]) == 0


def test_a_csv_larger_than_the_read_limit_is_refused(tmp_path, capsys):
    path = tmp_path / "cork_1.csv"
    path.write_text("t,x,y,z\n" + "".join(f"{i / 800},0,0,1\n" for i in range(20000)))
    assert main(["train", "--data", str(path), "--max-read-mb", "1"]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cork_1.csv: parsing the CSV log needs" in err, err


def test_a_header_only_csv_is_one_line_without_a_numpy_warning(tmp_path):
    path = tmp_path / "cork_1.csv"
    path.write_text("t,x,y,z\n")
    argv = ["predict", "--model", "m.onnx", "--data", str(path)]
    out = subprocess.run(
        [
            sys.executable,
            "-W",
            "default",
            "-c",
            f"from tactile_torch.robot.files.formats import read_data; read_data({[str(path)]!r})",
        ],
        capture_output=True,
        text=True,
    )
    assert "must hold at least 2 samples, got 0" in out.stderr and "Warning" not in out.stderr, out.stderr
    del argv


# ---------------------------------------------------------------------------------- class names
@pytest.mark.parametrize(
    ("names", "says"),
    [
        (["cork\nfake row 1.0000", "felt"], "class_names must hold no control characters"),
        (["cork", "cork"], "class_names must be distinct, got 'cork' at indices 0 and 1"),
    ],
)
def test_class_names_with_newlines_or_twice_are_refused(tmp_path, capsys, names, says):
    rng = np.random.default_rng(0)
    path = tmp_path / "feat.npz"
    np.savez(path, features=rng.normal(size=(20, 3)), labels=np.arange(20) % 2, class_names=np.array(names))
    assert main(["train", "--data", str(path)]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err, err


# ---------------------------------------------------------------------------------- safe outputs
def test_export_onto_its_model_file_is_refused_and_the_model_kept(files, tmp_path, capsys):
    model = tmp_path / "m.npz"
    model.write_bytes((files / "m.npz").read_bytes())
    before = model.read_bytes()
    assert main(["export", "--model", str(model), "--out", str(model)]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is the input file" in err and model.read_bytes() == before


def test_predict_onto_its_data_file_is_refused_and_the_data_kept(files, tmp_path, capsys):
    data = tmp_path / "d.npz"
    data.write_bytes((files / "rec.npz").read_bytes())
    link = tmp_path / "hard.npz"
    link.hardlink_to(data)  # another name of the same file is the same input
    for out in (data, link):
        argv = ["predict", "--model", str(files / "m.onnx"), "--data", str(data), "--out", str(out)]
        assert main(argv) == BAD_INPUT_EXIT
        assert "is the input file" in capsys.readouterr().err
    assert data.read_bytes() == (files / "rec.npz").read_bytes()


def _device_node(tmp_path):
    """A character device to aim --out at: our own null device when root may make one, else /dev/null.

    Never /dev/null itself as root: code without the fix (run to check that this test fails before it)
    would replace the system's /dev/null with a regular file, as the issue found.
    """
    import os
    import stat

    node = tmp_path / "null"
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, OSError):
        if os.geteuid() == 0:
            pytest.skip("cannot make a device node here, and /dev/null must not be put at risk as root")
        return Path("/dev/null")  # not root: /dev cannot be written, the node is safe
    return node


@pytest.mark.parametrize("target", ["device", "directory", "symlink", "fifo"])
@pytest.mark.parametrize("command", ["train", "predict", "export"])
def test_out_onto_a_device_directory_symlink_or_fifo_is_refused(files, tmp_path, capsys, command, target):
    import os

    out = {"device": _device_node(tmp_path), "directory": tmp_path, "symlink": tmp_path / "l.npz"}.get(
        target, tmp_path / "fifo"
    )
    if target == "symlink":
        (tmp_path / "elsewhere.npz").write_bytes(b"keep")
        out.symlink_to(tmp_path / "elsewhere.npz")
    if target == "fifo":
        os.mkfifo(out)
    argv = {
        "train": ["train", "--data", str(files / "rec.npz"), "--window", "100", "--method", "svm"],
        "predict": ["predict", "--model", str(files / "m.onnx"), "--data", str(files / "rec.npz")],
        "export": ["export", "--model", str(files / "m.npz")],
    }[command]
    assert main([*argv, "--out", str(out)]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    what = {"device": "is a device", "directory": "is a directory", "symlink": "is a symbolic link"}
    assert err.count("\n") == 1 and what.get(target, "is a FIFO") in err, err
    assert Path("/dev/null").is_char_device() and (target != "device" or out.is_char_device())
    if target == "symlink":
        assert out.is_symlink() and (tmp_path / "elsewhere.npz").read_bytes() == b"keep"


@pytest.mark.parametrize(
    "command",
    [["tradeoff", "--quick"], ["cluster"], ["report", "--quick"], ["train"], ["predict"], ["export"]],
    ids=lambda c: c[0],
)
def test_an_out_where_nothing_can_be_written_is_refused_before_any_work(
    files, tmp_path, monkeypatch, capsys, command
):
    """A read-only --out is found first (not after the work, naming a temporary file): one line naming
    --out and the place, status 2. As root, permissions do not stop a write: access() is made to say so."""
    import os

    import tactile_torch.robot.files.safe_write as safe_write

    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    if os.geteuid() == 0:
        access = os.access
        monkeypatch.setattr(safe_write.os, "access", lambda p, mode: Path(p) != locked and access(p, mode))
    name = {"train": "m.npz", "predict": "labels.npz", "export": "m.onnx"}.get(command[0], "runs")
    data = ["--model", str(files / "m.npz")] if command[0] == "export" else ["--data", str(files / "rec.npz")]
    data = ["--model", str(files / "m.onnx"), *data] if command[0] == "predict" else data
    data = [] if command[0] == "report" else data
    try:
        assert main([*command, *data, "--out", str(locked / name)]) == BAD_INPUT_EXIT
    finally:
        locked.chmod(0o755)
    err = capsys.readouterr().err
    assert (
        err
        == f"tactile-torch {command[0]}: --out {locked / name}: cannot write there ({locked} is not writable)\n"
    )
    assert list(locked.iterdir()) == []
    # a file where a directory is expected, a path through a file
    if command[0] in ("tradeoff", "cluster"):
        assert main([*command, *data, "--out", str(files / "rec.npz")]) == BAD_INPUT_EXIT
        assert "--out" in capsys.readouterr().err


def test_write_atomic_leaves_no_partial_file(tmp_path):
    from tactile_torch.robot.files.safe_write import write_atomic

    path = tmp_path / "out.bin"
    path.write_bytes(b"old")

    def fail(f):
        f.write(b"half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        write_atomic(path, fail)
    assert path.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_train_piped_into_head_still_writes_the_model(files, tmp_path):
    model = tmp_path / "m.npz"
    cmd = (
        f"{sys.executable} -m tactile_torch.cli train --data {files / 'rec.npz'} --window 100 --method svm "
        f"--out {model} | head -1"
    )
    out = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("\n") == 1 and "Broken pipe" not in out.stderr, out.stderr
    assert model.is_file() and model.stat().st_size > 0


# ---------------------------------------------------------------------------------- user error or bug
BUGS = [
    AttributeError("'NoneType' object has no attribute 'X'"),
    TypeError("unsupported operand type(s) for +: 'int' and 'str'"),
    IndexError("index 3 is out of bounds for axis 0 with size 3"),
    KeyError("class_names"),
]


@pytest.mark.parametrize("bug", BUGS, ids=[type(b).__name__ for b in BUGS])
def test_a_bug_inside_the_library_is_an_internal_error_not_bad_input(files, monkeypatch, capsys, bug):
    import tactile_torch.training as training

    def broken(*args, **kwargs):
        raise bug

    monkeypatch.setattr(training, "train_classifier", broken)  # past every check of the input
    argv = ["train", "--data", str(files / "rec.npz"), "--window", "100", "--method", "svm"]
    assert main(argv) == cli.INTERNAL_ERROR_EXIT
    assert cli.INTERNAL_ERROR_EXIT not in (0, BAD_INPUT_EXIT)
    captured = capsys.readouterr()
    err = captured.err
    assert err.count("\n") == 1 and "Traceback" not in err + captured.out, err
    assert err.startswith(f"tactile-torch train: internal error: {type(bug).__name__}: "), err
    assert err.endswith("(rerun with --debug for the traceback, and please report it)\n"), err
    with pytest.raises(type(bug)):  # --debug: the exception and its traceback reach Python
        main([*argv, "--debug"])


def test_the_traceback_of_a_bug_is_shown_only_with_debug(files):
    code = (
        "import sys\n"
        "import tactile_torch.training as training\n"
        "def broken(*args, **kwargs):\n"
        "    raise AttributeError('no attribute X')\n"
        "training.train_classifier = broken\n"
        "from tactile_torch.cli import main\n"
        f"sys.exit(main(['train', '--data', {str(files / 'rec.npz')!r}, '--window', '100'] + sys.argv[1:]))\n"
    )
    plain = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert plain.returncode == cli.INTERNAL_ERROR_EXIT, plain.stderr
    assert "Traceback" not in plain.stderr and "internal error: AttributeError" in plain.stderr
    debug = subprocess.run(
        [sys.executable, "-c", code, "--debug"], capture_output=True, text=True, timeout=300
    )
    assert debug.returncode == 1  # Python's own status for an uncaught exception
    assert "Traceback" in debug.stderr and "AttributeError: no attribute X" in debug.stderr


def test_an_input_error_of_the_library_is_bad_input_whatever_its_base(files, monkeypatch, capsys):
    import tactile_torch.training as training
    from tactile_torch.exceptions import InputTypeError

    def refuse(*args, **kwargs):
        raise InputTypeError("labels must be integers, got float64")

    monkeypatch.setattr(training, "train_classifier", refuse)
    argv = ["train", "--data", str(files / "rec.npz"), "--window", "100", "--method", "svm"]
    assert main(argv) == BAD_INPUT_EXIT
    assert (
        capsys.readouterr().err
        == f"tactile-torch train: {files / 'rec.npz'}: labels must be integers, got float64\n"
    )


def test_the_validation_helpers_raise_input_errors():
    from tactile_torch.exceptions import InputError, InputTypeError
    from tactile_torch.validation import check_positive, check_tensor

    with pytest.raises(InputTypeError, match=r"frames must be a torch\.Tensor, got list"):
        check_tensor([1, 2], "frames")
    with pytest.raises(InputTypeError, match=r"window must be an integer, got 2\.5"):
        check_positive(2.5, "window", integer=True)
    assert issubclass(InputTypeError, TypeError) and issubclass(InputTypeError, InputError)
    assert cli.is_user_error(InputTypeError("x")) and cli.is_user_error(FileNotFoundError(2, "x", "f"))
    assert not cli.is_user_error(TypeError("x")) and not cli.is_user_error(AttributeError("x"))


def test_an_error_inside_a_stage_on_accepted_input_is_internal_whatever_its_class(
    tmp_path, monkeypatch, capsys
):
    """A ValueError raised by an internal call (a shape check fed by the library itself) after the input was
    accepted is a bug: status 1 "internal error in <stage>", never status 2 (bad input)."""
    import tactile_torch.tradeoff.runner as runner
    from tactile_torch.data.vibration import VibrationRecordings
    from tactile_torch.exceptions import InternalError, internal_stage

    with pytest.raises(InternalError) as caught, internal_stage("feature SNR"):
        raise ValueError("x must have shape (B, F), got (240, 3, 800)")
    assert not cli.is_user_error(caught.value) and isinstance(caught.value.__cause__, ValueError)
    with pytest.raises(OSError), internal_stage("writing"):  # the machine's, not a bug: passes as is
        raise OSError(28, "No space left on device")

    def broken(*args, **kwargs):
        raise ValueError("x must have shape (B, F), got (240, 3, 800)")

    monkeypatch.setattr(runner, "execute_plan", broken)
    rng = np.random.default_rng(0)
    path = VibrationRecordings(
        [rng.normal(0, 0.1, (2000, 3)).astype(np.float32) for _ in range(4)],
        np.array([0, 0, 1, 1]),
        ("a", "b"),
        800.0,
    ).save(tmp_path / "rec.npz")
    argv = [
        "tradeoff",
        "--data",
        str(path),
        "--out",
        str(tmp_path / "o"),
        "--quick",
        "--quiet",
        "--windows",
        "400",
    ]
    assert main(argv) == 1
    assert capsys.readouterr().err == (
        "tactile-torch tradeoff: internal error in cross-validation, export and timing: ValueError: x must have "
        "shape (B, F), got (240, 3, 800) (rerun with --debug for the traceback, and please report it)\n"
    )


def test_help_lists_the_exit_statuses(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "exit status: 0 done; 2 bad input" in out and "1 internal error (a bug" in out


@pytest.mark.parametrize(
    ("library", "command_line"),
    [
        ("n_folds must be at most 10 here", "--folds must be at most 10 here"),
        ("window: none of the sizes fits; pass window=", "--window: none of the sizes fits; pass --window"),
        ("x.csv: t looks like ms; pass time_unit='ms'", "x.csv: t looks like ms; pass --time-unit ms"),
        (
            "b: two topics; name one with topic=, the bag has",
            "b: two topics; name one with --topic, the bag has",
        ),
        ("b: give the map's shape with shape=(H, W)", "b: give the map's shape with --shape H,W"),
        (
            "x.npz: pickled; pass allow_pickle=True if you trust it",
            "x.npz: pickled; pass --allow-pickle if you trust it",
        ),
        ("x.npz: counts; scale=0.0039 for the ADXL345", "x.npz: counts; --scale 0.0039 for the ADXL345"),
        ("x.npz: features must be finite", "x.npz: features must be finite"),  # about the file's content
        (
            "frames must have shape (B, T, 3, H, W)",
            "frames must have shape (B, T, 3, H, W)",
        ),  # not an option here
    ],
)
def test_library_messages_name_arguments_and_the_cli_shows_its_options(library, command_line):
    flags = {k: v for k, v in cli.ARGUMENT_FLAGS.items() if k != "frames"}  # as for train (no --frames)
    assert cli.with_flags(library, flags) == command_line


def test_library_error_messages_name_no_command_line_option():
    """Every error and warning of the library names the argument; the options are the CLI's business
    (a whole command line, ``'tactile-torch train --out'``, may be quoted)."""
    import ast
    import re

    def texts(node):
        return [n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)]

    root = Path(__file__).resolve().parents[2] / "tactile_torch"
    found = []
    for path in root.rglob("*.py"):
        if "cli" in path.relative_to(root).parts or path.parent.name == "studies":
            continue  # the command line itself; the studies write reproduce lines, not errors
        for node in ast.walk(ast.parse(path.read_text())):
            warns = isinstance(node, ast.Call) and ast.unparse(node.func) in ("warnings.warn", "warn")
            message = isinstance(node, ast.FunctionDef) and node.name.endswith("_message")
            if isinstance(node, ast.Raise) or warns or message:
                found += [
                    f"{path.relative_to(root)}:{node.lineno}: {t}"
                    for t in texts(node)
                    if re.search(r"(^|[\s(])--[a-z]", re.sub(r"tactile-torch [\w-]+ --[\w-]+", "", t))
                ]
    assert not found, found
