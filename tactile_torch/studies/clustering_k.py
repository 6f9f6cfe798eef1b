"""How many surfaces, on five data sources: the posterior of K of each prior and power of the likelihood.

Five data sources, each with a known number of surfaces (:func:`k_sources`):

- ``gaussian-3``: 3 Gaussian clusters in D = 3 (sd 1, centres 5 apart on an equilateral triangle,
  50 points each): well specified, the theory's case;
- ``bundled-28``: the README's example (28 bundled synthetic stylus surfaces, 60 s each, W = 800,
  PCA-3 features; several surfaces are near-duplicates);
- ``sessions-3x3``: 3 bundled surfaces recorded in 3 sessions, each session's signal scaled by its own
  gain (0.8, 1.0, 1.25: a re-mounted sensor), as CSV logs of a user would be;
- ``sessions-3x3, per-session standardised``: the same with every feature standardised within each
  session (the remedy when sessions are known; the real sets have one surface per recording, so it
  does not apply to them);
- ``hapmat-3-sessions`` (with and without per-session standardisation): HapMat's recordings cut into
  thirds, third k scaled by ``SESSION_GAINS[k]`` (:func:`real_sessions`): real surfaces, simulated
  re-mounting;
- ``hapmat``, ``borealtc``: the real 5-material / 5-terrain IMU sets when present (2 s windows, up to
  60 per class, PCA-3).

:func:`k_coverage` fits :class:`~tactile_torch.mixture.PitmanYorGMM` with each setting on each source
and returns one row per (source, setting): the posterior of K, whether its 95 % interval covers the
truth, R-hat, ESS and time. ``python -m tactile_torch.studies.clustering_k`` prints the table
(``--quick`` for short chains).
"""

from __future__ import annotations

import sys
import time
import warnings
from typing import Any

import numpy as np

SESSION_GAINS = (0.8, 1.0, 1.25)
"""Gain of each session of ``sessions-3x3`` (a sensor re-mounted between sessions)."""

SETTINGS: dict[str, dict[str, Any]] = {
    "pyp (study)": {"model": "pyp", "coarsen": None},
    "mfm": {"model": "mfm", "coarsen": None},
    "mfm, coarsen 10000": {"model": "mfm", "coarsen": 10000.0},
    "mfm, coarsen 3000": {"model": "mfm", "coarsen": 3000.0},
    "mfm, coarsen 1000": {"model": "mfm", "coarsen": 1000.0},
    "mfm, coarsen 300": {"model": "mfm", "coarsen": 300.0},
}
"""Settings compared by :func:`k_coverage` (keyword arguments of PitmanYorGMM)."""


