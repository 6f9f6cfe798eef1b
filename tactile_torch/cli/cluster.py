"""``tactile-torch cluster``: discover surfaces with a Bayesian mixture (:mod:`tactile_torch.clustering`)."""

from __future__ import annotations

import argparse

from ._options import (
    SEED,
    Number,
    UsageError,
    add_allow_pickle,
    add_data_options,
    announce_layout,
    data_name,
    read_data_arg,
    window_type,
)


def register(sub) -> None:
    """Add the ``cluster`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "cluster",
        help="discover surfaces with a Bayesian mixture (how many, and which window is which)",
        description="Fit tactile_torch.mixture.PitmanYorGMM to vibration recordings (windows -> 21 features -> "
        "the unsupervised transform -> principal components) or to a 'features' array (n, D); write the point "
        "estimate of the clustering (and the MAP sample, the posterior samples of K) to OUT/clustering.npz, a "
        "summary (posterior of K first) to OUT/summary.txt and the model to OUT/model.npz (for tactile-torch "
        "export). Recordings: the last third of each recording's windows are held out of the fit and set the "
        "novelty threshold (--calibrate, --false-alarm) that the exported graph, predict and stream --discover use.",
    )
    add_data_options(
        p,
        data_help="vibration recordings (.npz with 'signals', CSV logs, ROS 2 bags), or a .npz with "
        "'features' (n, D) and optionally 'labels' (n,)",
    )
    p.add_argument("--out", default="runs/cluster", help="output directory (default: runs/cluster)")
    p.add_argument(
        "--window",
        type=window_type(),
        default=800,
        help="recordings: window in samples, >= 16 (default: 800)",
    )
    p.add_argument(
        "--step", type=Number(int, low=1), default=None, help="recordings: window hop (default: the window)"
    )
    p.add_argument(
        "--components",
        type=Number(int, low=1),
        default=3,
        help="recordings: principal components that count K and cluster (default: 3)",
    )
    p.add_argument(
        "--novelty-components",
        type=Number(int, low=0),
        default=5,
        help="recordings: principal components of the novelty rule's density, computed side by side with "
        "--components in the exported graph (default: 5; 0: the same as --components)",
    )
    add_allow_pickle(p)
    p.add_argument(
        "--model",
        choices=("mfm", "pyp"),
        default="mfm",
        help="prior: 'mfm' mixture of finite mixtures, consistent for K (default); 'pyp' the study's Pitman-Yor",
    )
    p.add_argument(
        "--coarsen",
        type=Number(low=0, open_low=True),
        default=None,
        help="coarsened posterior: likelihood to the power a/(a+n) (--model mfm; default: off, see docs/mixture.md)",
    )
    p.add_argument(
        "--n-iter",
        type=Number(int, low=1, words=("auto",)),
        default="auto",
        help="Gibbs sweeps per chain, burn-in included, or 'auto': until R-hat < 1.01 and ESS of K >= 400 "
        "(default: auto)",
    )
    p.add_argument(
        "--max-iter",
        type=Number(int, low=1),
        default=40000,
        help="--n-iter auto: most sweeps per chain (default: 40000)",
    )
    p.add_argument(
        "--max-seconds",
        type=Number(low=0, open_low=True),
        default=300.0,
        help="--n-iter auto: wall-clock budget of the chains in seconds (default: 300)",
    )
    p.add_argument(
        "--burn-in",
        type=Number(int, low=0),
        default=250,
        help="sweeps discarded per chain, at least (default: 250)",
    )
    p.add_argument(
        "--chains",
        type=Number(int, low=1),
        default=4,
        help="independent chains, run in parallel (default: 4)",
    )
    p.add_argument(
        "--alpha",
        type=Number(low=0, open_low=True),
        default=None,
        help="fix the concentration (default: sampled)",
    )
    p.add_argument(
        "--discount",
        type=Number(low=0, high=1, open_high=True),
        default=None,
        help="fix the discount; 0 = Dirichlet process",
    )
    p.add_argument(
        "--init",
        type=Number(int, low=1, words=("kmeans", "one")),
        default="kmeans",
        help="'kmeans' (default), 'one', or a number of k-means clusters",
    )
    p.add_argument(
        "--calibrate",
        type=Number(low=0, high=1, open_high=True),
        metavar="SHARE",
        default=None,
        help="share of the rows held out of the fit to calibrate the novelty rule on: the last SHARE of each "
        "recording's windows (recordings: default a third), a random SHARE of a 'features' array (default: "
        "none); 0: no hold-out, the model's own rule",
    )
    p.add_argument(
        "--false-alarm",
        type=Number(low=0, high=1, open_low=True, open_high=True),
        metavar="RATE",
        default=0.02,
        help="novelty thresholds: at most RATE of the held-out windows' decisions are novel (default: 0.02)",
    )
    p.add_argument(
        "--sessions",
        choices=("auto", "model", "standardise", "none"),
        default="auto",
        help="how to use the recordings' sessions (days): 'model' fits a mixture in which each surface may move "
        "from session to session, so that K counts surfaces across them; 'standardise' standardises the "
        "components within each session (not exportable); 'none' ignores them; 'auto' (default): 'model' when "
        "some session holds recordings of several surfaces, else 'none'",
    )
    p.add_argument("--seed", type=SEED, default=0, help="random seed (default: 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=run_cluster)


def run_cluster(args: argparse.Namespace) -> int:
    """Fit the mixture, write and print its results; return the exit status."""
    from ..clustering import CLUSTERED_KINDS, clustering_summary, fit_clustering, write_clustering

    if args.model == "mfm" and (args.alpha is not None or args.discount is not None):
        raise UsageError(
            "--alpha and --discount apply to --model pyp (the Pitman-Yor mixture), got --model mfm"
        )
    if args.model == "pyp" and args.coarsen is not None:
        raise UsageError("--coarsen applies to --model mfm, got --model pyp")
    announce_layout(args, print)  # before any file is read
    data = read_data_arg(args)
    if data.kind not in CLUSTERED_KINDS:
        raise UsageError(
            f"{data_name(args.data)}: --data must hold vibration recordings ('signals') or a 'features' "
            f"array (n, D) to cluster, got {data.kind} data"
        )
    sessions_from = None
    if data.kind == "vibration" and data.session is not None:
        from ._output import session_origin

        sessions_from = session_origin(args)
    clustering = fit_clustering(
        data,
        window=args.window,
        step=args.step,
        components=args.components,
        novelty_components=args.novelty_components or None,
        sensor_range_g=getattr(args, "data_sensor_range", None),
        name=data_name(args.data),
        log=print,
        calibrate=args.calibrate,
        false_alarm=args.false_alarm,
        sessions=args.sessions,
        sessions_from=sessions_from,
        model=args.model,
        coarsen=args.coarsen,
        alpha=args.alpha,
        discount=args.discount,
        n_iter=args.n_iter,
        max_iter=args.max_iter,
        max_seconds=args.max_seconds,
        burn_in=args.burn_in,
        n_chains=args.chains,
        init=args.init,
        random_state=args.seed,
        progress=not args.quiet,
    )
    paths = write_clustering(args.out, clustering)
    print(clustering_summary(clustering))
    note = {
        "standardised": ", per-session standardised: not exportable",
        "model": ", a window of a new session classified with its session's effect integrated out",
    }.get(clustering.session_mode, "")
    print(
        f"written: {paths['results']}, {paths['summary']}, {paths['model']} (tactile-torch export: "
        f"the point estimate's {clustering.mixture.n_clusters_} components{note})"
    )
    return 0
