"""Real taxel-array grasps from the shared data sets, as image explorations.

:func:`load_icub_grasps` reads ``icub_grasp`` (Soh, Su & Demiris 2012: an iCub hand's 5 fingertips of
12 capacitive taxels grasping 10 objects); :func:`load_drimus_grasps` reads the other real
pressure-array set, ``drimus_sdh_tactile`` (a Schunk hand). Both hold objects rather than
textures: they test whether conclusions drawn on the synthetic textures carry over to real tactile
sequences (``tactile_torch.studies.claims``). Each set's ``PROVENANCE.md`` gives its licence and caveats.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import torch

from ..robot.stream.touches import fit_frames
from ..validation import check_positive
from .images import SATURATION, ImageExplorations, render_pressure

ICUB = "icub_grasp"
"""Name of the shared iCub grasp data set."""
ICUB_FINGERS = 5
ICUB_TAXELS = 12
_ICUB_LINES = (
    7  # per time slice: 9 joint encoders, 5 per-finger maxima, then one line of 12 taxels per finger
)


def _read_icub(path: Path) -> np.ndarray:
    """Taxel readings ``(T, 5, 12)`` of one iCub grasp file (first line ``-10000``, then 7 lines per slice)."""
    lines = [line.split() for line in path.read_text().splitlines()[1:] if line.strip()]
    if len(lines) % _ICUB_LINES:
        raise ValueError(
            f"{path.name}: expected blocks of {_ICUB_LINES} lines per time slice, got {len(lines)} lines"
        )
    slices = [lines[i + 2 : i + _ICUB_LINES] for i in range(0, len(lines), _ICUB_LINES)]
    taxels = np.array([[[float(v) for v in row] for row in block] for block in slices])
    if taxels.shape[1:] != (ICUB_FINGERS, ICUB_TAXELS):
        raise ValueError(
            f"{path.name}: expected {ICUB_FINGERS} x {ICUB_TAXELS} taxels per slice, got {taxels.shape[1:]}"
        )
    return taxels


def load_icub_grasps(
    path: str | Path | None = None,
    *,
    n_frames: int = 4,
    scale: int = 4,
    reliable_only: bool = True,
) -> ImageExplorations:
    """Return the iCub grasps as explorations of a 5 x 12 taxel map (finger x taxel), last ``n_frames`` slices.

    Contact lowers an iCub skin reading (0-255), so each taxel's pressure is its resting level (the
    maximum over the whole grasp) minus the reading: 0 where untouched. The rows are fingers (thumb,
    index, middle, ring, little) and the columns the 12 taxels of a fingertip in file order: a map,
    not a spatial image (neighbouring columns are not always neighbouring taxels), rendered by
    :func:`~tactile_torch.data.images.render_pressure` at ``scale`` pixels per taxel.

    Parameters
    ----------
    path : path, optional
        The data set's directory; default ``shared_data_dir("icub_grasp")``.
    n_frames : int
        Slices kept per grasp, the last ones (the object held; :func:`tactile_torch.robot.stream.touches.fit_frames`,
        which the live stream brings a touch to the bundle's frames with); every grasp has at least 4.
    scale : int
        Display pixels per taxel.
    reliable_only : bool
        Leave out ``full_coke``, which the data set's README calls unreliable.

    Returns
    -------
    ImageExplorations
        ``frames`` ``(N, n_frames, 3, 5 scale, 12 scale)`` uint8, ``labels`` by object (classes in
        alphabetical order), ``pressure`` the taxel maps ``(N, n_frames, 5, 12)``.
    """
    from . import shared_data_dir

    check_positive(n_frames, "n_frames", integer=True)
    check_positive(scale, "scale", integer=True)
    root = Path(path) if path is not None else shared_data_dir(ICUB)
    if root is None or not (root / "index.csv").is_file():
        raise FileNotFoundError(f"the {ICUB} data set (index.csv) was not found at {root}")
    with (root / "index.csv").open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if not reliable_only or r["reliable"] == "True"]
    names = sorted({r["class_name"] for r in rows})
    maps, labels = [], []
    for row in rows:
        taxels = _read_icub(root / row["file"])
        if taxels.shape[0] < n_frames:
            raise ValueError(
                f"n_frames must be <= {taxels.shape[0]} (slices of {row['file']}), got {n_frames}"
            )
        maps.append(taxels.max(axis=0) - fit_frames(taxels, n_frames))
        labels.append(names.index(row["class_name"]))
    pressure = torch.from_numpy(np.stack(maps).astype(np.float32))
    return ImageExplorations(
        frames=render_pressure(pressure, (scale * ICUB_FINGERS, scale * ICUB_TAXELS), saturation=SATURATION),
        labels=torch.tensor(labels, dtype=torch.int64),
        class_names=tuple(names),
        pressure=pressure,
    )


DRIMUS = "drimus_sdh_tactile"
"""Name of the shared real data set of pressure-array grasps (Drimus et al. 2012, see its PROVENANCE.md)."""


def load_drimus_grasps(
    path: str | Path | None = None,
    *,
    sensor: str = "ts1_f1_proximal",
    n_frames: int = 100,
    scale: int = 4,
) -> ImageExplorations:
    """Return real pressure-array grasps as explorations: one sensor's last ``n_frames`` frames per grasp.

    The shared data set ``drimus_sdh_tactile`` (a Schunk hand's 14 x 6 / 13 x 6 piezoresistive arrays
    grasping 5 objects; raw 8-bit readings, about 15 frames/s) holds objects rather than textures, but
    it is a real pressure-array image sequence for testing the pipeline on realistic input. Each taxel's
    resting level (its minimum over the grasp) is subtracted, so that no contact reads 0, and the maps
    are rendered by :func:`render_pressure` at ``scale`` pixels per taxel.

    Parameters
    ----------
    path : path, optional
        The data set's directory; default ``shared_data_dir("drimus_sdh_tactile")``.
    sensor : str
        Array name in the grasp files (``ts1_f1_proximal`` ... ``ts6_f3_distal``).
    n_frames : int
        Frames kept per grasp, the last ones (the object held; :func:`tactile_torch.robot.stream.touches.fit_frames`,
        which the live stream brings a touch to the bundle's frames with); every grasp has at least 324.
    scale : int
        Display pixels per taxel.

    Returns
    -------
    ImageExplorations
        ``frames`` (51, n_frames, 3, scale * R, scale * C) uint8, ``labels`` by object, ``pressure``
        the baseline-subtracted readings.
    """
    from . import shared_data_dir

    check_positive(n_frames, "n_frames", integer=True)
    check_positive(scale, "scale", integer=True)
    root = Path(path) if path is not None else shared_data_dir(DRIMUS)
    if root is None or not (root / "grasps_npz").is_dir():
        raise FileNotFoundError(f"the {DRIMUS} data set (grasps_npz/) was not found at {root}")
    maps, labels, names = [], [], {}
    for file in sorted((root / "grasps_npz").glob("*.npz")):
        with np.load(file, allow_pickle=False) as grasp:
            if sensor not in grasp.files:
                raise ValueError(f"sensor must be one of the arrays in {file.name}, got {sensor!r}")
            readings = grasp[sensor].astype(np.float32)
            if readings.shape[0] < n_frames:
                raise ValueError(
                    f"n_frames must be <= {readings.shape[0]} (frames of {file.name}), got {n_frames}"
                )
            maps.append(fit_frames(readings, n_frames) - readings.min(axis=0))
            labels.append(int(grasp["label"]))
            names[int(grasp["label"])] = str(grasp["class_name"])
    pressure = torch.from_numpy(np.stack(maps))
    height, width = pressure.shape[-2:]
    return ImageExplorations(
        frames=render_pressure(pressure, (scale * height, scale * width), saturation=SATURATION),
        labels=torch.tensor(labels, dtype=torch.int64),
        class_names=tuple(names[k] for k in sorted(names)),
        pressure=pressure,
    )


__all__ = ["DRIMUS", "ICUB", "load_drimus_grasps", "load_icub_grasps"]
