"""Loaders of the real accelerometer data sets under ``../shared/data/`` into :class:`VibrationRecordings`.

Both sets are 100 Hz IMU logs, far from the study's 800 Hz stylus: nothing above 50 Hz is recorded
(fine texture vibration is not in them), and upsampling to 800 Hz (``rate_hz=800``) changes the
sample count, not the content. They exercise the feature and classifier code on real, labelled,
non-synthetic triaxial signals; absolute feature values and the study's window sizes do not
transfer. Read each set's ``PROVENANCE.md`` (licence, source commit, caveats).

=================  =========================================================================
``hapmat_imu5``    HapMat (MIT licence): an IMU on a rigid stick swiped by hand over 5 materials
                   (Fabric, Leather, Metal, Paper, Wood), one 60 s recording each (6001 rows,
                   100 Hz). Columns ``accel_x, accel_y, accel_z``; the unit is **not
                   documented**. We take the values as g: they are small and zero-mean (std
                   0.015-0.14), consistent with gravity-removed linear acceleration in g; if they
                   were m/s^2 every value would be 9.81x too large here (pass ``scale=``). About
                   2 % of consecutive rows repeat (the sensor updates slower than the log).
``borealtc_imu``   BorealTC (CC0): a Husky wheeled robot's body IMU on 5 terrains (ASPHALT,
                   FLOORING, ICE, SANDY_LOAM, SNOW), 15 runs of 9-88 s at 100 Hz. Columns
                   ``ax, ay, az`` in m/s^2 **including gravity**; converted to g (divided by
                   9.80665), so ``az`` is about +1 g. Axis frame: the robot's IMU frame.
=================  =========================================================================
"""

from __future__ import annotations

import csv
from pathlib import Path

from ..robot.files.formats import read_csv_recordings
from . import shared_data_dir
from .vibration import VibrationRecordings

HAPMAT_COLUMNS = ("time", "accel_x", "accel_y", "accel_z")
BOREALTC_COLUMNS = ("time", "ax", "ay", "az")


def _data_dir(name: str, root: str | Path | None) -> Path:
    path = Path(root) if root is not None else shared_data_dir(name)
    if path is None or not path.is_dir():
        where = root if root is not None else f"../shared/data/{name}"
        raise FileNotFoundError(
            f"data set {name!r} not found at {where}; it lives next to the checkout (see "
            "tactile_torch.data.shared_data_dir) or pass root="
        )
    return path


def load_hapmat_imu5(
    root: str | Path | None = None, *, rate_hz: float | None = None, scale: float = 1.0
) -> VibrationRecordings:
    """Load HapMat (5 materials, one 60 s recording each, 100 Hz) as :class:`VibrationRecordings`.

    Parameters
    ----------
    root : path, optional
        The data set's directory (``<Material>_<k>.csv`` files); default ``../shared/data/hapmat_imu5``.
    rate_hz : float, optional
        Resample to this rate (``scipy.signal.resample_poly``); default the native 100 Hz.
    scale : float
        Factor applied to the accelerations, which are taken as g (their unit is undocumented).

    Returns
    -------
    VibrationRecordings
        Class = material, session = the number after it (the naming rule: ``Fabric_1.csv`` →
        ``Fabric``, session ``1``).

    Examples
    --------
    >>> rec = load_hapmat_imu5()  # doctest: +SKIP
    >>> rec.class_names, rec.rate_hz  # doctest: +SKIP
    (('Fabric', 'Leather', 'Metal', 'Paper', 'Wood'), 100.0)
    """
    files = sorted(_data_dir("hapmat_imu5", root).glob("*.csv"))
    if not files:
        raise FileNotFoundError(f"no CSV file in {_data_dir('hapmat_imu5', root)}")
    rec = VibrationRecordings.from_arrays(read_csv_recordings(files, columns=HAPMAT_COLUMNS, scale=scale))
    return rec if rate_hz is None else rec.resample(rate_hz)


def load_borealtc_imu(root: str | Path | None = None, *, rate_hz: float | None = None) -> VibrationRecordings:
    """Load the BorealTC subset (5 terrains, 15 runs, 100 Hz) as :class:`VibrationRecordings` in g.

    Parameters
    ----------
    root : path, optional
        The data set's directory (``<CLASS>/imu_XX.csv``, listed in ``index.csv`` when present);
        default ``../shared/data/borealtc_imu``.
    rate_hz : float, optional
        Resample to this rate; default the native 100 Hz.

    Returns
    -------
    VibrationRecordings
        Accelerations ``ax, ay, az`` divided by 9.80665 (m/s^2 with gravity → g); class = terrain
        folder, session = ``<CLASS>/imu_XX``.
    """
    path = _data_dir("borealtc_imu", root)
    index = path / "index.csv"
    if index.exists():
        with index.open(newline="") as f:
            files = [path / row["imu_file"] for row in csv.DictReader(f)]
    else:
        files = sorted(path.glob("*/imu_*.csv"))
    if not files:
        raise FileNotFoundError(f"no imu_*.csv file in {path}")
    arrays = read_csv_recordings(
        files,
        class_names=[f.parent.name for f in files],
        sessions=[f"{f.parent.name}/{f.stem}" for f in files],
        columns=BOREALTC_COLUMNS,
        units="m/s2",
    )
    rec = VibrationRecordings.from_arrays(arrays)
    return rec if rate_hz is None else rec.resample(rate_hz)


__all__ = ["load_borealtc_imu", "load_hapmat_imu5"]
