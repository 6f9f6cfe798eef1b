"""``tactile-torch predict``: classify a data file with an exported ONNX bundle (onnxruntime, no torch).

Torch-free, as on the robot: :class:`tactile_torch.robot.runtime.OnnxPipeline` and numpy only.
"""

from __future__ import annotations

import argparse
import sys

from ._options import (
    CPUS,
    Number,
    UsageError,
    add_allow_pickle,
    add_data_options,
    add_touch_options,
    announce_layout,
    data_name,
    data_options,
    parse_range_g,
    touch_options,
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
        "--threads",
        type=Number(int, low=0, high=CPUS),
        default=1,
        help=f"onnxruntime intra-op threads, at most this machine's {CPUS} CPUs (0: onnxruntime's choice; default: 1)",
    )
    p.add_argument(
        "--range",
        type=Number(low=0, open_low=True, allow_inf=True, unit="g"),
        metavar="G",
        help="vibration: windows with a sample beyond +-G g are not classified; inf: off (default: the "
        "bundle's sensor_range_g, else 5)",
    )
    p.add_argument(
        "--touches",
        action="store_true",
        help="frame bundles: cut touches from the data's frames as 'stream' does and classify each (the "
        "default for a frame recording or a bag; explorations are played one after another with --rest)",
    )
    p.add_argument(
        "--rest",
        type=Number(float, low=0, high=3600),
        default=0.5,
        help="--touches on explorations: seconds of rest after each (default: 0.5)",
    )
    p.add_argument(
        "--frame-rate",
        type=Number(float, low=0, open_low=True, high=1e6),
        default=None,
        help="--touches on explorations: frames per second (default: the file's frame_rate_hz; explorations "
        "that state none need it)",
    )
    p.add_argument("--json", action="store_true", help="--touches: one JSON object per touch on stdout")
    add_touch_options(p)
    add_allow_pickle(p)
    p.set_defaults(handler=run_predict)


def run_predict(args: argparse.Namespace) -> int:
    """Classify the data file with the bundle and print the labels or a class report; return the exit status."""
    # torch-free: onnxruntime and numpy only, as on the robot.
    import numpy as np

    from ..metrics import class_report
    from ..robot.contract import BEYOND_RANGE, FEATURES_LAYOUT, UNKNOWN, WINDOWS_LAYOUT
    from ..robot.runtime import OnnxPipeline

    announce_layout(args, lambda line: print(f"tactile-torch predict: {line}", file=sys.stderr))
    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    if _touch_data(args, pipe):
        return predict_touches(args, pipe)
    range_g = parse_range_g(args.range, "--range", off=True)
    windows = pipe.input_layout == WINDOWS_LAYOUT
    if range_g is not None and not windows:
        raise UsageError(f"--range: {args.model} takes no vibration windows ({pipe.pipeline} bundle)")
    data = pipe.read_npz(args.data, allow_pickle=args.allow_pickle, options=data_options(args))
    where = data_name(args.data)
    if data.note:
        print(f"tactile-torch predict: note: {where}: {data.note}", file=sys.stderr)
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
    causes = np.array([c or "" for p in parts for c in p.causes])
    novel = None if parts[0].novel is None else np.concatenate([p.novel for p in parts])
    classified = labels != UNKNOWN
    what = {WINDOWS_LAYOUT: "windows", FEATURES_LAYOUT: "samples"}.get(pipe.input_layout, "explorations")
    if windows and (causes == BEYOND_RANGE).all():
        raise UsageError(
            f"{where}: all {len(labels)} windows have samples beyond ±{range_g:g} g, so none was classified (the "
            "range is the bundle's sensor_range_g, else 5 g; --range sets it)"
        )
    print(f"{pipe!r}: {len(labels)} {what} of {where}")
    if args.out:
        from ..robot.files.npz import write_npz

        names = np.array(
            [
                pipe.label_name(int(v)) if r is None else f"unknown: {r}"
                for v, r in zip(labels, reasons, strict=True)
            ]
        )
        arrays = {"labels": labels, "names": names, **({} if novel is None else {"novel": novel})}
        write_npz(args.out, arrays, inputs=[*args.data, args.model])
        print(f"labels written to {args.out}")
    clustering = data.labels is not None and pipe.pipeline.endswith("-pyp")
    # a class of the file the bundle does not know: only a classified sample can be scored against it
    foreign = (
        np.zeros(len(labels), dtype=bool)
        if data.labels is None or clustering
        else classified & (data.labels < 0)
    )
    print(_left_out_line(args, pipe, data, what, causes, foreign, range_g, clustering))
    if novel is not None:
        _print_novel(novel & classified, pipe, data)
    if clustering:
        from ..metrics import pairwise_accuracy

        if not classified.any():
            print("no sample was classified")
            return 0
        found = labels[classified]  # the components, scored against the file's classes
        accuracy = pairwise_accuracy(data.file_labels[classified], found)
        print(f"{len(np.unique(found))} components used; pairwise accuracy {accuracy:.4f}")
        return 0
    scored = classified & ~foreign
    if data.labels is None or not scored.any():
        counts = np.bincount(labels[classified], minlength=len(pipe.class_names))
        for name, n in zip(pipe.class_names, counts, strict=True):
            print(f"{name:<24} {n:>7}")
        print(f"{'unknown':<24} {int((~classified).sum()):>7}")
        return 0
    n = len(pipe.class_names)
    print_class_report(
        class_report(data.labels[scored], labels[scored], labels=np.arange(n), names=pipe.class_names)
    )
    return 0


