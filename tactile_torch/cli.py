"""The ``tactile-torch`` command line.

Every subcommand of DESIGN.md is listed; the handlers import their modules lazily so that
``tactile-torch predict`` can run on a robot with onnxruntime and no torch.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

NOT_BUILT_EXIT = 2

# Subcommands of DESIGN.md that are listed but not built yet: name -> (help, where it will come from).
PLANNED: dict[str, tuple[str, str]] = {
    "export": ("export a trained pipeline to one ONNX file", "issue 7"),
    "predict": ("classify a data set with an exported ONNX pipeline", "issue 7"),
    "stream": ("classify a live serial sensor stream", "tactile_torch.stream"),
    "simulate-sensor": ("emulate a serial sensor from recorded or synthetic data", "tactile_torch.stream"),
}


def _not_built(name: str, issue: str) -> Callable[[argparse.Namespace], int]:
    def handler(args: argparse.Namespace) -> int:
        print(
            f"tactile-torch {name}: not built yet ({issue}); nothing was done.",
            file=sys.stderr,
        )
        return NOT_BUILT_EXIT

    return handler


def _report(args: argparse.Namespace) -> int:
    from .studies import run_report

    only = [s for s in args.only.split(",") if s] if args.only else None
    path = run_report(args.out, random_state=args.seed, quick=args.quick, only=only)
    print(f"report written to {path}")
    return 0


def _train(args: argparse.Namespace) -> int:
    from .training import load_features, save_model, train_classifier

    gamma = args.gamma if args.gamma == "scale" else float(args.gamma)
    features = load_features(
        args.data, window=args.window, step=args.step, fuse=not args.no_fuse, allow_pickle=args.allow_pickle
    )
    print(
        f"{args.data}: {features.X.shape[0]} samples x {features.X.shape[1]} features "
        f"({features.source['kind']}), {len(features.class_names)} classes"
    )
    model = train_classifier(
        features,
        args.method,
        C=args.C,
        gamma=gamma,
        kernel=args.kernel,
        test_size=args.test_size,
        random_state=args.seed,
    )
    rep = model.report
    print(
        f"{args.method}: trained on {len(model.train_index)}, tested on {len(model.test_index)} held-out samples"
    )
    print(f"{'class':<24} {'samples':>7} {'accuracy':>9} {'type I':>8} {'type II':>8}")
    for row in rep.rows():
        print(
            f"{row['class']:<24} {row['samples']:>7} {row['accuracy']:>9.4f} "
            f"{row['type I error']:>8.4f} {row['type II error']:>8.4f}"
        )
    print(f"overall accuracy {rep.overall_accuracy:.4f}")
    if args.out:
        print(f"model written to {save_model(args.out, model, features)}")
    return 0


def _bench(args: argparse.Namespace) -> int:
    runner = Path(__file__).resolve().parents[1] / "bench" / "run.py"
    if not runner.exists():
        print(
            "tactile-torch bench: the benchmarks live in the source checkout (bench/run.py), "
            f"which was not found at {runner.parent}",
            file=sys.stderr,
        )
        return NOT_BUILT_EXIT
    cmd = [
        sys.executable,
        str(runner),
        *(["--quick"] if args.quick else []),
        *(["--only", args.only] if args.only else []),
    ]
    return subprocess.call(cmd)


def _cluster(args: argparse.Namespace) -> int:
    import numpy as np

    from .metrics import pairwise_accuracy
    from .mixture import PitmanYorGMM

    with np.load(args.data, allow_pickle=False) as data:
        if "features" not in data:
            print(
                f"tactile-torch cluster: {args.data} must hold an array 'features' of shape (n, D) "
                f"(and optionally 'labels' (n,)), found {sorted(data.files)}",
                file=sys.stderr,
            )
            return 2
        X = data["features"]
        truth = data["labels"] if "labels" in data else None
    init = int(args.init) if args.init.isdigit() else args.init
    model = PitmanYorGMM(
        alpha=args.alpha,
        discount=args.discount,
        n_iter=args.n_iter,
        burn_in=args.burn_in,
        init=init,
        random_state=args.seed,
        progress=not args.quiet,
    ).fit(X)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    np.savez(
        out / "clustering.npz",
        labels=model.labels_,
        means=model.means_,
        covariances=model.covariances_,
        precisions_cholesky=model.precisions_cholesky_,
        weights=model.weights_,
        n_clusters_samples=model.n_clusters_samples_,
        alpha_samples=model.alpha_samples_,
        discount_samples=model.discount_samples_,
    )
    summary = model.summary()
    if truth is not None:
        summary += f"\npairwise accuracy of the MAP labels: {pairwise_accuracy(truth, model.labels_):.4f}"
    (out / "summary.txt").write_text(summary + "\n")
    print(summary)
    print(f"written: {out / 'clustering.npz'}, {out / 'summary.txt'}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every subcommand."""
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="tactile-torch",
        description="Recognise surfaces from tactile images and vibration; train, cluster, export, run.",
    )
    parser.add_argument("--version", action="version", version=f"tactile-torch {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("report", help="run every pipeline on the bundled data and write a report (make run)")
    p.add_argument("--out", default="runs/latest", help="output directory (default: runs/latest)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the whole run (default: 0)")
    p.add_argument("--quick", action="store_true", help="smaller data and fewer iterations, for a smoke test")
    p.add_argument("--only", default="", help="comma-separated study names to run (default: all)")
    p.set_defaults(handler=_report)

    p = sub.add_parser("bench", help="run the benchmarks and write bench/results (make bench)")
    p.add_argument("--quick", action="store_true", help="small sizes, for a smoke test")
    p.add_argument("--only", default="", help="comma-separated benchmark names (default: all)")
    p.set_defaults(handler=_bench)

    p = sub.add_parser(
        "train", help="train a classifier on an image, vibration or feature .npz; print a class report"
    )
    p.add_argument(
        "--data",
        required=True,
        help="a .npz of DESIGN.md's formats (frames, signals) or with a features matrix",
    )
    p.add_argument(
        "--method",
        default="hmsvm",
        choices=["hmsvm", "svm", "lda", "knn"],
        help="classifier (default: hmsvm)",
    )
    p.add_argument("--out", default="", help="write the trained model here (torch.save), e.g. model.pt")
    p.add_argument("--C", type=float, default=16.0, help="SVM penalty (default: 16)")
    p.add_argument("--gamma", default="scale", help="RBF width, a float or 'scale' (default)")
    p.add_argument("--kernel", default="rbf", choices=["rbf", "linear"], help="SVM kernel (default: rbf)")
    p.add_argument("--window", type=int, default=800, help="vibration window in samples (default: 800)")
    p.add_argument("--step", type=int, default=None, help="vibration window hop (default: the window)")
    p.add_argument("--no-fuse", action="store_true", help="image: per-frame features instead of fused ones")
    p.add_argument(
        "--test-size", type=float, default=0.25, help="held-out share for the report (default: 0.25)"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument(
        "--allow-pickle", action="store_true", help="allow object arrays in a trusted vibration .npz"
    )
    p.set_defaults(handler=_train)

    p = sub.add_parser(
        "cluster",
        help="discover surfaces with the Pitman-Yor mixture (how many, and which window is which)",
        description="Fit tactile_torch.mixture.PitmanYorGMM to the 'features' array (n, D) of an .npz file; "
        "write the MAP clustering and the posterior samples to OUT/clustering.npz and a summary to OUT/summary.txt.",
    )
    p.add_argument("--data", required=True, help=".npz with 'features' (n, D) and optionally 'labels' (n,)")
    p.add_argument("--out", default="runs/cluster", help="output directory (default: runs/cluster)")
    p.add_argument("--n-iter", type=int, default=2000, help="Gibbs sweeps, burn-in included (default: 2000)")
    p.add_argument("--burn-in", type=int, default=500, help="sweeps discarded (default: 500)")
    p.add_argument("--alpha", type=float, default=None, help="fix the concentration (default: sampled)")
    p.add_argument("--discount", type=float, default=None, help="fix the discount; 0 = Dirichlet process")
    p.add_argument(
        "--init", default="kmeans", help="'kmeans' (default), 'one', or a number of k-means clusters"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cluster)

    for name, (help_text, issue) in PLANNED.items():
        p = sub.add_parser(name, help=f"{help_text} [not built yet]")
        p.set_defaults(handler=_not_built(name, issue))
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    return int(args.handler(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