def gaussian_three(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Return (X (150, 3), labels): 3 Gaussian clusters, sd 1, centres 5 apart, 50 points each."""
    rng = np.random.default_rng(seed)
    centres = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [2.5, 2.5 * np.sqrt(3.0), 0.0]])
    X = np.concatenate([rng.normal(c, 1.0, size=(50, 3)) for c in centres])
    return X, np.repeat(np.arange(3), 50)


def _pca_features(windows, components: int = 3) -> np.ndarray:
    import torch

    from ..signal import fit_clustering_transform, window_features

    return fit_clustering_transform(window_features(windows.to(torch.float64)), components)[1]


def bundled_28(seed: int = 0, components: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Return the README example's PCA-3 features (28 surfaces, 60 s, W = 800; or ``components``) and labels."""
    from ..data import make_vibration_recordings

    ds = make_vibration_recordings(28, duration_s=60, random_state=seed).windows(800)
    return _pca_features(ds.windows, components), ds.labels.numpy()


def gain_invariant_features(feats) -> np.ndarray:
    """Return the 20 features of :func:`~tactile_torch.signal.window_features`' 21 that a session's gain does not move.

    A gain ``g`` multiplies every axis of a session: ``var`` by ``g^2``, ``tv`` and ``hf`` by ``g``;
    the standardised moments (``skew``, ``kurt``, ``m5``) and the threshold crossings (thresholds
    between the window's extremes) are unchanged. Kept per axis: ``skew``, ``log kurt``, ``m5``,
    ``log(1 + cross)``, ``log(tv / sd)``, ``log(hf / sd)`` (spectral shape normalised by power),
    and between axes ``log(var_x / var_z)``, ``log(var_y / var_z)``.
    """
    F = np.asarray(feats, dtype=np.float64).reshape(len(feats), 3, 7)
    var, skew, kurt, m5, tv, cross, hf = (F[:, :, k] for k in range(7))
    tiny = np.finfo(np.float64).tiny
    log_sd = 0.5 * np.log(np.maximum(var, tiny))
    per_axis = [
        skew,
        np.log(np.maximum(kurt, tiny)),
        m5,
        np.log1p(cross),
        np.log(np.maximum(tv, tiny)) - log_sd,
        np.log(np.maximum(hf, tiny)) - log_sd,
    ]
    ratios = [2 * (log_sd[:, 0] - log_sd[:, 2]), 2 * (log_sd[:, 1] - log_sd[:, 2])]
    return np.column_stack([*(c for c in per_axis), *ratios])


def _gain_invariant_pca(windows, components: int) -> np.ndarray:
    """Principal components of the standardised :func:`gain_invariant_features` of ``windows``."""
    import torch
    from sklearn.decomposition import PCA
    from sklearn.preprocessing import StandardScaler

    from ..signal import window_features

    G = gain_invariant_features(window_features(windows.to(torch.float64)).numpy())
    return PCA(components, random_state=0).fit_transform(StandardScaler().fit_transform(G))


def sessions_3x3(
    seed: int = 0, *, per_session: bool = False, components: int = 3, gain_invariant: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Return PCA-3 features and labels of 3 surfaces x 3 sessions with the gains ``SESSION_GAINS``.

    ``per_session``: standardise the features within each session
    (:func:`tactile_torch.signal.sessions.standardise_per_session`), the remedy when sessions are known.
    ``gain_invariant``: the principal components of the standardised :func:`gain_invariant_features`
    instead (no session labels needed: issue 32, decision (b)).
    """
    from ..data import make_vibration_recordings
    from ..data.vibration import VibrationRecordings

    rec = make_vibration_recordings(3, duration_s=30, n_sessions=3, random_state=seed)
    session = np.array([int(str(s).rsplit("/", 1)[1]) for s in rec.session])
    signals = [
        (s * np.float32(SESSION_GAINS[k])).astype(np.float32)
        for s, k in zip(rec.signals, session, strict=True)
    ]
    shifted = VibrationRecordings(signals, rec.labels, rec.class_names, rec.rate_hz, rec.session)
    ds = shifted.windows(800)
    X = (
        _gain_invariant_pca(ds.windows, components)
        if gain_invariant
        else _pca_features(ds.windows, components)
    )
    if per_session:
        from ..signal.sessions import standardise_per_session

        X = standardise_per_session(X, session[ds.recording.numpy()])
    return X, ds.labels.numpy()


def real_sessions(
    name: str = "hapmat_imu5", *, per_session: bool = False, components: int = 3, gain_invariant: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Return PCA-3 features and labels of a real set cut into 3 sessions with the gains ``SESSION_GAINS``.

    Each recording is cut into thirds in time; third k is session k, its signal scaled by
    ``SESSION_GAINS[k]`` (every session then holds every surface, as CSV logs of a re-mounted sensor
    would). 2 s windows, 1 s apart. ``per_session``: standardise within each session;
    ``gain_invariant``: as :func:`sessions_3x3`'s.
    """
    from ..data.recordings import load_borealtc_imu, load_hapmat_imu5
    from ..data.vibration import VibrationRecordings

    rec = {"hapmat_imu5": load_hapmat_imu5, "borealtc_imu": load_borealtc_imu}[name]()
    signals, labels, sessions = [], [], []
    for sig, label in zip(rec.signals, rec.labels, strict=True):
        sig = np.asarray(sig)
        cuts = np.linspace(0, sig.shape[0], 4).astype(int)  # (n, 3): time first
        for k in range(3):
            signals.append((sig[cuts[k] : cuts[k + 1]] * np.float32(SESSION_GAINS[k])).astype(np.float32))
            labels.append(int(label))
            sessions.append(k)
    shifted = VibrationRecordings(
        signals,
        np.asarray(labels),
        rec.class_names,
        rec.rate_hz,
        [f"{i}/{k}" for i, k in enumerate(sessions)],
    )
    ds = shifted.windows(int(2 * rec.rate_hz), int(rec.rate_hz))
    X = (
        _gain_invariant_pca(ds.windows, components)
        if gain_invariant
        else _pca_features(ds.windows, components)
    )
    if per_session:
        from ..signal.sessions import standardise_per_session

        X = standardise_per_session(X, np.asarray(sessions)[ds.recording.numpy()])
    return X, ds.labels.numpy()


def session_overlap(seed: int = 0) -> np.ndarray:
    """Return the Bhattacharyya distances (9, 9) between the (surface, session) groups of ``sessions-3x3``.

    Rows and columns ordered surface-major: (0, 0), (0, 1), (0, 2), (1, 0), ... Gaussian fits of each
    group's PCA-3 features; a distance below about 1 means two groups overlap (a Bayes error above
    about 18 %).
    """
    from ..data import make_vibration_recordings

    X, y = sessions_3x3(seed)
    rec = make_vibration_recordings(3, duration_s=30, n_sessions=3, random_state=seed)
    session = np.array([int(str(s).rsplit("/", 1)[1]) for s in rec.session])
    sess = session[rec.windows(800).recording.numpy()]
    groups = [(c, k) for c in range(3) for k in range(3)]
    stats = []
    for c, k in groups:
        sel = (y == c) & (sess == k)
        stats.append((X[sel].mean(0), np.cov(X[sel].T)))
    out = np.zeros((9, 9))
    for i, (m1, c1) in enumerate(stats):
        for j, (m2, c2) in enumerate(stats):
            S = (c1 + c2) / 2
            d = m1 - m2
            out[i, j] = d @ np.linalg.solve(S, d) / 8 + 0.5 * np.log(
                np.linalg.det(S) / np.sqrt(np.linalg.det(c1) * np.linalg.det(c2))
            )
    return out


def real_set(name: str, per: int = 60, components: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Return PCA-3 features (or ``components``) and labels of up to ``per`` 2 s windows per class of a real set."""
    from .clustering_experiments import real_windows

    X, y, _, _ = real_windows(name, per, components)
    return X, y


SOURCE_NAMES = (
    "gaussian-3",
    "sessions-3x3",
    "sessions-3x3, per-session standardised",
    "sessions-3x3, gain-invariant",
    "bundled-28",
    "hapmat",
    "borealtc",
    "hapmat-3-sessions",
    "hapmat-3-sessions, per-session standardised",
    "hapmat-3-sessions, gain-invariant",
)
"""Every source :func:`k_sources` can return (the real sets' only where their data are present)."""


def k_sources(quick: bool = False, components: int = 3) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Return {source name: (X, labels)} for the sources available here (the real sets when present).

    ``components``: principal components of the vibration sources (the study's 3; the Gaussian
    clusters stay in 3 dimensions).
    """
    from ..data import shared_data_dir

    out = {"gaussian-3": gaussian_three()}
    from .clustering_experiments import have_vibration_features

    if have_vibration_features():
        out["sessions-3x3"] = sessions_3x3(components=components)
        out["sessions-3x3, per-session standardised"] = sessions_3x3(per_session=True, components=components)
        if not quick:
            out["sessions-3x3, gain-invariant"] = sessions_3x3(gain_invariant=True, components=components)
            out["bundled-28"] = bundled_28(components=components)
        for name, key in (("hapmat_imu5", "hapmat"), ("borealtc_imu", "borealtc")):
            if shared_data_dir(name) is not None:
                out[key] = real_set(name, 30 if quick else 60, components)
        if shared_data_dir("hapmat_imu5") is not None:
            out["hapmat-3-sessions"] = real_sessions(components=components)
            out["hapmat-3-sessions, per-session standardised"] = real_sessions(
                per_session=True, components=components
            )
            out["hapmat-3-sessions, gain-invariant"] = real_sessions(
                gain_invariant=True, components=components
            )
    return out


def k_coverage(
    sources: dict[str, tuple[np.ndarray, np.ndarray]],
    settings: dict[str, dict[str, Any]] | None = None,
    *,
    random_state: int = 0,
    **fit: Any,
) -> list[dict[str, Any]]:
    """Return one row per (source, setting): posterior of K, coverage of the truth, R-hat, ESS, seconds.

    ``fit``: further keyword arguments of every PitmanYorGMM (``n_iter``, ``burn_in``, ...).
    """
    from ..mixture import PitmanYorGMM

    rows = []
    for source, (X, y) in sources.items():
        for name, kw in (settings or SETTINGS).items():
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                model = PitmanYorGMM(random_state=random_state, progress=False, **kw, **fit).fit(X)
            rows.append(coverage_row(source, y, name, model, time.perf_counter() - t0))
    return rows


def coverage_row(source: str, y: np.ndarray, setting: str, model, seconds: float) -> dict[str, Any]:
    """One row of :func:`k_coverage` for a fitted ``model`` on labels ``y``."""
    truth = int(np.unique(y).size)
    ks = model.n_clusters_summary_
    lo, hi = ks["interval"]
    conv = {r["quantity"]: r for r in model.convergence_}
    return {
        "source": source,
        "n": len(y),
        "true K": truth,
        "setting": setting,
        "K mode": ks["mode"],
        "K 95% interval": f"[{lo}, {hi}]",
        "covers": "yes" if lo <= truth <= hi else "no",
        "K point estimate": ks["point_estimate"],
        "R-hat K": round(float(conv["K"]["R-hat"]), 3),
        "ESS K": round(float(conv["K"]["ESS bulk"])),
        "sweeps": model.n_iter_,
        "seconds": round(seconds, 1),
    }


MIXING_SOURCES = ("gaussian-3", "bundled-28", "sessions-3x3", "hapmat", "borealtc")
"""Sources of :func:`mixing_rows` (issue 22: converged at the defaults on each)."""


def mixing_rows(
    sources: dict[str, tuple[np.ndarray, np.ndarray]], *, random_state: int = 0, **fit: Any
) -> list[dict[str, Any]]:
    """Return one row per source of a fit at the defaults (plus ``fit``): R-hat, bulk ESS, K, run length, stop reason."""
    from ..mixture import PitmanYorGMM

    rows = []
    for source, (X, y) in sources.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m = PitmanYorGMM(random_state=random_state, progress=False, **fit).fit(X)
        ks = m.n_clusters_summary_
        rows.append(
            {"source": source, "n": len(y), "true K": int(np.unique(y).size)}
            | {f"R-hat {r['quantity']}": round(float(r["R-hat"]), 3) for r in m.convergence_}
            | {
                "ESS K": round(float(m.convergence_[0]["ESS bulk"])),
                "K mode": ks["mode"],
                "K 95% interval": "[{}, {}]".format(*ks["interval"]),
                "sweeps": m.n_iter_,
                "stopped by": m.stopped_by_,
                "ms/sweep": round(1e3 * m.sweep_seconds_, 2),
                "seconds": round(m.fit_seconds_, 1),
            }
        )
    return rows


ELBOW_GRID = (30.0, 100.0, 300.0, 1000.0, 3000.0, 10000.0, None)
"""Values of ``coarsen`` of :func:`coarsening_curve` (None: the exact posterior)."""


def coarsening_curve(
    X: np.ndarray, grid: tuple = ELBOW_GRID, *, random_state: int = 0, **fit: Any
) -> list[dict[str, Any]]:
    """Return, per ``coarsen`` value, the posterior mode of K and the mean log density of the data under the point estimate.

    Miller & Dunson (2018) calibrate ``coarsen`` by the elbow of fit against K: the fit stops
    improving much once the components that matter are there.
    """
    from ..mixture import PitmanYorGMM

    rows = []
    for a in grid:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            model = PitmanYorGMM(coarsen=a, random_state=random_state, progress=False, **fit).fit(X)
        rows.append(
            {
                "coarsen": "none" if a is None else a,
                "K mode": model.n_clusters_summary_["mode"],
                "K 95% interval": "[{}, {}]".format(*model.n_clusters_summary_["interval"]),
                "K point estimate": model.n_clusters_,
                "mean log density": round(float(model.score_samples(X).mean()), 3),
            }
        )
    return rows


def _main(argv: list[str] | None = None) -> None:
    import argparse

    from ._cli import refuse_unknown

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short chains, fewer windows")
    parser.add_argument(
        "--overlap",
        action="store_true",
        help="print the Bhattacharyya distances of sessions-3x3's groups and stop",
    )
    parser.add_argument("--only", nargs="*", help="sources to run (default: all available)")
    parser.add_argument(
        "--elbow",
        action="store_true",
        help="print K and fit against coarsen per source (Miller & Dunson's elbow)",
    )
    parser.add_argument("--settings", nargs="*", help="settings to run (names of SETTINGS)")
    parser.add_argument(
        "--mixing",
        action="store_true",
        help="print R-hat, ESS and K at the estimator's defaults per source (default sources: MIXING_SOURCES)",
    )
    parser.add_argument(
        "--components", type=int, default=3, help="principal components of the vibration sources (default: 3)"
    )
    parser.add_argument("--near", type=float, default=None, help="near_pairs of the split-merge move")
    parser.add_argument("--max-seconds", type=float, default=300.0, help="wall-clock budget of n_iter='auto'")
    parser.add_argument("--n-iter", default="auto", type=lambda v: v if v == "auto" else int(v))
    parser.add_argument("--burn-in", default=250, type=int)
    parser.add_argument("--n-split-merge", default=5, type=int, help="split-merge moves per sweep")
    parser.add_argument(
        "--jobs", default=None, type=int, help="threads (default: one per chain up to the cores)"
    )
    args = parser.parse_args(argv)
    refuse_unknown(parser, "--only", args.only, SOURCE_NAMES)
    refuse_unknown(parser, "--settings", args.settings, SETTINGS)
    if args.components < 1:
        parser.error(
            f"--components: expected a positive number of principal components, got {args.components}"
        )
    if args.overlap:
        np.set_printoptions(precision=1, suppress=True, linewidth=150)
        print(session_overlap())
        return
    sources = k_sources(args.quick, args.components)
    if args.only or args.mixing:
        sources = {k: v for k, v in sources.items() if k in (args.only or MIXING_SOURCES)}
    for name in sorted(set(args.only or ()) - set(sources)):
        print(f"clustering_k: {name}: skipped, its data set is not found here", file=sys.stderr)
    if args.mixing:
        kw = {"near_pairs": args.near, "max_seconds": args.max_seconds, "n_jobs": args.jobs}
        for i, (name, data) in enumerate(sources.items()):
            rows = mixing_rows({name: data}, **kw, **({"n_iter": 300, "burn_in": 100} if args.quick else {}))
            if i == 0:
                print("| " + " | ".join(rows[0]) + " |\n|" + " --- |" * len(rows[0]))
            print("| " + " | ".join(str(v) for v in rows[0].values()) + " |", flush=True)
        return
    if args.elbow:
        for name, (X, y) in sources.items():
            for r in coarsening_curve(X, n_iter=args.n_iter, burn_in=args.burn_in):
                print(
                    f"| {name} | {np.unique(y).size} | " + " | ".join(str(v) for v in r.values()) + " |",
                    flush=True,
                )
        return
    settings = {k: v for k, v in SETTINGS.items() if not args.settings or k in args.settings}
    fit = {"n_iter": 300, "burn_in": 100} if args.quick else {"n_iter": args.n_iter, "burn_in": args.burn_in}
    fit |= {"n_split_merge": args.n_split_merge, "n_jobs": args.jobs}
    for i, (name, data) in enumerate(sources.items()):
        rows = k_coverage({name: data}, settings, **fit)
        if i == 0:
            print("| " + " | ".join(rows[0]) + " |")
            print("|" + " --- |" * len(rows[0]))
        for r in rows:
            print("| " + " | ".join(str(v) for v in r.values()) + " |", flush=True)


if __name__ == "__main__":
    _main()
