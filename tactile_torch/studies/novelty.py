"""New surfaces: which novelty rule finds withheld surfaces at a set false-alarm rate, on three data sources.

Every recording is cut into windows in time order and split per recording: the first 40 % are the
training period, the next 20 % the calibration windows, the last 40 % the test windows. Some
surfaces are withheld: none of their windows is used for training or calibration. The unsupervised
transform (21 features -> ``n_components`` principal components, 3 by default) and :class:`~tactile_torch.mixture.PitmanYorGMM` (its default
model, the mixture of finite mixtures) are fitted on the known surfaces' training windows only.

Rules compared (:data:`RULES`), each turned into a decision after ``N`` consecutive windows of one
recording:

- the shipped rule (:data:`SHIPPED`): minus the log density of the window under the point
  estimate's mixture (:meth:`PitmanYorGMM.novelty_score`), averaged over N windows, above the
  ``1 - false_alarm`` quantile of the same on the calibration windows
  (:meth:`PitmanYorGMM.calibrate_novelty`, :meth:`PitmanYorGMM.novel_after`);
- ``new component``: the model's own rule, a window is novel when a new component is more probable
  than every known cluster (a fixed threshold, not calibrated); after N windows: N novel in a row;
- ``new-component log-odds, calibrated``: the log-odds of a new component against the best known
  cluster, averaged over N windows and calibrated like the shipped rule;
- ``log density, calibrated on training windows``: the shipped score, the quantile taken on the
  training windows (in-sample);
- ``log density, oracle threshold``: the shipped score, the quantile taken on the known surfaces'
  *test* windows: not a usable rule, it measures how well the score separates new from known when
  the threshold is right (the gap to the shipped rule is the cost of calibrating on other windows);
- ``log density, N in a row``: the shipped score, N windows in a row above a threshold calibrated so
  that the min over N calibration windows is above it ``false_alarm`` of the time.

Sources: ``bundled`` (28 synthetic stylus surfaces, 60 s, W = 800; surfaces 3, 10, 17, 24 withheld,
then 0, 7, 14, 21), ``bundled-new-session`` (the same in two sessions: the test windows are the
second session's), ``hapmat`` and ``borealtc`` (the real IMU sets when present, 2 s windows 1 s apart; each
class withheld in turn). ``python -m tactile_torch.studies.novelty`` prints recall and false alarms
per window and after N windows for every rule.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ..mixture import window_means

SHIPPED = "calibrated mean log density (PitmanYorGMM.calibrate_novelty, novel_after)"
"""The rule the estimator, the exported graph and ``stream --discover`` use."""

PER_COMPONENT = "calibrated mean log density, per component"
"""The shipped score with one threshold per component (of the run's last window), measured against the global one."""

ROBUST = "robust model refit to the test windows: a component of under 5 % training windows"
"""The robust model's own answer (``novelty_rows(agreement=True)``): is the window in a new component once refitted?"""

RULES = (
    SHIPPED,
    PER_COMPONENT,
    "new component",
    "new-component log-odds, calibrated",
    "log density, calibrated on training windows",
    "log density, oracle threshold",
    "log density, N in a row",
)
"""Names of the rules compared by :func:`novelty_rows`."""

SPLIT = (0.4, 0.2)
"""Share of each recording's windows (in time order) for training and for calibration; the rest is test."""


def time_split(recording: np.ndarray, position: np.ndarray, split: tuple[float, float] = SPLIT) -> np.ndarray:
    """Return 0 (train), 1 (calibration) or 2 (test) per window: each recording cut in time order, shape (n,).

    :func:`tactile_torch.model_selection.time_holdout` with the shares ``split`` (rounded to the nearest window).
    """
    from ..model_selection import time_holdout

    return time_holdout(recording, position, split)


def window_runs(score: np.ndarray, recording: np.ndarray, position: np.ndarray, n: int, how: str) -> tuple:
    """Return (aggregate (m,), index of each run's last window (m,)) over every run of ``n`` consecutive windows of one recording.

    ``how``: ``"mean"``, ``"max"`` or ``"min"`` of the ``n`` scores.
    """
    agg, last = [], []
    for r in np.unique(recording):
        idx = np.flatnonzero(recording == r)
        idx = idx[np.argsort(position[idx], kind="stable")]
        if idx.size < n:
            continue
        win = np.lib.stride_tricks.sliding_window_view(score[idx], n)
        agg.append({"mean": np.mean, "max": np.max, "min": np.min}[how](win, axis=1))
        last.append(idx[n - 1 :])
    if not agg:
        return np.zeros(0), np.zeros(0, dtype=int)
    return np.concatenate(agg), np.concatenate(last)


SOURCES = ("bundled", "bundled-new-session", "hapmat", "borealtc")
"""The sources of :func:`source_windows` (the real sets' only where their data are present)."""


def source_windows(name: str, seed: int = 0) -> dict[str, Any]:
    """Return the 21 window features (torch, float64), labels, recording ids, positions and sessions of a source.

    ``session`` is the recording's session (0 for a source of one session).
    """
    import torch

    from ..signal import window_features

    session = None
    if name in ("bundled", "bundled-new-session"):
        from ..data import make_vibration_recordings

        n_sessions = 2 if name == "bundled-new-session" else 1
        rec = make_vibration_recordings(28, duration_s=60, n_sessions=n_sessions, random_state=seed)
        ds = rec.windows(800)
        session = np.array([int(str(s).rsplit("/", 1)[1]) for s in rec.session])[ds.recording.numpy()]
    else:
        from ..data.recordings import load_borealtc_imu, load_hapmat_imu5

        rec = {"hapmat": load_hapmat_imu5, "borealtc": load_borealtc_imu}[name]()
        ds = rec.windows(int(2 * rec.rate_hz), int(rec.rate_hz))  # 2 s windows, 1 s apart
    recording = ds.recording.numpy()
    return {
        "features": window_features(ds.windows.to(torch.float64)),
        "labels": ds.labels.numpy(),
        "recording": recording,
        "position": ds.position.numpy(),
        "session": np.zeros(recording.shape, dtype=int) if session is None else session,
    }


def new_session_split(
    recording: np.ndarray, position: np.ndarray, session: np.ndarray, calibrate: float
) -> np.ndarray:
    """Return 0 (train), 1 (calibration) or 2 (test) per window: session 0 split in time order, later sessions test."""
    part = time_split(recording, position, (1.0 - calibrate, calibrate))
    part[session > 0] = 2
    return part


def withheld_sets(name: str, labels: np.ndarray) -> list[tuple[int, ...]]:
    """Return the withheld surfaces of each experiment on a source."""
    if name.startswith("bundled"):
        return [(3, 10, 17, 24), (0, 7, 14, 21)]
    return [(int(c),) for c in np.unique(labels)]


def scores(model, X: np.ndarray) -> dict[str, np.ndarray]:
    """Return per-window novelty scores (larger = more novel) of every rule: name -> (n,)."""
    known, new = model._point_scores(X)
    best = known.max(axis=1)
    dens = -model.score_samples(X)
    return {
        "new component": new - best,
        "new-component log-odds, calibrated": new - best,
        "log density, calibrated on training windows": dens,
        "log density, oracle threshold": dens,
        "log density, N in a row": dens,
    }


def per_component_decisions(
    score: np.ndarray,
    component: np.ndarray,
    recording: np.ndarray,
    position: np.ndarray,
    calibration: np.ndarray,
    test: np.ndarray,
    n: int,
    false_alarm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (mean score of each test run (m,), its threshold (m,), its last window (m,)): one threshold per component of the run's last window.

    A component with fewer than ``1 / false_alarm`` calibration runs (at most ``false_alarm`` of
    them above its quantile needs that many) takes the global threshold.
    """
    agg_c, last_c = window_runs(np.where(calibration, score, np.nan), recording, position, n, "mean")
    keep = np.isfinite(agg_c)
    agg_c, last_c = agg_c[keep], last_c[keep]
    agg, last = window_runs(np.where(test, score, np.nan), recording, position, n, "mean")
    keep = np.isfinite(agg)
    agg, last = agg[keep], last[keep]
    if agg_c.size == 0:  # no run of n calibration windows: no decision (as in evaluate)
        return agg[:0], agg[:0], last[:0]
    glob = np.quantile(agg_c, 1.0 - false_alarm, method="higher")
    threshold = np.full(agg.shape, glob)
    for k in np.unique(component):
        mine = agg_c[component[last_c] == k]
        if mine.size >= 1.0 / false_alarm:
            threshold[component[last] == k] = np.quantile(mine, 1.0 - false_alarm, method="higher")
    return agg, threshold, last


def evaluate(
    score: np.ndarray,
    rule: str,
    new: np.ndarray,
    recording: np.ndarray,
    position: np.ndarray,
    calibration: np.ndarray,
    test: np.ndarray,
    train: np.ndarray,
    n: int,
    false_alarm: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (decisions on the test runs (m,), whether each run is of a withheld surface (m,))."""
    # N in a row above a threshold <=> the minimum of the N scores above it
    how = "min" if rule in ("new component", "log density, N in a row") else "mean"
    if rule.endswith("on training windows"):
        calibration = train
    elif rule.endswith("oracle threshold"):  # the known surfaces' test windows: the best a threshold can do
        calibration = test & ~new
    if rule == "new component":  # the model's own threshold (0), not calibrated
        score, threshold = (score > 0).astype(float), 0.5
    else:
        agg_c, _ = window_runs(np.where(calibration, score, np.nan), recording, position, n, how)
        agg_c = agg_c[np.isfinite(agg_c)]
        if agg_c.size == 0:  # no run of n calibration windows
            return np.zeros(0, dtype=bool), np.zeros(0, dtype=bool)
        # the estimator's calibration (PitmanYorGMM.calibrate_novelty): at most false_alarm above
        threshold = np.quantile(agg_c, 1.0 - false_alarm, method="higher")
    agg, last = window_runs(np.where(test, score, np.nan), recording, position, n, how)
    keep = np.isfinite(agg)
    return agg[keep] > threshold, new[last[keep]]


def novelty_rows(
    name: str,
    *,
    windows: tuple[int, ...] = (1, 3, 5, 10),
    false_alarm: float = 0.02,
    seed: int = 0,
    n_components: int = 3,
    split: tuple[float, float] = SPLIT,
    agreement: bool = False,
    **fit: Any,
) -> list[dict[str, Any]]:
    """Return one row per (rule, N): recall and false alarms pooled over the source's withheld sets.

    ``split``: shares of each recording's windows for training and calibration (the rest is test).
    Source ``bundled-new-session``: the bundled surfaces recorded in two sessions; session 0 is
    split into training and calibration windows (``split``'s ratio), every window of session 1 is
    a test window (known surfaces in a session the model has not seen).
    ``agreement``: also refit the mixture to the training and test windows together (what the robot
    would fit after meeting the withheld surfaces) and add the row :data:`ROBUST`: a test window is
    new when its component of the refit holds under 5 % training windows; its decisions column
    gives the share of test windows on which it agrees with the shipped rule (N = 1).
    ``fit``: keyword arguments of :class:`~tactile_torch.mixture.PitmanYorGMM` (``n_iter``, ...).
    """
    from ..mixture import PitmanYorGMM
    from ..signal import fit_clustering_transform

    data = source_windows(name, seed)
    y, rec, pos = data["labels"], data["recording"], data["position"]
    if name == "bundled-new-session":
        part = new_session_split(rec, pos, data["session"], split[1] / (split[0] + split[1]))
    else:
        part = time_split(rec, pos, split)
    pooled: dict[tuple[str, int], list] = {}
    for withheld in withheld_sets(name, y):
        new = np.isin(y, withheld)
        train = (part == 0) & ~new
        calibration = (part == 1) & ~new
        test = part == 2
        _, X = fit_clustering_transform(data["features"], n_components, fit_rows=train)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            model = PitmanYorGMM(random_state=seed, progress=False, **fit).fit(X[train])
        # the shipped rule, through the estimator (rows are in time order within each recording)
        model.calibrate_novelty(
            X[calibration], false_alarm=false_alarm, max_windows=max(windows), groups=rec[calibration]
        )
        for n in windows:
            decided = model.novel_after(X[test], n, groups=rec[test])
            keep = np.isfinite(window_means(np.zeros(int(test.sum())), n, rec[test]))  # runs of n
            pooled.setdefault((SHIPPED, n), []).append((decided[keep], new[test][keep]))
        if agreement:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                refit = PitmanYorGMM(random_state=seed, progress=False, **fit).fit(X[train | test])
            labels, in_train = refit.labels_, train[train | test]
            share = np.bincount(labels, weights=in_train) / np.bincount(labels)
            robust = (share < 0.05)[labels][~in_train]  # the test windows, in order
            shipped = model.novel_after(X[test], 1, groups=rec[test])
            pooled.setdefault((ROBUST, 1), []).append((robust, new[test], robust == shipped))
        score = model.novelty_score(X)
        component = np.argmax(model._point_scores(X)[0], axis=1)  # most likely known component
        for n in windows:
            agg, threshold, last = per_component_decisions(
                score, component, rec, pos, calibration, test, n, false_alarm
            )
            pooled.setdefault((PER_COMPONENT, n), []).append((agg > threshold, new[last]))
        for rule, score in scores(model, X).items():
            for n in windows:
                decided, is_new = evaluate(
                    score, rule, new, rec, pos, calibration, test, train, n, false_alarm
                )
                pooled.setdefault((rule, n), []).append((decided, is_new))
    rows = []
    for (rule, n), parts in pooled.items():
        decided = np.concatenate([p[0] for p in parts])
        is_new = np.concatenate([p[1] for p in parts])
        if not is_new.any() or is_new.all():
            continue
        agree = (
            f"; agrees with the shipped rule on {np.concatenate([p[2] for p in parts]).mean():.3f}"
            if rule == ROBUST
            else ""
        )
        rows.append(
            {
                "source": name,
                "rule": rule,
                "N": n,
                "recall": round(float(decided[is_new].mean()), 3),
                "false alarms": round(float(decided[~is_new].mean()), 4),
                "decisions (new / known)": f"{int(is_new.sum())} / {int((~is_new).sum())}{agree}",
            }
        )
    return rows


def _main(argv: list[str] | None = None) -> None:
    import argparse

    from ._cli import refuse_unknown

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only", nargs="*", default=["bundled", "hapmat", "borealtc"], help="also: bundled-new-session"
    )
    parser.add_argument(
        "--split",
        nargs=2,
        type=float,
        default=list(SPLIT),
        help="shares of each recording for training and calibration (default: 0.4 0.2; "
        "0.48 0.12 is tactile-torch cluster's 80/20 hold-out)",
    )
    parser.add_argument("--windows", nargs="*", type=int, default=[1, 3, 5, 10])
    parser.add_argument("--false-alarm", type=float, default=0.02)
    parser.add_argument("--n-iter", type=int, default=1000)
    parser.add_argument("--burn-in", type=int, default=250)
    parser.add_argument("--chains", type=int, default=2)
    parser.add_argument("--components", type=int, default=3, help="principal components of the features")
    parser.add_argument(
        "--cluster-features",
        type=int,
        default=None,
        help="count and cluster on the first K of the components, score novelty on all of them "
        "(PitmanYorGMM's cluster_features; tactile-torch cluster's default: --components 5 --cluster-features 3)",
    )
    parser.add_argument(
        "--rules", nargs="*", default=[*RULES, ROBUST], help="rules to report (names of RULES, ROBUST)"
    )
    parser.add_argument(
        "--agreement", action="store_true", help="also refit to the test windows: the robust model's answer"
    )
    args = parser.parse_args(argv)
    if args.cluster_features is not None and not 1 <= args.cluster_features < args.components:
        parser.error(f"--cluster-features must be in 1 .. {args.components - 1}, got {args.cluster_features}")
    refuse_unknown(parser, "--only", args.only, SOURCES)
    refuse_unknown(parser, "--rules", args.rules, (*RULES, ROBUST))
    first = True
    for name in args.only:
        rows = novelty_rows(
            name,
            windows=tuple(args.windows),
            false_alarm=args.false_alarm,
            n_iter=args.n_iter,
            burn_in=args.burn_in,
            n_chains=args.chains,
            n_components=args.components,
            split=tuple(args.split),
            agreement=args.agreement,
            **({"cluster_features": args.cluster_features} if args.cluster_features else {}),
        )
        if first:
            print("| " + " | ".join(rows[0]) + " |")
            print("|" + " --- |" * len(rows[0]))
            first = False
        for r in rows:
            if r["rule"] not in args.rules:
                continue
            print("| " + " | ".join(str(v) for v in r.values()) + " |", flush=True)


if __name__ == "__main__":
    _main()
