"""Data: seeded synthetic generators, loaders for the ``.npz`` formats, and the shared real data sets.

Submodules (imported on demand, so that this package stays free of torch):
``images`` - tactile-image explorations (seeded generator, ``.npz`` loader and saver);
``vibration`` - triaxial recordings and windows (``.npz``/CSV loaders and savers);
``stylus`` - the seeded simulator of the study's stylus recordings;
``recordings`` - loaders of the shared real IMU data sets;

What a ``--data`` argument names (``.npz``, CSV logs with declared columns, units and time unit,
ROS 2 bags) is read by the robot side, which reads it too (``tactile-torch predict``):
:mod:`tactile_torch.robot.files.data_sources`, :mod:`tactile_torch.robot.files.csv_logs`,
:mod:`tactile_torch.robot.ros2.bags` and :mod:`tactile_torch.robot.files.formats`.

Real data sets live outside the repository, in ``../shared/data/<name>/`` (each with a
``PROVENANCE.md``); :func:`shared_data_dir` finds them.
"""

from __future__ import annotations

import os
from pathlib import Path

from .._exports import lazy_exports

SHARED_DATA_ENV = "TACTILE_TORCH_SHARED_DATA"


def shared_data_dir(name: str | None = None) -> Path | None:
    """Return the directory of the shared real data (or of one data set in it), or ``None`` if absent.

    Looked up, in order: the ``TACTILE_TORCH_SHARED_DATA`` environment variable, then
    ``../shared/data`` next to the source checkout, then ``../shared/data`` relative to the current
    directory.
    """
    candidates = []
    if os.environ.get(SHARED_DATA_ENV):
        candidates.append(Path(os.environ[SHARED_DATA_ENV]))
    candidates.append(Path(__file__).resolve().parents[2] / ".." / "shared" / "data")
    candidates.append(Path.cwd() / ".." / "shared" / "data")
    for root in candidates:
        path = root / name if name else root
        if path.is_dir():
            return path.resolve()
    return None


__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "vibration": (
            "VibrationRecordings",
            "VibrationWindows",
            "load_vibration_npz",
            "save_vibration_npz",
        ),
        "stylus": ("make_vibration_dataset", "make_vibration_recordings"),
        "recordings": ("load_borealtc_imu", "load_hapmat_imu5"),
    },
    defined=("SHARED_DATA_ENV", "shared_data_dir"),
)
