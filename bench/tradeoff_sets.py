"""Two data sets shaped like users' own, for the trade-off's bench rows and tests (issue 39).

Neither is the bundled default of ``make run``; both come from the package's seeded generators with
settings of their own, so that a conclusion drawn on them is drawn on data the study was not tuned on:

* :func:`lab_logs`: a lab's stylus logs kept as a lab keeps them, one folder per day
  (``day1/felt.csv`` ...), CSV ``t,x,y,z`` at 1 kHz, 30 s each; 7 surfaces x 5 days = 35 recordings,
  with sessions that shift (each day every surface's parameters move by a log-normal spread of
  :data:`LAB_SESSION_JITTER`, against the generator's default 0.04, and the sensor noise is higher).
  The folder is the session (docs/formats.md, the naming rule), so the study's folds hold out days.
* :func:`fingertip_explorations`: a 4 x 4 taxel fingertip (3 mm pitch) slid over 7 fabrics, 186
  explorations of :data:`FINGERTIP_FRAMES` raw pressure frames at :data:`FINGERTIP_RATE_HZ`, in
  :data:`FINGERTIP_SESSIONS` sessions whose grip differs; from the frame generator
  (:func:`tactile_torch.data.images.make_explorations` with 4 sensels per side and ``keep_pressure``),
  7 of its objects standing for the fabrics. The session is the group (the folds hold out sessions).

``scale`` multiplies the sessions (days of logs, sessions of explorations) for the bench's "4x the data"
rows.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

LAB_SURFACES = 7
LAB_DAYS = 5
LAB_SECONDS = 30.0
LAB_RATE_HZ = 1000.0
LAB_SESSION_JITTER = 0.12
"""Day-to-day spread of the surfaces' parameters (the generator's default is 0.04)."""
LAB_NOISE_LSB = 2.0
LAB_TABLE_START = 9
"""The lab's surfaces are rows 9-15 of the generator's table (not the first ones, which the bundled data use)."""

FINGERTIP_FABRICS = 7
FINGERTIP_EXPLORATIONS = 186
FINGERTIP_FRAMES = 200
FINGERTIP_RATE_HZ = 100.0
FINGERTIP_PITCH_MM = 3.0
"""Distance between the fingertip's taxel centres: a 4 x 4 array of about 12 mm."""
FINGERTIP_SESSIONS = 6
FINGERTIP_CONTACT_SPREAD = 0.15
"""Log-normal spread of the fingertip pad's size from one session to the next."""
FABRICS = (0, 4, 9, 13, 1, 5, 15)
"""The generator's objects (:data:`tactile_torch.data.images.OBJECTS`) that stand for the 7 fabrics: two of
dots, two of dashes, one of lines and two of grids, of different pitch and relief (in two groups of
distinct patterns: the generator labels an exploration by its object's pattern)."""


def lab_logs(out_dir: str | Path, *, scale: int = 1, random_state: int = 39) -> list[Path]:
    """Write the lab's stylus logs under ``out_dir`` (``day<k>/<surface>.csv``); return the files, sorted.

    ``scale`` days per original day: ``scale=4`` writes 20 days of the same 7 surfaces (4x the data).
    """
    from tactile_torch.data.stylus import make_vibration_recordings, surface_table

    table = surface_table(LAB_TABLE_START + LAB_SURFACES)[LAB_TABLE_START:]
    rec = make_vibration_recordings(
        surfaces=table,
        duration_s=LAB_SECONDS,
        n_sessions=LAB_DAYS * scale,
        rate_hz=LAB_RATE_HZ,
        session_jitter=LAB_SESSION_JITTER,
        noise_lsb=LAB_NOISE_LSB,
        random_state=random_state,
    )
    out = Path(out_dir)
    files = []
    for signal, label, session in zip(rec.signals, rec.labels, rec.session, strict=True):
        day = int(str(session).rsplit("/", 1)[1]) + 1
        path = out / f"day{day}" / f"{rec.class_names[int(label)]}.csv"
        path.parent.mkdir(parents=True, exist_ok=True)
        t = np.arange(len(signal)) / LAB_RATE_HZ
        np.savetxt(
            path,
            np.column_stack([t, signal]),
            delimiter=",",
            header="t,x,y,z",
            comments="",
            fmt=["%.3f", "%.4f", "%.4f", "%.4f"],
        )
        files.append(path)
    return sorted(files)


