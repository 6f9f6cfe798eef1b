"""``tactile-torch tradeoff``: speed against accuracy, the candidates evaluated on the user's data and the
simplest adequate one recommended (:mod:`tactile_torch.tradeoff`, :mod:`tactile_torch.tradeoff.job`).

The study's options default to ``None`` here, "not given": their defaults are those of
:class:`tactile_torch.tradeoff.job.TradeoffOptions` (which the library reads too), and the reproduce
line repeats the options whose values differ from them. The parser does not import the library (it
needs torch): ``predict`` and ``stream`` build the same parser on the robot.
"""

from __future__ import annotations

import argparse
import sys

from ._codes import ARGUMENT_FLAGS, INTERNAL_ERROR_EXIT, NO_RECOMMENDATION_EXIT, NOT_EXPORTED_EXIT
from ._codes import with_flags as _with_flags
from ._options import (
    SEED,
    Number,
    add_allow_pickle,
    add_data_options,
    announce_layout,
    data_name,
    data_option_words,
    data_options,
    window_list,
    window_type,
)

REPRODUCED = (
    ("n_folds", "folds"),
    ("window", "window"),
    ("windows", "windows"),
    ("frame_rate_hz", "frame_rate"),
    ("threshold", "threshold"),
    ("erosion", "erosion"),
    ("contact", "contact"),
    ("max_per_class", "max_per_class"),
    ("classifiers", "classifiers"),
    ("features", "features"),
    ("random_state", "seed"),
    ("target", "target"),
    ("deploy", "deploy"),
)
"""The options the reproduce line repeats when they are not at their defaults: (option of
:class:`~tactile_torch.tradeoff.job.TradeoffOptions`, attribute of the parsed arguments), in the
line's order."""


def _classifier_names() -> list[str]:
    """The ``--classifiers`` help's list: the catalogue's classical classifiers, by display name
    (:mod:`tactile_torch.catalogue` imports no torch, so the robot's parser builds it too)."""
    from ..catalogue import CLASSIFIERS, display_name

    return [display_name(key) for key in CLASSIFIERS]


def register(sub) -> None:
    """Add the ``tradeoff`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "tradeoff",
        help="speed against accuracy: evaluate candidate models on your data and recommend the simplest adequate one",
        description="Cross-validate candidate models (HM-SVM, SVC, LDA, kNN, nearest class mean on every feature set) "
        "on a data file, export each to ONNX and time it, and write OUT/tradeoff.json, OUT/tradeoff.md and charts of "
        "accuracy against latency, size and time to a decision; the recommendation is the cheapest model on the "
        "Pareto front within one standard error of the best (docs/tradeoff.md).",
    )
    add_data_options(
        p,
        data_help="an image-exploration, pressure-map, vibration or feature .npz, vibration CSV logs "
        "(t,x,y,z) or ROS 2 bags (IMU or pressure-array topics)",
    )
    p.add_argument("--out", default="runs/tradeoff", help="output directory (default: runs/tradeoff)")
    p.add_argument("--quick", action="store_true", help="fewer candidates and at most 60 samples per class")
    p.add_argument(
        "--folds",
        type=Number(int, low=2),
        default=None,
        help="cross-validation folds (default: 5, or fewer when the data allow fewer; a number the data do "
        "not allow is an error)",
    )
    p.add_argument(
        "--window",
        type=window_type(),
        default=None,
        help="vibration: reference window in samples (default: 800)",
    )
    p.add_argument(
        "--windows",
        type=window_list,
        default=None,
        help="vibration: window sizes to try (default: 200,400,800,1600)",
    )
    p.add_argument(
        "--frame-rate",
        type=Number(low=0, open_low=True),
        default=None,
        help="explorations: frames/s (default: the file's frame_rate_hz; frame recordings: from t; never assumed)",
    )
    p.add_argument(
        "--threshold",
        type=Number(low=0, open_low=True, words=("auto", "otsu", "display")),
        default=None,
        help="image threshold: auto (default), otsu, display or a number",
    )
    p.add_argument(
        "--erosion",
        type=Number(int, low=1, high=4096, words=("relative",)),
        default=None,
        help="erosion in pixels, or relative (default)",
    )
    p.add_argument(
        "--contact",
        default=None,
        choices=["raises", "lowers", "auto"],
        help="pressure maps: does contact raise (default) or lower the reading",
    )
    p.add_argument(
        "--max-per-class",
        type=Number(int, low=2, words=("auto",)),
        default=None,
        help="samples kept per class (default: 60 quick, 300)",
    )
    p.add_argument(
        "--classifiers",
        default=None,
        help=f"comma-separated subset of {','.join(_classifier_names())} (names or keys)",
    )
    p.add_argument(
        "--features", default=None, help="comma-separated feature-set name prefixes (e.g. fused,top)"
    )
    p.add_argument(
        "--target",
        type=Number(low=0, high=1, open_low=True),
        default=None,
        metavar="ACC",
        help="the accuracy a deployment needs: recommend the cheapest candidate whose interval's lower end "
        "reaches it (default: the one-standard-error rule; docs/tradeoff.md)",
    )
    p.add_argument(
        "--deploy",
        default=None,
        metavar="NAME",
        help="also refit candidate NAME (as in tradeoff.json) on all the data and write OUT/<name>.onnx and .npz "
        "(the recommended one always goes to OUT/recommended.onnx)",
    )
    p.add_argument("--seed", type=SEED, default=None, help="random seed (default: 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument(
        "--no-breaking",
        action="store_true",
        help="skip the breaking points of the recommended and the study's model (docs/robustness.md)",
    )
    p.add_argument(
        "--no-tune",
        action="store_true",
        help="run every candidate at the catalogue's default hyper-parameters instead of tuning it inside "
        "each training fold (for comparison)",
    )
    p.add_argument(
        "--exhaustive",
        action="store_true",
        help="evaluate every candidate on every fold (default: a candidate that cannot be recommended stops "
        "early; docs/tradeoff.md, 'What the default study evaluates, and what it skips')",
    )
    p.add_argument(
        "--backend",
        default=None,
        choices=["sequential", "loky", "threading", "multiprocessing", "dask"],
        help="where the cross-validation tasks run (default: this process; loky with --n-jobs); dask needs "
        "the optional extra dask",
    )
    p.add_argument(
        "--n-jobs", type=Number(int, low=-1), default=None, help="parallel workers (-1: every core)"
    )
    p.add_argument(
        "--scheduler",
        default=None,
        help="--backend dask: address of a running dask scheduler (tcp://host:8786)",
    )
    add_allow_pickle(p)
    p.set_defaults(handler=run_tradeoff_command)


def _names(text: str | None) -> tuple[str, ...] | None:
    return tuple(text.split(",")) if text else None


def tradeoff_options(args: argparse.Namespace):
    """Return the :class:`~tactile_torch.tradeoff.job.TradeoffOptions` the parsed arguments give: the
    options given, the library's defaults for the others (checked: a bad value raises ``ValueError``)."""
    from ..tradeoff.job import TradeoffOptions

    given = {
        "n_folds": args.folds,
        "window": args.window,
        "windows": args.windows,
        "frame_rate_hz": args.frame_rate,
        "threshold": args.threshold,
        "erosion": args.erosion,
        "contact": args.contact,
        "max_per_class": args.max_per_class,
        "classifiers": _names(args.classifiers),
        "features": _names(args.features),
        "target": args.target,
        "deploy": args.deploy or None,
        "random_state": args.seed,
    }
    return TradeoffOptions(
        quick=args.quick,
        tune=not args.no_tune,
        breaking=not args.no_breaking,
        exhaustive=args.exhaustive,
        **{name: value for name, value in given.items() if value is not None},
    )