def _left_out_line(args, pipe, data, what: str, causes, foreign, range_g: float, clustering: bool) -> str:
    """One line counting every sample once: classified (scored against its class), or left out with its one
    reason (unknown to the bundle, and why; or of a class the bundle does not know)."""

    from ..robot.contract import BEYOND_RANGE, NO_VIBRATION, NOT_FINITE, OUT_OF_DISTRIBUTION
    from ..robot.files.naming import name_list
    from ._codes import ARGUMENT_FLAGS, with_flags
    from ._options import data_layout

    quantile = float(pipe.metadata.get("ood_quantile", "nan"))
    threshold = pipe.ood_threshold
    words = {
        BEYOND_RANGE: f"beyond the sensor's range ±{range_g:g} g",
        NO_VIBRATION: "no vibration (every axis constant)",
        NOT_FINITE: "non-finite scores",
        OUT_OF_DISTRIBUTION: f"out of distribution (distance to the training data beyond {threshold or 0:.3g}, the "
        f"{quantile:.1%} quantile of the training {what})",
    }
    parts = [f"{int((causes == c).sum())} {text}" for c, text in words.items() if (causes == c).any()]
    if foreign.any():
        unknown = name_list(sorted({data.file_class_names[i] for i in data.file_labels[foreign]}), 6)
        part = f"{int(foreign.sum())} of {'a class' if ',' not in unknown else 'classes'} the model does not know ({unknown}"
        names = data_layout(args)
        fix = (
            f": {with_flags(names.other_way, ARGUMENT_FLAGS)} reads the files the other way"
            if names and names.other_way
            else ""
        )
        parts.append(f"{part}; it knows {name_list(pipe.class_names, 6)}){fix}")
    kept = int(len(causes) - (causes != "").sum() - foreign.sum())
    done = (
        "assigned to a component"
        if clustering
        else "scored against their class"
        if data.labels is not None
        else "classified"
    )
    line = f"{len(causes)} {what}: {kept} {done}"
    return line + (f", {len(causes) - kept} left out: {', '.join(parts)}" if parts else "")


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


def _touch_data(args: argparse.Namespace, pipe) -> bool:
    """Whether to cut touches: asked for, or a frame bundle given a frame recording or a bag of frames."""
    from ..robot.stream.live import frame_bundle

    if not frame_bundle(pipe):
        if args.touches:
            raise UsageError(
                f"--touches: touches are cut from frames; {args.model} takes {pipe.input_layout} input"
            )
        return False
    if args.touches:
        return True
    from ..robot.ros2.bags import is_bag

    if len(args.data) == 1 and is_bag(args.data[0]):
        return True
    from ..robot.files.npz import read_npz

    return all(
        {"frames", "t"} <= set(read_npz(path, what="data file (.npz of docs/formats.md)"))
        for path in args.data
    )