def fingertip_explorations(
    *,
    scale: int = 1,
    random_state: int = 39,
    n_frames: int = FINGERTIP_FRAMES,
    sessions: int = FINGERTIP_SESSIONS,
    total: int = FINGERTIP_EXPLORATIONS,
) -> dict[str, np.ndarray]:
    """Return the fingertip set as the ``.npz`` arrays of raw pressure maps (docs/formats.md).

    ``frames`` float32 ``(N, T, 4, 4)``, ``labels`` ``(N,)``, ``class_names`` ``(7,)``, ``groups``
    ``(N,)`` (the session) and ``rate_hz``. The 7 fabrics are 7 objects of the generator
    (:data:`FABRICS`); each of :data:`FINGERTIP_SESSIONS` sessions (``scale`` times as many with
    ``scale``) draws its explorations with a fingertip contact of its own (the pad's size moves by
    :data:`FINGERTIP_CONTACT_SPREAD` from one session to the next: another day's grip).
    """
    from tactile_torch.data.images import DEFAULT_CONTACT_MM, OBJECTS, make_explorations

    rng = np.random.default_rng(random_state)
    per_session = -(-total // (FINGERTIP_FABRICS * sessions))  # 5
    sessions *= scale
    fabrics = [OBJECTS[i] for i in FABRICS]
    frames, labels, groups = [], [], []
    for session in range(sessions):
        size = float(rng.lognormal(0.0, FINGERTIP_CONTACT_SPREAD))
        contact = (DEFAULT_CONTACT_MM[0] * size, DEFAULT_CONTACT_MM[1] * size)
        for first in range(0, FINGERTIP_FABRICS, 4):
            chunk = fabrics[first : first + 4]
            # make_explorations labels by pattern and needs one object of each: fill with the first ones
            patterns = [o.pattern for o in chunk]
            fill = [o for o in OBJECTS if o.pattern not in patterns]
            objects = tuple(chunk + [next(o for o in fill if o.pattern == p) for p in _missing(patterns)])
            data = make_explorations(
                per_session,
                n_frames=n_frames,
                frame_size=16,
                sensels=4,
                objects=objects,
                keep_pressure=True,
                sensel_pitch_mm=FINGERTIP_PITCH_MM,
                contact_mm=contact,
                random_state=rng,
            )
            pattern_of = np.array([data.class_names[int(c)] for c in data.labels.numpy()])
            for j, obj in enumerate(chunk):
                rows = np.flatnonzero(pattern_of == obj.pattern)
                frames.append(data.pressure.numpy()[rows].astype(np.float32))
                labels.append(np.full(len(rows), first + j))
                groups.append(np.full(len(rows), session))
    frames, labels, groups = (np.concatenate(a) for a in (frames, labels, groups))
    # 186 of 210 (x scale): 27 of the first four fabrics, 26 of the others, evenly over the sessions
    total *= scale
    counts = np.full(FINGERTIP_FABRICS, total // FINGERTIP_FABRICS)
    counts[: total % FINGERTIP_FABRICS] += 1
    keep = np.zeros(len(labels), dtype=bool)
    for c, n in enumerate(counts):
        rows = np.flatnonzero(labels == c)
        keep[rows[np.linspace(0, len(rows) - 1, n).round().astype(int)]] = True
    return {
        "frames": frames[keep],
        "labels": labels[keep].astype(np.int64),
        "class_names": np.array([o.name for o in fabrics]),
        "groups": groups[keep].astype(np.int64),
        "rate_hz": np.float64(FINGERTIP_RATE_HZ),
    }


def _missing(patterns: list[str]) -> list[str]:
    from tactile_torch.data.images import CLASS_NAMES

    return [p for p in CLASS_NAMES if p not in patterns]


def write_fingertip(path: str | Path, *, scale: int = 1, random_state: int = 39) -> Path:
    """Write :func:`fingertip_explorations` to ``path`` (``.npz``); return it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **fingertip_explorations(scale=scale, random_state=random_state))
    return path
