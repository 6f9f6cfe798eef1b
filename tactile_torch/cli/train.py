"""``tactile-torch train``: train a classifier of the catalogue on a data file, print its held-out
class report and write its model file (:mod:`tactile_torch.training`)."""

from __future__ import annotations

import argparse

from ._codes import ARGUMENT_FLAGS, with_flags
from ._options import (
    SEED,
    Number,
    add_allow_pickle,
    add_data_options,
    announce_layout,
    data_name,
    data_options,
    declare_range,
    read_data_arg,
    window_type,
)
from ._output import print_class_report, recordings_line


def catalogue_choices() -> list[str]:
    """The ``--method`` choices: the classifier catalogue's keys and aliases (:mod:`tactile_torch.catalogue`)."""
    from ..catalogue import choices

    return choices()


def register(sub) -> None:
    """Add the ``train`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "train", help="train a classifier on an image, vibration or feature .npz; print a class report"
    )
    add_data_options(p)
    p.add_argument(
        "--method",
        default="hmsvm",
        choices=catalogue_choices(),
        help="classifier of the catalogue, docs/tradeoff.md (default: hmsvm; svm = svc); every one writes a model file (--out)",
    )
    p.add_argument(
        "--select",
        type=Number(int, low=1),
        default=None,
        metavar="K",
        help="keep the K best-ranked features (the trade-off's 'top K' feature sets; default: all)",
    )
    p.add_argument(
        "--out", default="", help="write the trained model's file here (no pickle), e.g. model.npz"
    )
    p.add_argument("--C", type=Number(low=0, open_low=True), default=16.0, help="SVM penalty (default: 16)")
    p.add_argument(
        "--gamma",
        type=Number(low=0, open_low=True, words=("scale",)),
        default="scale",
        help="RBF width, a number > 0 or 'scale' (default)",
    )
    p.add_argument("--kernel", default="rbf", choices=["rbf", "linear"], help="SVM kernel (default: rbf)")
    p.add_argument(
        "--window", type=window_type(), default=800, help="vibration window in samples, >= 16 (default: 800)"
    )
    p.add_argument(
        "--step", type=Number(int, low=1), default=None, help="vibration window hop (default: the window)"
    )
    p.add_argument(
        "--features",
        default=None,
        choices=["fused", "per-frame", "per-taxel"],
        help="frames: the 12 image features of the fused edges, 12 per frame, or 7 time-series features per "
        "taxel (default: per-taxel for a pressure array of at most 256 taxels, else fused)",
    )
    p.add_argument(
        "--frame-rate",
        type=Number(low=0, open_low=True),
        default=None,
        help="explorations: frames per second, for the live stream (default: the file's; frame recordings: "
        "from t)",
    )
    p.add_argument(
        "--folds",
        type=Number(int, low=2),
        default=5,
        help="held-out folds, grouped by session or recording, or time blocks (default: 5)",
    )
    p.add_argument(
        "--test-size",
        type=Number(low=0, high=1, open_low=True, open_high=True),
        default=None,
        help="(old) held-out share: --folds round(1 / share)",
    )
    p.add_argument("--seed", type=SEED, default=0, help="random seed (default: 0)")
    add_allow_pickle(p)
    p.set_defaults(handler=run_train)


def run_train(args: argparse.Namespace) -> int:
    """Train, print the class report, write the model file; return the exit status."""
    from ..exceptions import InputError, InputValueError
    from ..features.files import load_features
    from ..training import save_model, train_classifier

    announce_layout(args, print)  # before any file is read: a tree read the wrong way costs nothing
    data = read_data_arg(args)
    if data.kind == "vibration":
        print(f"{data_name(args.data)}: {recordings_line(data, args)}")
    features = load_features(
        data,
        window=args.window,
        step=args.step,
        features=args.features,
        frame_rate_hz=args.frame_rate,
        options=data_options(args),
        name=data_name(args.data),
    )
    for note in features.notes:
        print(f"{data_name(args.data)}: {with_flags(note, ARGUMENT_FLAGS)}")
    declare_range(features.source, args)
    print(
        f"{data_name(args.data)}: {features.X.shape[0]} samples x {features.X.shape[1]} features "
        f"({features.source['kind']}), {len(features.class_names)} classes"
    )
    try:
        model = train_classifier(
            features,
            args.method,
            C=args.C,
            gamma=args.gamma,
            kernel=args.kernel,
            n_folds=args.folds,
            test_size=args.test_size,
            select=args.select,
            random_state=args.seed,
        )
    except (ValueError, InputError) as err:  # e.g. a class with one sample: name the file it came from
        raise InputValueError(f"{data_name(args.data)}: {err}") from err
    print(f"{args.method}: held-out accuracy from {model.split}")
    print_class_report(model.report)
    print(
        f"held out: accuracy per fold {', '.join(f'{a:.3f}' for a in model.fold_accuracy)}; the model "
        f"(--out) is then trained on all {len(model.train_index)} samples"
    )
    if model.early_rule is not None:  # frames: what the exported bundle decides before a touch ends
        print(f"early decisions: {model.early_rule.describe()}")
    if args.out:
        print(f"model written to {save_model(args.out, model, features)}")
    return 0
