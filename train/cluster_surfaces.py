"""Reproduce the unsupervised study: how many surfaces, with the Pitman-Yor mixture (method 2).

Runs, at the study's scale (10,000 sweeps by default), on the features of ``--data``:

- the comparison with k-means / EM given K, EM + BIC and the variational DP mixture (Table 2),
- the posterior over K (mode, median, 95 % interval), the point estimate of the clustering (minimum
  expected Variation of Information) and the MAP sample, convergence across chains (R-hat, ESS),
- the learning curve (1 ... 50 windows per surface) for the Dirichlet-process and Pitman-Yor priors,

and writes a report (``report.md``, ``report.json``, figures) under ``--out``. The logic lives in
:mod:`tactile_torch.studies.clustering`; this program only chooses the data and the sizes.

Examples
--------
python train/cluster_surfaces.py --out runs/clustering                  # synthetic clusters, full size
python train/cluster_surfaces.py --out runs/clustering-smoke --quick    # a minute
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from tactile_torch.robot.files.formats import read_features
from tactile_torch.studies.clustering_experiments import (
    cluster_and_compare,
    learning_curve,
    synthetic_clusters,
)
from tactile_torch.studies.report import Report


def load_features(name: str, seed: int, quick: bool) -> tuple[np.ndarray, np.ndarray, str]:
    """Return (features (n, D), labels (n,), description) of a data set."""
    if name == "synthetic":
        n_clusters, per = (8, 20) if quick else (28, 50)
        X, y = synthetic_clusters(n_clusters, per, seed=seed)
        return X, y, f"{n_clusters} seeded Gaussian clusters x {per} points in D = 3"
    data = read_features(name, require_labels=True)  # docs/formats.md: one line naming a bad field
    return data.features, data.labels, f"features and labels of {name}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", default="runs/clustering", help="report directory")
    parser.add_argument(
        "--data", default="synthetic", help="'synthetic' or an .npz with 'features' (n, D) and 'labels' (n,)"
    )
    parser.add_argument(
        "--n-iter", type=int, default=10_000, help="Gibbs sweeps (default 10,000, as the study)"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="small data and chains, for a smoke run")
    args = parser.parse_args(argv)
    n_iter = 300 if args.quick else args.n_iter
    burn_in = n_iter // 5
    X, y, what = load_features(args.data, args.seed, args.quick)
    report = Report(args.out, title="Unsupervised surface discovery (Pitman-Yor mixture)")
    command = "python train/cluster_surfaces.py " + " ".join(argv if argv is not None else sys.argv[1:])
    report.preamble.append(f"Written by `{command}`. Data: {what}; {n_iter} sweeps ({burn_in} burn-in).")

    section = report.section("PYP mixture vs baselines")
    section.command(command)
    out = cluster_and_compare(X, y, n_iter=n_iter, burn_in=burn_in, random_state=args.seed)
    section.table(out["rows"], caption="Table 2: clustering accuracy and K")
    section.text("```\n" + out["model"].summary() + "\n```")

    section = report.section("Learning curve: DP vs PYP")
    section.command(command)
    per_class = [1, 2, 5, 10, 20] if args.quick else [1, 2, 5, 10, 20, 30, 40, 50]
    counts = np.bincount(np.unique(y, return_inverse=True)[1])
    per_class = [m for m in per_class if m <= counts.min()]
    rows = learning_curve(
        X, y, per_class, n_iter=max(200, n_iter // 5), burn_in=max(50, burn_in // 5), random_state=args.seed
    )
    section.table(rows, caption="K and pairwise accuracy with m windows per surface")
    path = report.write()
    print(f"report written to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
