"""Is ``tradeoff --quick``'s SVM grid a fair candidate? The quick grid against the full one, held-out sessions.

Every session is held out in turn (leave-one-session-out); inside each training part the SVC (one-vs-one
RBF, on the 21 standardised window features) is tuned on 3 inner folds grouped by session, as the
trade-off tunes its candidates (:class:`tactile_torch.model_selection.Tuning`), over each grid below; the printed
accuracy is the mean over the held-out sessions. The grids: the catalogue's quick and full ones
(:data:`tactile_torch.catalogue.SVM_QUICK_C_GRID`, ...), and the issue's reference (C = 2^0 .. 2^10,
gamma 0.003 .. 0.3 in 7 log steps). A quick grid that loses more than about 3 points against the full
one is not a fair candidate (issue 34, point 8); docs/tradeoff.md has the numbers.

Examples
--------
PYTHONPATH=. python train/quick_grid.py                               # generator, 5 surfaces x 5 sessions
PYTHONPATH=. python train/quick_grid.py --borealtc DIR --window 100   # BorealTC IMU (real), runs as sessions
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def grids(n_features: int) -> dict[str, dict]:
    """The grids compared, in the classifier's parameter names (gamma on standardised features)."""
    from tactile_torch import catalogue

    return {
        "quick (catalogue)": catalogue.param_grid("svc", n_features, quick=True),
        "full (catalogue)": catalogue.param_grid("svc", n_features, quick=False),
        "reference (issue 34)": {
            "C": [2.0**k for k in range(11)],
            "gamma": list(np.geomspace(0.003, 0.3, 7)),
        },
    }


def main(argv: list[str] | None = None) -> int:
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler

    from tactile_torch import catalogue
    from tactile_torch.features.transformers import WindowFeatureTransformer
    from tactile_torch.model_selection import Tuning, cross_validate
    from tactile_torch.tradeoff.inputs import vibration_samples

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--borealtc", help="the borealtc_imu data set's directory (runs as sessions)")
    parser.add_argument("--window", type=int, default=800, help="window in samples (default: 800)")
    parser.add_argument(
        "--max-per-class", type=int, default=60, help="windows per class (default: 60, --quick's)"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jitter", type=float, default=0.15, help="generator: session jitter (default 0.15)")
    args = parser.parse_args(argv)
    if args.borealtc:
        from tactile_torch.data import load_borealtc_imu

        rec, what = load_borealtc_imu(args.borealtc), "BorealTC IMU (real, 5 terrains, runs as sessions)"
        rec.session = np.arange(len(rec.signals)).astype(str) if rec.session is None else rec.session
    else:
        from tactile_torch.data import make_vibration_recordings

        rec = make_vibration_recordings(
            5, duration_s=24, n_sessions=5, session_jitter=args.jitter, noise_lsb=3, random_state=args.seed
        )
        rec.session = np.array(
            [str(s).split("/")[1] for s in rec.session]
        )  # "glass/2" -> day 2: all surfaces
        what = f"generator, 5 surfaces x 5 sessions x 24 s, session jitter {args.jitter:g}, noise 3 LSB, seed {args.seed}"
    sessions = len(np.unique(rec.session))
    s = vibration_samples(
        rec, args.window, n_folds=sessions, max_per_class=args.max_per_class, random_state=args.seed
    )
    print(f"{what}: W = {args.window}, {s.split}")
    for name, grid in grids(21).items():
        model = Pipeline(
            [
                ("features", WindowFeatureTransformer()),
                ("scale", StandardScaler()),
                ("classifier", catalogue.make_classifier("svc", random_state=args.seed)),
            ]
        )
        tuning = Tuning(catalogue.prefixed(grid, "classifier__"), 3, "kfold")
        start = time.perf_counter()
        res = cross_validate(
            {name: model}, s.X, s.y, s.folds, groups=s.groups, tuning={name: tuning}, random_state=args.seed
        )[name]
        seconds = time.perf_counter() - start
        tested = res.fold >= 0
        per = [
            np.mean(res.predictions[s.units == u] == s.y[s.units == u]) for u in np.unique(s.units[tested])
        ]
        chosen = ", ".join(
            f"C={p['classifier__C']:g} g={p['classifier__gamma'] * 21:.2g}/21" for p in res.params[:3]
        )
        print(
            f"| {name} | {tuning.size} | {np.mean(per):.3f} | {min(per):.3f}-{max(per):.3f} | "
            f"{seconds:.0f} s | {chosen} ... |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
