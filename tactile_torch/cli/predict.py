"""``tactile-torch predict``: classify a data file with an exported ONNX bundle (onnxruntime, no torch).

Torch-free, as on the robot: :class:`tactile_torch.robot.runtime.OnnxPipeline` and numpy only.
"""

from __future__ import annotations

import argparse
import sys

from ._options import (
    Number,
    UsageError,
    add_allow_pickle,
    add_data_options,
    data_name,
    data_options,
    parse_range_g,
)
from ._output import print_class_report


def register(sub) -> None:
    """Add the ``predict`` command to the subparsers ``sub``."""
    p = sub.add_parser(
        "predict",
        help="classify a data file with an exported ONNX pipeline (onnxruntime, no torch); print a class report",
    )
    p.add_argument("--model", required=True, help="the .onnx bundle written by tactile-torch export")
    add_data_options(p, sensor_range=False)  # predict's --range leaves windows out instead
    p.add_argument("--out", default="", help="also write the predicted labels and names to this .npz")
    p.add_argument(
        "--batch", type=Number(int, low=1), default=256, help="samples per onnxruntime call (default: 256)"
    )
    p.add_argument(
        "--threads", type=Number(int, low=0), default=1, help="onnxruntime intra-op threads (default: 1)"
    )
    p.add_argument(
        "--range",
        type=Number(low=0, open_low=True, allow_inf=True, unit="g"),
        metavar="G",
        help="vibration: windows with a sample beyond +-G g are not classified; inf: off (default: the "
        "bundle's sensor_range_g, else 5)",
    )
    add_allow_pickle(p)
    p.set_defaults(handler=run_predict)


def run_predict(args: argparse.Namespace) -> int:
    """Classify the data file with the bundle and print the labels or a class report; return the exit status."""
    # torch-free: onnxruntime and numpy only, as on the robot.
    import numpy as np

    from ..metrics import class_report
    from ..robot.contract import UNKNOWN, WINDOWS_LAYOUT
    from ..robot.runtime import OnnxPipeline

    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    range_g = parse_range_g(args.range, "--range", off=True)
    windows = pipe.input_layout == WINDOWS_LAYOUT
    if range_g is not None and not windows:
        raise UsageError(f"--range: {args.model} takes no vibration windows ({pipe.pipeline} bundle)")
    data = pipe.read_npz(args.data, allow_pickle=args.allow_pickle, options=data_options(args))
    where = data_name(args.data)
    mismatch = pipe.sample_rate_mismatch(data.rate_hz)
    if mismatch:
        print(f"tactile-torch predict: warning: {where}: {mismatch}", file=sys.stderr)
    # Windows holding a sample the sensor cannot give (a corrupted value), and samples whose features
    # lie far from the training data, are "unknown" (-1), as in stream and OnnxPipeline.classify.
    range_g = pipe.range_g if range_g is None else range_g
    parts = [
        pipe.classify(data.raw[i : i + args.batch], range_g=range_g)
        for i in range(0, len(data.raw), args.batch)
    ]
    labels = np.concatenate([p.labels for p in parts])
    reasons = [r for p in parts for r in p.reasons]
    novel = None if parts[0].novel is None else np.concatenate([p.novel for p in parts])
    beyond = f"beyond ±{range_g:g} g"
    n_range = sum(r is not None and r.endswith(f"range ±{range_g:g} g") for r in reasons)
    n_ood = sum(r is not None and r.startswith("out of distribution") for r in reasons)
    n_nan = sum(r is not None and r.startswith("scores not finite") for r in reasons)
    classified = labels != UNKNOWN
    if windows and n_range == len(labels):
        raise UsageError(
            f"{where}: all {n_range} windows have samples {beyond}, so none was classified (the range is the "
            "bundle's sensor_range_g, else 5 g; --range sets it)"
        )
    if n_range:
        print(
            f"tactile-torch predict: warning: {where}: {n_range} of {len(labels)} windows have samples "
            f"{beyond} and were not classified",
            file=sys.stderr,
        )
    print(f"{pipe!r}: {len(labels)} samples of {where}")
    if args.out:
        from ..robot.npz import write_npz

        names = np.array(
            [
                pipe.label_name(int(v)) if r is None else f"unknown: {r}"
                for v, r in zip(labels, reasons, strict=True)
            ]
        )
        arrays = {"labels": labels, "names": names, **({} if novel is None else {"novel": novel})}
        write_npz(args.out, arrays, inputs=[*args.data, args.model])
        print(f"labels written to {args.out}")
    if n_range:
        print(f"{n_range} windows with samples {beyond} were not classified and are left out")
    if n_ood:
        threshold = pipe.ood_threshold
        print(
            f"{n_ood} samples are unknown: out of distribution (distance to the training data beyond "
            f"{threshold:.3g}, the {float(pipe.metadata.get('ood_quantile', 'nan')):.1%} quantile of the "
            "training windows) and are left out"
        )
    if n_nan:
        print(f"{n_nan} samples gave non-finite scores and are left out")
    if novel is not None:
        _print_novel(novel & classified, pipe, data)
    if data.labels is not None and pipe.pipeline.endswith("-pyp"):
        from ..metrics import pairwise_accuracy

        if not classified.any():
            print("no sample was classified")
            return 0
        found = labels[classified]  # the components, scored against the file's classes
        accuracy = pairwise_accuracy(data.file_labels[classified], found)
        print(f"{len(np.unique(found))} components used; pairwise accuracy {accuracy:.4f}")
        return 0
    known = None if data.labels is None else data.labels >= 0
    if known is not None and not known.all():
        print(f"{int((~known).sum())} samples of classes the model does not know are left out")
    known = classified if known is None else known & classified
    if data.labels is None or not known.any():
        counts = np.bincount(labels[classified], minlength=len(pipe.class_names))
        for name, n in zip(pipe.class_names, counts, strict=True):
            print(f"{name:<24} {n:>7}")
        print(f"{'unknown':<24} {int((~classified).sum()):>7}")
        return 0
    n = len(pipe.class_names)
    print_class_report(
        class_report(data.labels[known], labels[known], labels=np.arange(n), names=pipe.class_names)
    )
    return 0


def _print_novel(novel, pipe, data) -> None:
    """Say how many windows the clustering bundle flags as novel (a surface it did not see), per file class."""
    import json

    import numpy as np

    from ..robot.contract import NOVELTY_THRESHOLDS_KEY

    rule = (
        f"novelty above {json.loads(pipe.metadata[NOVELTY_THRESHOLDS_KEY])[0]:.4g}, the bundle's calibrated "
        "threshold"
        if NOVELTY_THRESHOLDS_KEY in pipe.metadata
        else "a new component more probable than every known one; not calibrated"
    )
    print(f"{int(novel.sum())} of {len(novel)} samples are novel ({rule})")
    if data.file_labels is None or not novel.any():
        return
    file_labels = np.asarray(data.file_labels)
    names = list(data.file_class_names or [])
    for c in np.unique(file_labels):
        mine = file_labels == c
        name = names[c] if 0 <= c < len(names) else f"class {c}"
        print(f"  {name:<22} {int(novel[mine].sum()):>6} of {int(mine.sum())} novel")