def _word(value: object) -> str:
    return ",".join(str(v) for v in value) if isinstance(value, tuple) else str(value)


def reproduce_line(args: argparse.Namespace, options) -> str:
    """Return the command line that reproduces this run (the options not at their defaults)."""
    words = [f"--data {' '.join(args.data)}", *data_option_words(args), f"--out {args.out}"]
    words += ["--quick"] if args.quick else []
    words += ["--no-breaking"] if args.no_breaking else []
    words += ["--no-tune"] if args.no_tune else []
    words += ["--exhaustive"] if args.exhaustive else []
    changed = options.changed()
    words += [
        f"--{name.replace('_', '-')} {_word(getattr(args, name))}"
        for field, name in REPRODUCED
        if field in changed
    ]
    return "tactile-torch tradeoff " + " ".join(words)


def with_flags(text: str) -> str:
    """Return a line of the trade-off library with the arguments it names shown as this command's options.

    The library's notes name the Python argument (``features=``, ``with target=ACC``); printed by
    ``tactile-torch tradeoff`` they read ``--features``, ``with --target ACC``
    (:func:`tactile_torch.cli.with_flags`, with the :data:`~tactile_torch.cli.ARGUMENT_FLAGS` of the
    options this command has).

    >>> with_flags("frame rate not given: 30 frames/s assumed (frame_rate_hz= to set it)")
    'frame rate not given: 30 frames/s assumed (--frame-rate to set it)'
    """
    sub = argparse.ArgumentParser().add_subparsers()
    register(sub)
    options = sub.choices["tradeoff"]._option_string_actions
    return _with_flags(text, {name: flag for name, flag in ARGUMENT_FLAGS.items() if flag in options})


def run_tradeoff_command(args: argparse.Namespace) -> int:
    """Run the study, print its summary and what was written; return the exit status."""
    from ..tradeoff import load_tradeoff_data, summary_lines
    from ..tradeoff.job import run_tradeoff_job
    from ..tradeoff.output import incomplete_lines

    options = tradeoff_options(args)
    command = reproduce_line(args, options)
    log = (lambda line: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    announce_layout(args, lambda line: print(f"[tradeoff] {line}", file=sys.stderr))  # before any work
    data = load_tradeoff_data(
        args.data,
        frame_rate_hz=options.frame_rate_hz,
        options=data_options(args),
        name=data_name(args.data),
    )
    result, paths = run_tradeoff_job(
        data,
        options,
        args.out,
        command=command,
        allow_pickle=args.allow_pickle,
        backend=args.backend,
        n_jobs=args.n_jobs,
        scheduler=args.scheduler,
        progress=not args.quiet,
        log=log,
    )
    for line in summary_lines(result):
        print(with_flags(line))
    for note in result.notes:
        print(f"note:        {with_flags(note)}")
    print(f"written: {', '.join(str(p) for p in paths.values())} ({result.seconds:.0f} s)")
    if result.incomplete:  # a late stage failed: a bug, reported as one, after what was complete is written
        for line in incomplete_lines(result):
            print(f"tactile-torch tradeoff: {line}", file=sys.stderr)
        return INTERNAL_ERROR_EXIT
    if result.status == "none exported":
        return NOT_EXPORTED_EXIT
    return 0 if result.status == "recommended" else NO_RECOMMENDATION_EXIT
