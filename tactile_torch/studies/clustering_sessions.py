"""How many surfaces across days: the mixture with session effects against the plain one, on data that span sessions.

Sources (:func:`session_sources`), each with the true surface of every window and its session:

- ``days-SxD-seedN``: the stylus generator recorded on ``D`` days (:func:`multi_day`): ``S`` surfaces
  drawn per seed with one deliberately near-duplicate pair (alike surfaces at a quarter of their
  tabulated distance), every surface's parameters moved per day (pressure, speed, wear: log-normal
  ``session_jitter``) and every day's signals scaled by that day's gain (a re-mounted sensor);
- ``sessions-3x3``: the 3 bundled surfaces x 3 sessions with gains 0.8 / 1 / 1.25 of
  :mod:`.clustering_k`;
- ``hapmat-days``: HapMat's five real recordings cut into 5 consecutive sessions of 12 s each
  (the hand-held swipes drift: real, unsimulated session changes), and ``hapmat-days, gains``: the
  same with a gain per session as a re-mounted sensor would add.

:func:`session_rows` fits :class:`~tactile_torch.mixture.PitmanYorGMM` at its defaults (``n_iter="auto"``)
three ways per source: the plain mixture, the plain mixture on per-session standardised features, and
the mixture with session effects (``fit(X, sessions=...)``); each row gives the posterior of K, whether
its 95 % interval covers the number of surfaces (or one less: the near-duplicate pair merged) and
lies within one of it, the point estimate's pairwise accuracy and adjusted Rand index against the
surfaces, R-hat and ESS of K, and the time.
``python -m tactile_torch.studies.clustering_sessions`` prints the table (``--only``, ``--ways``).
"""

from __future__ import annotations

import sys
import time
import warnings
from typing import Any

import numpy as np

MULTI_DAY = ((5, 3, 0), (6, 4, 1), (7, 5, 2), (8, 6, 3), (7, 5, 4))
"""(surfaces, days, seed) of the generator's multi-day sources."""
NEAR_DUPLICATE = 0.25
"""``alike_distance`` of the near-duplicate pair: a quarter of the tabulated difference."""
GAIN_SD = 0.1
"""Log-normal spread of a day's gain (a re-mounted sensor: about +-10 %)."""
DAY_JITTER = 0.08
"""Log-normal spread of every surface parameter from one day to the next (pressure, speed, wear)."""
WAYS = ("plain", "per-session standardised", "session effects")
"""How :func:`session_rows` fits each source."""