def _labelled_recordings(paths: list, options) -> list:
    """Frame recordings read together, each frame labelled with its class (its own label, or its file's)."""
    import numpy as np

    from ..robot.files.frame_recordings import read_frame_recordings

    data = read_frame_recordings(paths, options)
    for i, rec in enumerate(data.recordings):
        if data.file_labels is not None:  # one class per file (its layout): every frame of it
            rec.labels = np.full(len(rec), int(data.file_labels[i]), dtype=np.int64)
        rec.class_names = data.class_names
    return data.recordings


def predict_touches(args: argparse.Namespace, pipe) -> int:
    """Cut touches from the data's frames as the stream does, classify each; print them and a class report."""
    import numpy as np

    from ..metrics import class_report
    from ..robot.files.frame_recordings import read_frame_recording, touch_labels
    from ..robot.stream.output import result_json, result_text

    if args.range is not None:
        raise UsageError(
            "--range: frames out of the bundle's value_range are rejected as in stream; --range is for windows"
        )
    from ..robot.stream.live import classify_recording

    options = data_options(args)
    if options.shape is None:  # bags of flat arrays (TactileState, a field): the bundle's frames
        from dataclasses import replace

        options = replace(options, shape=tuple(int(d) for d in pipe.input_shape[-2:]))
    if len(args.data) == 1:
        recordings = [
            read_frame_recording(
                args.data[0], frame_rate_hz=args.frame_rate, rest_s=args.rest, options=options
            )
        ]
    else:  # a day's logs, one after another; their classes from their labels or the files' layout
        recordings = _labelled_recordings(args.data, options)

    def say(event) -> None:
        print(f"tactile-torch predict: {event.message}", file=sys.stderr)

    write = result_json if args.json else result_text
    touches, truth = [], []
    for recording in recordings:
        results, live = classify_recording(
            pipe, recording, touch_options(args, segment="touches"), on_event=say
        )
        mine = [r for r in results if r.kind == "touch"]
        if not args.json:
            print(f"{pipe!r}: {len(recording)} frames of {recording.name}")
        for result in mine:
            print(write(result))
        print(live.summary(), file=sys.stderr if args.json else sys.stdout)
        touches += mine
        truth += [touch_labels(recording, r.segment.start_item, r.segment.frames) for r in mine]
    if args.json:
        return 0
    truth = np.array(truth, dtype=np.int64)
    decided = np.array(
        [-2 if r.decision.label is None else r.decision.label for r in touches], dtype=np.int64
    )
    ended = np.array([-2 if r.label is None else r.label for r in touches], dtype=np.int64)
    early = np.array([r.decision.early for r in touches], dtype=bool)
    if early.any():
        after = np.array([r.decision.after_s for r in touches])[early]
        print(
            f"{int(early.sum())} of {len(touches)} touches decided early, median {np.median(after):.3g} s into the touch "
            f"({live.rule.describe()})"
        )
    if args.out:
        from ..robot.files.npz import write_npz

        arrays = {
            "start": np.array([r.segment.start_item for r in touches], dtype=np.int64),
            "frames": np.array([r.segment.frames for r in touches], dtype=np.int64),
            "duration_s": np.array([r.segment.duration_s for r in touches]),
            "ended_by": np.array([str(r.segment.ended_by) for r in touches]),
            "labels": ended,
            "names": np.array([str(r.name) if r.reason is None else f"unknown: {r.reason}" for r in touches]),
            "decision_labels": decided,
            "decision_early": early,
            "decision_s": np.array([r.decision.after_s for r in touches]),
            "true_labels": truth,
        }
        write_npz(args.out, arrays, inputs=[*args.data, args.model])
        print(f"touches written to {args.out}")
    if recordings[0].labels is None or not (truth >= 0).any():
        return 0
    names = list(recording.class_names or ())
    index = {name: i for i, name in enumerate(pipe.class_names)}
    lookup = np.array([index.get(name, -1) for name in names], dtype=np.int64)
    known = truth >= 0
    truth_b = np.where(known, lookup[np.maximum(truth, 0)], -1)
    keep = (truth_b >= 0) & (decided >= 0)
    if keep.any():
        n = len(pipe.class_names)
        print("decisions (early where the rule was sure, else at the end of the touch):")
        print_class_report(
            class_report(truth_b[keep], decided[keep], labels=np.arange(n), names=pipe.class_names)
        )
    return 0
