"""Test data for the robot tests, built without torch: they run on the robot install (``.ci/robot``).

- :func:`surface_recordings`: triaxial recordings in g (numpy only), one per surface;
- :func:`write_log`, :func:`write_logs`: CSV logs ``t,x,y,z`` of recordings (``felt_1.csv``, ...);
- :func:`prebuilt`: a fixture that only the training side can build (an exported clustering, the
  stylus simulator's recordings). In the development venv it is built on the spot; on the robot
  install, where torch is missing, it is read from ``$TACTILE_TORCH_TEST_FIXTURES/<name>``, which
  ``python -m tests.robot_data DIR`` wrote beforehand in the development venv (``.ci/robot`` does).
  A fixture that is neither there nor buildable fails the test (no skip).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tactile_torch.robot.files.formats import RecordingArrays

FIXTURES_ENV = "TACTILE_TORCH_TEST_FIXTURES"
"""Directory of the fixtures built beforehand (one subdirectory per :data:`BUILDERS` entry)."""
SURFACES = ("cork", "felt", "glass", "rubber", "sandpaper", "wood")


def surface_recordings(
    n_surfaces: int = 4, seconds: float = 4.0, rate_hz: float = 800.0, *, random_state: int = 0
) -> RecordingArrays:
    """Return one recording ``(seconds * rate_hz, 3)`` float32 in g per surface.

    Gravity (1 g on z) plus a vibration of band-limited noise, each surface with its own band
    (centred at 40 + 60 k Hz) and amplitude (0.1 + 0.05 k g rms), quantised to the ADXL345's 3.9 mg:
    values a real stylus gives, within its ±5 g.
    """
    rng = np.random.default_rng(random_state)
    n = round(seconds * rate_hz)
    freqs = np.fft.rfftfreq(n, 1 / rate_hz)
    signals = []
    for k in range(n_surfaces):
        band = np.exp(-(((freqs - (40 + 60 * k)) / 25.0) ** 2))[:, None]
        vibration = np.fft.irfft(np.fft.rfft(rng.normal(size=(n, 3)), axis=0) * band, n, axis=0)
        vibration *= (0.1 + 0.05 * k) / vibration.std(axis=0)
        signal = np.round((vibration + np.array([0.0, 0.0, 1.0])) / 0.0039) * 0.0039
        signals.append(signal.astype(np.float32))
    return RecordingArrays(signals, np.arange(n_surfaces), SURFACES[:n_surfaces], float(rate_hz))


def write_log(path, signal, rate, *, header="t,x,y,z", t_factor=1.0, factor=1.0, fmt="%.9g") -> Path:
    """Write ``signal`` ``(n, 3)`` (times ``factor``) as a CSV log with ``t`` (times ``t_factor``); return ``path``."""
    t = np.arange(len(signal)) / rate * t_factor
    np.savetxt(
        path, np.column_stack([t, signal * factor]), delimiter=",", header=header, comments="", fmt=fmt
    )
    return path


def write_logs(directory, rec, **kwargs) -> list[Path]:
    """felt_1.csv, felt_2.csv ...: each recording of ``rec`` cut in two halves, the sessions 1 and 2."""
    paths = []
    for signal, label in zip(rec.signals, rec.labels, strict=True):
        half = len(signal) // 2
        for k, part in enumerate((signal[:half], signal[half:]), start=1):
            name = f"{rec.class_names[label]}_{k}.csv"
            paths.append(write_log(Path(directory) / name, part, rec.rate_hz, **kwargs))
    return paths


# ------------------------------------------------------------------------------------ prebuilt fixtures
def build_discovery(out: Path) -> None:
    """An exported clustering of three stylus surfaces (glass, cork, rubber), their recordings, and a
    recording of a surface the clustering never saw (the coarsest sandpaper): ``cl.onnx``, ``rec.npz``,
    ``unseen.npy``. Needs the training extra."""
    from tactile_torch.cli import main
    from tactile_torch.data.stylus import SURFACES as STYLUS
    from tactile_torch.data.stylus import make_vibration_recordings

    known = [STYLUS[0], STYLUS[5], STYLUS[7]]  # glass, cork, rubber
    rec = make_vibration_recordings(surfaces=known, duration_s=8.0, random_state=0)
    np.savez(
        out / "rec.npz",
        signals=np.stack(rec.signals),
        rate_hz=rec.rate_hz,
        labels=rec.labels,
        class_names=np.array(rec.class_names),
    )
    unseen = make_vibration_recordings(surfaces=[STYLUS[27]], duration_s=4.0, random_state=1).signals[0]
    np.save(out / "unseen.npy", np.asarray(unseen))
    cluster = ["cluster", "--data", str(out / "rec.npz"), "--out", str(out / "cl")]
    common = ["--window", "400", "--n-iter", "60", "--burn-in", "20", "--chains", "2", "--quiet"]
    assert main([*cluster, *common]) == 0
    assert main(["export", "--model", str(out / "cl" / "model.npz"), "--out", str(out / "cl.onnx")]) == 0


BUILDERS: dict[str, Callable[[Path], None]] = {"discovery": build_discovery}
"""Every fixture :func:`prebuilt` serves, by name: ``python -m tests.robot_data DIR`` builds them all."""


def prebuilt(name: str, scratch: Path) -> Path:
    """Return the directory of the fixture ``name``: from ``$TACTILE_TORCH_TEST_FIXTURES`` when set (the
    robot install), else built now in ``scratch`` (the development venv)."""
    root = os.environ.get(FIXTURES_ENV)
    if root:
        path = Path(root) / name
        if not (path / ".done").is_file():
            raise FileNotFoundError(
                f"{path}: fixture {name!r} not built; run `python -m tests.robot_data {root}` in the "
                "development venv first"
            )
        return path
    path = Path(scratch) / name
    path.mkdir(parents=True, exist_ok=True)
    BUILDERS[name](path)
    (path / ".done").touch()
    return path


if __name__ == "__main__":  # python -m tests.robot_data DIR: build every fixture into DIR
    target = Path(sys.argv[1])
    for fixture in BUILDERS:
        prebuilt(fixture, target)
        print(f"built {target / fixture}")