def multi_day(
    n_surfaces: int = 7,
    n_days: int = 5,
    seed: int = 0,
    *,
    duration_s: float = 30.0,
    components: int = 3,
    gain_sd: float = GAIN_SD,
    day_jitter: float = DAY_JITTER,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (PCA features (n, components), surface labels (n,), day (n,)) of stylus recordings over several days.

    ``n_surfaces`` surfaces of the generator's table drawn with ``seed``, one alike pair among them
    moved to :data:`NEAR_DUPLICATE` of its distance (a near-duplicate); each recorded ``duration_s``
    on each of ``n_days`` days at 1 kHz, its parameters jittered per day by ``day_jitter`` and the
    day's signals scaled by a gain ``exp(N(0, gain_sd^2))``. 800-sample windows, the 21 features,
    the clustering transform (fitted on all windows) to ``components`` principal components.
    """
    from ..data.vibration import VibrationRecordings
    from .clustering_k import _pca_features

    rec = multi_day_recordings(
        n_surfaces, n_days, seed, duration_s=duration_s, gain_sd=gain_sd, day_jitter=day_jitter
    )
    day = np.array([int(str(s)[3:]) for s in rec.session])
    ds = VibrationRecordings(rec.signals, rec.labels, rec.class_names, rec.rate_hz, rec.session).windows(800)
    X = _pca_features(ds.windows, components)
    return X, ds.labels.numpy(), day[ds.recording.numpy()]


def multi_day_recordings(
    n_surfaces: int = 7,
    n_days: int = 5,
    seed: int = 0,
    *,
    duration_s: float = 30.0,
    gain_sd: float = GAIN_SD,
    day_jitter: float = DAY_JITTER,
):
    """Return the recordings of :func:`multi_day` as :class:`~tactile_torch.robot.files.formats.RecordingArrays`, session = ``"day<k>"``.

    What ``tactile-torch cluster`` reads from a lab's day folders: one recording per (surface, day).
    """
    from ..data.stylus import SURFACES, make_vibration_recordings
    from ..robot.files.formats import RecordingArrays

    rng = np.random.default_rng([seed, 38])
    pairs = [
        (i, next(k for k, t in enumerate(SURFACES) if t.name == s.alike_of))
        for i, s in enumerate(SURFACES)
        if s.alike_of
    ]
    pair = pairs[int(rng.integers(len(pairs)))]
    alike = {i for p in pairs for i in p}
    others = [i for i in range(len(SURFACES)) if i not in alike]
    chosen = [pair[1], pair[0], *rng.choice(others, n_surfaces - 2, replace=False).tolist()]
    rec = make_vibration_recordings(
        surfaces=[SURFACES[i] for i in chosen],
        duration_s=duration_s,
        n_sessions=n_days,
        rate_hz=1000.0,
        session_jitter=day_jitter,
        alike_distance=NEAR_DUPLICATE,
        random_state=seed,
    )
    day = np.array([int(str(s).rsplit("/", 1)[1]) for s in rec.session])
    gains = np.exp(rng.normal(0.0, gain_sd, n_days))
    signals = [(s * np.float32(gains[k])).astype(np.float32) for s, k in zip(rec.signals, day, strict=True)]
    return RecordingArrays(
        signals,
        np.asarray(rec.labels),
        tuple(rec.class_names),
        rec.rate_hz,
        np.array([f"day{k}" for k in day]),
    )


def held_back_day(
    n_surfaces: int = 7,
    n_days: int = 5,
    seed: int = 2,
    *,
    sessions: str = "model",
    random_state: int = 0,
    **fit: Any,
) -> dict[str, Any]:
    """Fit ``tactile-torch cluster``'s workflow on every day but the last; score the last day as the robot would.

    :func:`tactile_torch.clustering.fit_clustering` on the first ``n_days - 1`` days (``sessions``:
    ``"model"`` or ``"none"``; the last third of each recording calibrates the novelty rule at 2 %),
    then the held-back day's windows through the fitted transform and the point estimate's mixture
    (``predict(using="point")``: the exported graph's labels) and the calibrated novelty rule
    (``novel_after(X, 1)``: the graph's ``novel`` output, ``stream --discover 1``). Returns the
    posterior of K, and on the held-back day the share of windows whose cluster maps (by its
    training windows' majority surface) to their surface, the share flagged novel and the adjusted
    Rand index of the clusters against the surfaces.
    """
    from sklearn.metrics import adjusted_rand_score

    from ..clustering import fit_clustering
    from ..features import load_features
    from ..robot.files.formats import RecordingArrays

    rec = multi_day_recordings(n_surfaces, n_days, seed)
    last = f"day{n_days - 1}"
    keep = np.asarray(rec.session) != last

    def subset(mask):
        idx = np.flatnonzero(mask)
        return RecordingArrays(
            [rec.signals[i] for i in idx], rec.labels[idx], rec.class_names, rec.rate_hz, rec.session[idx]
        )

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        clustering = fit_clustering(
            subset(keep), window=800, sessions=sessions, random_state=random_state, progress=False, **fit
        )
    seconds = time.perf_counter() - t0
    model = clustering.mixture
    truth = clustering.truth[clustering.fitted_rows]
    majority = np.array([np.bincount(truth[model.labels_ == k]).argmax() for k in range(model.n_clusters_)])
    test = load_features(subset(~keep), window=800, name=last)
    X = np.asarray(clustering.transform.transform(test.X))
    pred = model.predict(X, using="point")
    mapped = np.where(pred >= 0, majority[np.maximum(pred, 0)], -1)
    ks = model.n_clusters_summary_
    return {
        "surfaces": n_surfaces,
        "training days": n_days - 1,
        "sessions": sessions,
        "K mode": int(ks["mode"]),
        "K 95% interval": "[{}, {}]".format(*ks["interval"]),
        "held-back day: windows": len(test.y),
        "right surface": round(float(np.mean(mapped == test.y)), 3),
        "novel (calibrated 2 %)": round(float(np.mean(model.novel_after(X, 1))), 3),
        "ARI": round(float(adjusted_rand_score(test.y, pred)), 3),
        "fit seconds": round(seconds, 1),
    }


def sessions_3x3(seed: int = 0, components: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return :func:`.clustering_k.sessions_3x3`'s features and labels with the session of every window."""
    from ..data import make_vibration_recordings
    from .clustering_k import sessions_3x3 as source

    X, y = source(seed, components=components)
    rec = make_vibration_recordings(3, duration_s=30, n_sessions=3, random_state=seed)
    session = np.array([int(str(s).rsplit("/", 1)[1]) for s in rec.session])
    return X, y, session[rec.windows(800).recording.numpy()]


def hapmat_days(
    n_days: int = 5, *, gains: bool = False, components: int = 3, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return HapMat cut into ``n_days`` consecutive sessions of each recording (2 s windows, 1 s apart).

    Session k is the k-th of ``n_days`` equal stretches of every material's recording: a real
    swipe drifts over a minute, so the sessions differ as real days do, without simulation. With
    ``gains`` each session's signals are also scaled by ``exp(N(0, GAIN_SD^2))`` (seeded).
    Raises ``FileNotFoundError`` when the data set is not present.
    """
    from ..data import shared_data_dir
    from ..data.recordings import load_hapmat_imu5
    from ..data.vibration import VibrationRecordings
    from .clustering_k import _pca_features

    if shared_data_dir("hapmat_imu5") is None:
        raise FileNotFoundError("hapmat_imu5: the shared data set is not present")
    rec = load_hapmat_imu5()
    g = np.exp(np.random.default_rng([seed, 38]).normal(0.0, GAIN_SD, n_days)) if gains else np.ones(n_days)
    signals, labels, sessions = [], [], []
    for sig, label in zip(rec.signals, rec.labels, strict=True):
        sig = np.asarray(sig)
        cuts = np.linspace(0, sig.shape[0], n_days + 1).astype(int)
        for k in range(n_days):
            signals.append((sig[cuts[k] : cuts[k + 1]] * np.float32(g[k])).astype(np.float32))
            labels.append(int(label))
            sessions.append(k)
    recs = VibrationRecordings(
        signals, np.asarray(labels), rec.class_names, rec.rate_hz, np.asarray(sessions).astype(str)
    )
    ds = recs.windows(int(2 * rec.rate_hz), int(rec.rate_hz))
    return (
        _pca_features(ds.windows, components),
        ds.labels.numpy(),
        np.asarray(sessions)[ds.recording.numpy()],
    )


def sines_and_impulses(
    n_surfaces: int = 5,
    seed: int = 0,
    *,
    duration_s: float = 60.0,
    rate_hz: float = 800.0,
    components: int = 3,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (PCA features, labels) of surfaces made of sums of sines and impulses, one session (not the stylus model).

    Each surface: 2-4 sines (frequencies 20-300 Hz, amplitudes 0.02-0.2 g, per axis), impulses at a
    Poisson rate of 1-6 per second (0.2-1 g, decaying at 150 Hz), white noise of 5 mg; 800-sample
    windows, the 21 features, the clustering transform. A window holds a few impulses or none, so a
    surface's windows do not form one Gaussian blob in feature space (issue 38, point 6).
    """
    from ..data.vibration import VibrationRecordings
    from .clustering_k import _pca_features

    rng = np.random.default_rng([seed, 386])
    n = int(duration_s * rate_hz)
    t = np.arange(n) / rate_hz
    signals = []
    for _ in range(n_surfaces):
        x = np.zeros((n, 3))
        for axis in range(3):
            for _ in range(int(rng.integers(2, 5))):
                f, a = rng.uniform(20.0, 300.0), rng.uniform(0.02, 0.2)
                x[:, axis] += a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        hits = np.flatnonzero(rng.random(n) < rng.uniform(1.0, 6.0) / rate_hz)
        kernel = np.exp(-150.0 * np.arange(int(0.05 * rate_hz)) / rate_hz)
        pulse = np.zeros(n)
        pulse[hits] = rng.uniform(0.2, 1.0, hits.size)
        x += np.convolve(pulse, kernel)[:n, None] * rng.uniform(0.3, 1.0, 3)
        x += rng.normal(0.0, 0.005, x.shape)
        signals.append(x.astype(np.float32))
    names = tuple(f"surface {k}" for k in range(n_surfaces))
    rec = VibrationRecordings(signals, np.arange(n_surfaces), names, rate_hz, np.array(["one"] * n_surfaces))
    ds = rec.windows(800)
    return _pca_features(ds.windows, components), ds.labels.numpy()


def session_sources(components: int = 3, only: tuple[str, ...] | None = None) -> dict[str, tuple]:
    """Return {name: (X, labels, sessions)} of every source available here (HapMat when present), or of ``only``."""
    from ..data import shared_data_dir

    makers = {
        f"days-{s}x{d}-seed{seed}": (lambda s=s, d=d, seed=seed: multi_day(s, d, seed, components=components))
        for s, d, seed in MULTI_DAY
    }
    makers["sessions-3x3"] = lambda: sessions_3x3(components=components)
    if shared_data_dir("hapmat_imu5") is not None:
        makers["hapmat-days"] = lambda: hapmat_days(components=components)
        makers["hapmat-days, gains"] = lambda: hapmat_days(gains=True, components=components)
    return {name: make() for name, make in makers.items() if only is None or name in only}


def source_names() -> tuple[str, ...]:
    """Every name :func:`session_sources` can return."""
    return (
        *(f"days-{s}x{d}-seed{seed}" for s, d, seed in MULTI_DAY),
        "sessions-3x3",
        "hapmat-days",
        "hapmat-days, gains",
    )


def session_row(source: str, y: np.ndarray, way: str, model, seconds: float) -> dict[str, Any]:
    """One row of :func:`session_rows` for a ``model`` fitted ``way`` to windows of true surfaces ``y``."""
    from sklearn.metrics import adjusted_rand_score

    from ..metrics import pairwise_accuracy

    truth = int(np.unique(y).size)
    ks = model.n_clusters_summary_
    lo, hi = (int(v) for v in ks["interval"])
    conv = {r["quantity"]: r for r in model.convergence_}
    return {
        "source": source,
        "n": len(y),
        "surfaces": truth,
        "way": way,
        "K mode": int(ks["mode"]),
        "K 95% interval": f"[{lo}, {hi}]",
        "covers": "yes"
        if lo <= truth <= hi
        else ("K - 1 (a pair merged)" if lo <= truth - 1 <= hi else "no"),
        "within K +- 1": "yes" if truth - 1 <= lo and hi <= truth + 1 else "no",
        "K point estimate": int(ks["point_estimate"]),
        "pairwise accuracy": round(float(pairwise_accuracy(y, model.labels_)), 3),
        "ARI": round(float(adjusted_rand_score(y, model.labels_)), 3),
        "lambda": None if getattr(model, "session_scale_", None) is None else round(model.session_scale_, 2),
        "R-hat K": round(float(conv["K"]["R-hat"]), 3),
        "ESS K": round(float(conv["K"]["ESS bulk"])),
        "stopped by": model.stopped_by_,
        "seconds": round(seconds, 1),
    }


def session_rows(
    sources: dict[str, tuple], ways: tuple[str, ...] = WAYS, *, random_state: int = 0, **fit: Any
) -> list[dict[str, Any]]:
    """Fit every source ``ways`` (names of :data:`WAYS`) at the defaults (plus ``fit``); one row each."""
    from ..mixture import PitmanYorGMM
    from ..signal.sessions import standardise_per_session

    rows = []
    for source, (X, y, sessions) in sources.items():
        for way in ways:
            data = standardise_per_session(X, sessions) if way == "per-session standardised" else X
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                model = PitmanYorGMM(random_state=random_state, progress=False, **fit)
                model.fit(data, sessions=sessions if way == "session effects" else None)
            rows.append(session_row(source, y, way, model, time.perf_counter() - t0))
    return rows


BLOB_SETTINGS = {
    "mfm": {},
    "coarsen 3000": {"coarsen": 3000.0},
    "coarsen 1000": {"coarsen": 1000.0},
    "coarsen 300": {"coarsen": 300.0},
}
"""Settings of :func:`blob_rows`: the mixture of finite mixtures, exact and coarsened (Miller & Dunson 2018)."""


def blob_rows(*, random_state: int = 0, **fit: Any) -> list[dict[str, Any]]:
    """K within one session where surfaces are not Gaussian blobs: the exact and the coarsened posterior (point 6).

    Sources: :func:`sines_and_impulses` (seeds 0 and 1) and HapMat's five recordings (one session,
    2 s windows, when present).
    """
    from ..data import shared_data_dir
    from ..mixture import PitmanYorGMM
    from .clustering_k import real_set

    sources = {f"sines and impulses, seed {k}": sines_and_impulses(5, k) for k in (0, 1)}
    if shared_data_dir("hapmat_imu5") is not None:
        sources["hapmat (one session)"] = real_set("hapmat_imu5", 60)
    rows = []
    for source, (X, y) in sources.items():
        for name, kw in BLOB_SETTINGS.items():
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                model = PitmanYorGMM(random_state=random_state, progress=False, **kw, **fit).fit(X)
            rows.append(session_row(source, y, name, model, time.perf_counter() - t0))
    return rows


def _main(argv: list[str] | None = None) -> None:
    import argparse

    from ._cli import refuse_unknown

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", help="sources to run (default: all available)")
    parser.add_argument("--ways", nargs="*", help=f"ways to fit (default: all of {', '.join(WAYS)})")
    parser.add_argument("--components", type=int, default=3, help="principal components (default: 3)")
    parser.add_argument("--max-seconds", type=float, default=300.0, help="wall-clock budget of n_iter='auto'")
    parser.add_argument("--seed", type=int, default=0, help="random_state of the fits (default: 0)")
    parser.add_argument(
        "--held-back-day",
        action="store_true",
        help="fit cluster's workflow on all days but the last of each multi-day source, score the last (robot side)",
    )
    parser.add_argument(
        "--blobs",
        action="store_true",
        help="K within one session on non-Gaussian surfaces: exact and coarsened posterior (blob_rows)",
    )
    args = parser.parse_args(argv)
    refuse_unknown(parser, "--only", args.only, source_names())
    if args.blobs:
        rows = blob_rows(random_state=args.seed, max_seconds=args.max_seconds)
        print("| " + " | ".join(rows[0]) + " |\n|" + " --- |" * len(rows[0]))
        for r in rows:
            print("| " + " | ".join(str(v) for v in r.values()) + " |", flush=True)
        return
    refuse_unknown(parser, "--ways", args.ways, WAYS)
    if args.held_back_day:
        for i, (s, d, seed) in enumerate(MULTI_DAY):
            if args.only and f"days-{s}x{d}-seed{seed}" not in args.only:
                continue
            for mode in ("model", "none"):
                row = {"source": f"days-{s}x{d}-seed{seed}"} | held_back_day(
                    s, d, seed, sessions=mode, random_state=args.seed, max_seconds=args.max_seconds
                )
                if i == 0 and mode == "model":
                    print("| " + " | ".join(row) + " |\n|" + " --- |" * len(row))
                print("| " + " | ".join(str(v) for v in row.values()) + " |", flush=True)
        return
    sources = session_sources(args.components, tuple(args.only) if args.only else None)
    for name in sorted(set(args.only or ()) - set(sources)):
        print(f"clustering_sessions: {name}: skipped, its data set is not found here", file=sys.stderr)
    ways = tuple(args.ways) if args.ways else WAYS
    for i, (name, data) in enumerate(sources.items()):
        rows = session_rows({name: data}, ways, random_state=args.seed, max_seconds=args.max_seconds)
        if i == 0:
            print("| " + " | ".join(rows[0]) + " |\n|" + " --- |" * len(rows[0]))
        for r in rows:
            print("| " + " | ".join(str(v) for v in r.values()) + " |", flush=True)


if __name__ == "__main__":
    _main()
