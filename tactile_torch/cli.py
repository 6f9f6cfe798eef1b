"""The ``tactile-torch`` command line.

Every subcommand of the toolkit is listed; the handlers import their modules lazily so that
``tactile-torch predict`` can run on a robot with onnxruntime and no torch.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import threading
import warnings
from collections.abc import Iterator
from pathlib import Path

from .cli_data import add_data_options, data_option_words, data_options, read_data_arg

NOT_BUILT_EXIT = 2
"""Exit status when a command cannot do its work (e.g. ``bench`` outside a source checkout)."""
BAD_INPUT_EXIT = 2
"""Exit status for bad input (a missing or malformed file, a wrong option), after one line on stderr."""
INTERNAL_ERROR_EXIT = 1
MAX_READ_ENV = "TACTILE_TORCH_MAX_READ_MB"
"""Where ``--max-read-mb`` puts the read bound (:func:`tactile_torch.robot.npz.max_read_bytes` reads it)."""
"""Exit status for an unexpected error (a bug): one line on stderr, the traceback with ``--debug``."""
NO_RECOMMENDATION_EXIT = 3
"""Exit status of ``tradeoff`` when no candidate is adequate (none reaches ``--target``, or none is
significantly above the trivial baseline): the outputs are written, nothing is deployed."""
NOT_EXPORTED_EXIT = 4
"""Exit status of ``tradeoff`` when no candidate could be fitted and exported (the notes say why)."""

TRAIN_EXTRA = "train"
TRAIN_MODULES = (
    "torch",
    "scipy",
    "sklearn",
    "numba",
    "matplotlib",
    "onnx",
    "onnxscript",
    "tqdm",
    "threadpoolctl",
)
"""Modules of the ``[train]`` extra (pyproject.toml); the robot install has numpy, onnxruntime, pyserial."""
NEEDS_TRAIN_EXTRA = ("report", "bench", "train", "cluster", "export", "tradeoff")
"""Commands that need the ``[train]`` extra; ``predict``, ``stream`` and ``simulate-sensor --data`` do not."""


class UsageError(ValueError):
    """Bad command-line input detected by a handler (reported in one line, like any ``ValueError``)."""


def _data_name(paths: str | Path | list) -> str:
    from .robot.formats import data_name

    return data_name(paths)


def _report(args: argparse.Namespace) -> int:
    from .studies import run_report

    only = [s for s in args.only.split(",") if s] if args.only else None
    path = run_report(args.out, random_state=args.seed, quick=args.quick, full=args.full, only=only)
    print(f"report written to {path}")
    return 0


def _print_class_report(rep) -> None:
    print(f"{'class':<24} {'samples':>7} {'accuracy':>9} {'type I':>8} {'type II':>8}")
    for row in rep.rows():
        print(
            f"{row['class']:<24} {row['samples']:>7} {row['accuracy']:>9.4f} "
            f"{row['type I error']:>8.4f} {row['type II error']:>8.4f}"
        )
    print(f"overall accuracy {rep.overall_accuracy:.4f}")


def _train(args: argparse.Namespace) -> int:
    from .training import load_features, save_model, train_classifier

    gamma = args.gamma if args.gamma == "scale" else float(args.gamma)
    if args.select is not None and args.select < 1:
        raise UsageError(f"--select must be a number of features >= 1, got {args.select}")
    features = load_features(
        read_data_arg(args),
        window=args.window,
        step=args.step,
        fuse=not args.no_fuse,
        name=_data_name(args.data),
    )
    _declare_range(features.source, args)
    print(
        f"{_data_name(args.data)}: {features.X.shape[0]} samples x {features.X.shape[1]} features "
        f"({features.source['kind']}), {len(features.class_names)} classes"
    )
    try:
        model = train_classifier(
            features,
            args.method,
            C=args.C,
            gamma=gamma,
            kernel=args.kernel,
            n_folds=args.folds,
            test_size=args.test_size,
            select=args.select,
            random_state=args.seed,
        )
    except ValueError as err:  # e.g. a class with one sample: name the file it came from
        raise ValueError(f"{_data_name(args.data)}: {err}") from err
    print(f"{args.method}: held-out accuracy from {model.split}")
    _print_class_report(model.report)
    print(
        f"held out: accuracy per fold {', '.join(f'{a:.3f}' for a in model.fold_accuracy)}; the model "
        f"(--out) is then trained on all {len(model.train_index)} samples"
    )
    if args.out:
        print(f"model written to {save_model(args.out, model, features)}")
    return 0


def _declare_range(source: dict, args: argparse.Namespace) -> None:
    """Keep a declared finite ``--sensor-range`` in a vibration model's source (export's default range)."""
    declared = getattr(args, "data_sensor_range", None)
    if source.get("kind") == "vibration" and declared is not None and declared != float("inf"):
        source["sensor_range_g"] = float(declared)


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
        "--out",
        str(Path(args.out).resolve()),
    ]
    print(f"tactile-torch bench: results go to {args.out}", file=sys.stderr)
    return subprocess.call(cmd)


def _n_iter(text: str) -> int | str:
    """``--n-iter``: a number of sweeps or 'auto'."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of sweeps or 'auto', got {text!r}") from None


def _cluster(args: argparse.Namespace) -> int:
    import numpy as np

    from .clustering_model import save_clustering_model
    from .metrics import pairwise_accuracy
    from .mixture import PitmanYorGMM
    from .training import load_features

    data = read_data_arg(args)
    if data.kind == "features":  # labels optional: clustering does not need them
        X, truth = data.features, data.labels
        source = {"kind": "features", "n_features": int(X.shape[1])}
    elif data.kind == "vibration":
        features = load_features(data, window=args.window, step=args.step, name=_data_name(args.data))
        X, truth, source = features.X, features.y, dict(features.source)
        _declare_range(source, args)
    else:
        raise UsageError(
            f"{_data_name(args.data)}: --data must hold vibration recordings ('signals') or a 'features' "
            f"array (n, D) to cluster, got {data.kind} data"
        )
    kind = source["kind"]
    transform = None
    if kind == "vibration":
        from .signal import ClusteringTransform

        transform = ClusteringTransform(args.components).fit(X)
        X = transform.transform(X)
        print(
            f"{_data_name(args.data)}: {len(X)} windows of {args.window} samples -> "
            f"{X.shape[1]} principal components"
        )
    init = int(args.init) if args.init.isdigit() else args.init
    if args.model == "mfm" and (args.alpha is not None or args.discount is not None):
        raise UsageError(
            "--alpha and --discount apply to --model pyp (the Pitman-Yor mixture), got --model mfm"
        )
    if args.model == "pyp" and args.coarsen is not None:
        raise UsageError("--coarsen applies to --model mfm, got --model pyp")
    model = PitmanYorGMM(
        model=args.model,
        coarsen=args.coarsen,
        alpha=args.alpha,
        discount=args.discount,
        n_iter=args.n_iter,
        max_iter=args.max_iter,
        burn_in=args.burn_in,
        n_chains=args.chains,
        init=init,
        random_state=args.seed,
        progress=not args.quiet,
    ).fit(X)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ks = model.n_clusters_summary_
    np.savez(
        out / "clustering.npz",
        labels=model.labels_,
        map_labels=model.map_labels_,
        means=model.means_,
        covariances=model.covariances_,
        precisions_cholesky=model.precisions_cholesky_,
        weights=model.weights_,
        n_clusters_samples=model.n_clusters_samples_,
        n_clusters_interval=np.array(ks["interval"]),
        alpha_samples=model.alpha_samples_,
        discount_samples=model.discount_samples_,
    )
    save_clustering_model(out / "model.npz", model, source=source, transform=transform)
    summary = model.summary()
    if truth is not None:
        summary += (
            f"\npairwise accuracy: point estimate {pairwise_accuracy(truth, model.labels_):.4f}, "
            f"MAP sample {pairwise_accuracy(truth, model.map_labels_):.4f}"
        )
    (out / "summary.txt").write_text(summary + "\n")
    print(summary)
    print(
        f"written: {out / 'clustering.npz'}, {out / 'summary.txt'}, {out / 'model.npz'} (tactile-torch export: "
        f"the point estimate's {model.n_clusters_} components)"
    )
    return 0


def _range_g(text: str | None, option: str, *, off: bool) -> float | None:
    """Return the sensor range in g an option gives (``None`` when not given), or raise a one-line error.

    ``off``: ``inf`` is accepted (no range check).
    """
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and (off or value != float("inf"))):
        expected = "a number of g > 0 ('inf': no check)" if off else "a finite number of g > 0"
        raise UsageError(f"{option} must be {expected}, got {text!r}")
    return value


@contextlib.contextmanager
def _stage(label: str, *, delay: float = 1.0) -> Iterator[None]:
    """Show ``label`` and the time elapsed on stderr while the block runs (a step of seconds that
    reports nothing itself, such as the ONNX export), from ``delay`` seconds on (a quick step, or one
    that fails at once, prints nothing); the line is cleared when it ends."""
    from tqdm.auto import tqdm

    bar = tqdm(desc=label, bar_format="{desc}: {elapsed}", file=sys.stderr, leave=False, delay=delay)
    done = threading.Event()

    def tick() -> None:
        while not done.wait(0.5):
            bar.refresh()

    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield
    finally:
        done.set()
        ticker.join()
        bar.close()


def _export(args: argparse.Namespace) -> int:
    from .pipeline import export_pipeline, pipeline_from_model
    from .robot.model_file import load_model_file

    sensor_range = _range_g(args.sensor_range, "--sensor-range", off=False)
    with _stage("export: building the pipeline"):
        pipeline = pipeline_from_model(load_model_file(args.model), sensor_range_g=sensor_range)
    with _stage("export: tracing the pipeline to ONNX and checking it"):
        path = export_pipeline(pipeline, args.out, inputs=[args.model])
    size = path.stat().st_size / 1024
    print(
        f"exported {pipeline.name}: input ({pipeline.input_layout}) = {pipeline.input_shape}, "
        f"{len(pipeline.class_names)} classes -> {path} ({size:.0f} KiB)"
    )
    if "k_exported" in pipeline.extra_metadata:  # a clustering: say which K, and why
        print(pipeline.extra_metadata["k_exported"])
    return 0


def _predict(args: argparse.Namespace) -> int:
    # torch-free: onnxruntime and numpy only, as on the robot.
    import numpy as np

    from .metrics import class_report
    from .robot.contract import UNKNOWN, WINDOWS_LAYOUT
    from .robot.runtime import OnnxPipeline

    if args.batch < 1:
        raise UsageError(f"--batch must be an int >= 1, got {args.batch}")
    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    range_g = _range_g(args.range, "--range", off=True)
    windows = pipe.input_layout == WINDOWS_LAYOUT
    if range_g is not None and not windows:
        raise UsageError(f"--range: {args.model} takes no vibration windows ({pipe.pipeline} bundle)")
    data = pipe.read_npz(args.data, allow_pickle=args.allow_pickle, options=data_options(args))
    where = _data_name(args.data)
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
        from .robot.npz import write_npz

        names = np.array(
            [
                pipe.label_name(int(v)) if r is None else f"unknown: {r}"
                for v, r in zip(labels, reasons, strict=True)
            ]
        )
        write_npz(args.out, {"labels": labels, "names": names}, inputs=[*args.data, args.model])
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
    if data.labels is not None and pipe.pipeline.endswith("-pyp"):
        from .metrics import pairwise_accuracy

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
    _print_class_report(
        class_report(data.labels[known], labels[known], labels=np.arange(n), names=pipe.class_names)
    )
    return 0


STREAM_NO_DATA_EXIT = 3
"""Exit status of ``stream`` when no sample came within the start or idle timeout."""
STREAM_DISCONNECTED_EXIT = 4
"""Exit status of ``stream`` when the port failed and was not (or could not be) reconnected."""
STREAM_STOPPED_EXIT = 0
"""Exit status of ``stream`` stopped by SIGTERM or SIGINT (Ctrl-C): a requested end, after the summary."""


def _at_least(minimum: float, kind: type = float):
    """Return an argparse type: a number of ``kind`` >= ``minimum``, else a one-line usage error."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not value >= minimum:
            raise argparse.ArgumentTypeError(f"expected a number >= {minimum:g}, got {text!r}")
        return value

    return parse


MAX_SIMULATED_S = 600
"""Longest synthetic recording ``simulate-sensor`` generates (28 surfaces are generated: 160 MB)."""


def _in_range(low: float, high: float):
    """Return an argparse type: a finite number ``low < x <= high``, else a one-line usage error."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not low < value <= high:
            raise argparse.ArgumentTypeError(f"expected a number > {low:g} and <= {high:g}, got {text!r}")
        return value

    return parse


def _stream(args: argparse.Namespace) -> int:
    # torch-free: pyserial, numpy and onnxruntime only, as on the robot.
    # SIGTERM (how systemd stops a service) ends the stream as Ctrl-C does: summary line, status 0.
    restore = _stop_on_sigterm()
    try:
        return _stream_until_stopped(args)
    finally:
        restore()


def _stream_until_stopped(args: argparse.Namespace) -> int:
    import math

    import numpy as np
    import serial

    from .robot.runtime import OnnxPipeline
    from .robot.stream import StreamDisconnected, StreamTimeout, WindowReader, sensor_range_g
    from .robot.stream_output import WindowVote, classify_windows, result_json, result_text

    range_g = _range_g(args.range, "--range", off=True)
    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    if "window_size" not in pipe.metadata:
        print(f"tactile-torch stream: {args.model} does not take vibration windows", file=sys.stderr)
        return 2
    size = int(pipe.metadata["window_size"])
    step = args.step if args.step is not None else max(size // 2, 1)
    rate = float(pipe.metadata["sample_rate_hz"]) if "sample_rate_hz" in pipe.metadata else None
    if args.time_unit == "samples" and rate is None:
        print(
            f"tactile-torch stream: --time-unit samples needs the sample rate, which {args.model} lacks",
            file=sys.stderr,
        )
        return 2
    info = sys.stderr if args.json else sys.stdout  # --json: stdout holds nothing but the JSON lines

    def say(message: str) -> None:
        print(f"tactile-torch stream: {message}", file=sys.stderr, flush=True)

    def open_port():
        return serial.serial_for_url(args.port, baudrate=args.baud, timeout=min(0.1, args.silence / 2))

    reading = []  # printed once the port is open (and the model warm): a sensor may start then

    def opened(name: str) -> None:
        if not reading:
            reading.append(name)
            print(
                f"{pipe!r}: reading {args.port}, windows of {size} samples every {step}, range ±{reader.range_g:g} g",
                file=info,
                flush=True,
            )

    reader = WindowReader(
        open_port,
        window_size=size,
        step=step,
        max_windows=args.max_windows or None,
        rate_hz=rate,
        time_unit=args.time_unit,
        range_g=range_g or sensor_range_g(pipe.metadata),
        silence_s=args.silence,
        idle_timeout_s=args.idle_timeout or math.inf,
        start_timeout_s=args.start_timeout or math.inf,
        reconnect=args.reconnect,
        on_event=lambda event: say(event.message),
        on_open=opened,
        name=args.port,
    )
    vote = WindowVote(args.vote, args.vote_method, pipe.class_names) if args.vote > 1 else None
    # Each classified window goes to every consumer in turn.
    write = result_json if args.json else result_text
    unknown = [0]

    def show(result) -> None:
        unknown[0] += result.label == -1
        print(write(result), flush=True)

    consumers = [show]
    if args.discover:  # new surfaces: N novel windows in a row (tactile_torch.robot.discovery)
        from .robot.discovery import stream_consumer

        consumers.append(stream_consumer(pipe, args.discover, info))
    status = 0
    try:
        # The first call allocates: run it before the port is opened (opening flushes the port's
        # buffer), so that neither the warm-up nor the open costs the sensor's first samples.
        warm = np.linspace(-0.5, 0.5, 3 * size, dtype=np.float32).reshape(1, 3, size)
        pipe.classify(warm)
        for result in classify_windows(reader, pipe, vote=vote, range_g=reader.range_g):
            for consume in consumers:
                consume(result)
    except StreamTimeout as err:
        say(str(err))
        status = STREAM_NO_DATA_EXIT
    except StreamDisconnected as err:
        say(str(err))
        status = STREAM_DISCONNECTED_EXIT
    except (KeyboardInterrupt, _Stopped) as err:
        say(f"stopped by {'SIGTERM' if isinstance(err, _Stopped) else 'SIGINT (Ctrl-C)'}")
        status = STREAM_STOPPED_EXIT
    print(
        f"{reader.samples} samples read, {reader.windows} windows, {reader.skipped} lines skipped, "
        f"{reader.rejected} samples out of range, {reader.gaps} gaps ({reader.lost} samples known lost), "
        f"{reader.reconnects} reconnections, {unknown[0]} windows unknown, {reader.format_switches} "
        "line-format switches",
        file=info,
        flush=True,
    )
    return status


class _Stopped(Exception):
    """SIGTERM arrived while streaming."""


def _stop_on_sigterm():
    """Make SIGTERM raise :class:`_Stopped` in the main thread; return the function that restores it."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def stop(signum, frame):
        raise _Stopped()

    previous = signal.signal(signal.SIGTERM, stop)
    return lambda: signal.signal(signal.SIGTERM, previous)


def _simulate_sensor(args: argparse.Namespace) -> int:
    import contextlib

    import serial

    from .robot.stream import pseudo_terminal, simulate_sensor

    if bool(args.port) == args.pty:
        print("tactile-torch simulate-sensor: give either --port PORT or --pty", file=sys.stderr)
        return 2
    if args.data:  # any layout of docs/formats.md, incl. recordings of different lengths
        from .robot.formats import read_recordings

        data = read_recordings(args.data, allow_pickle=args.allow_pickle, default_rate_hz=args.rate)
        if not 0 <= args.recording < len(data):
            raise UsageError(f"--recording must be in 0..{len(data) - 1} ({args.data}), got {args.recording}")
        recording, rate = data.signals[args.recording], data.rate_hz
    else:
        from .data import make_vibration_recordings

        rec = make_vibration_recordings(28, duration_s=args.seconds, random_state=args.seed)
        recording, rate = rec.signals[args.recording % 28], rec.rate_hz
    with contextlib.ExitStack() as stack:
        if args.pty:
            port, name = stack.enter_context(pseudo_terminal())
            print(f"sensor on {name}: read it with tactile-torch stream --port {name}", flush=True)
        else:
            port, name = stack.enter_context(serial.serial_for_url(args.port, baudrate=args.baud)), args.port
        print(f"writing {len(recording)} samples at {rate:g} Hz to {name}", flush=True)
        n = simulate_sensor(port, recording, rate_hz=rate, realtime=not args.fast, timestamps=args.timestamps)
    print(f"{n} samples written")
    return 0


def _tradeoff(args: argparse.Namespace) -> int:
    import math

    from .tradeoff import load_tradeoff_data, run_tradeoff, summary_lines, write_outputs
    from .tradeoff.output import staged_output

    def number_or(name: str, text: str, *words: str) -> str | float | int:
        if text in words:
            return text
        try:
            return int(text) if text.isdigit() else float(text)
        except ValueError:
            raise ValueError(f"--{name} must be one of {list(words)} or a number, got {text!r}") from None

    def int_list(name: str, text: str) -> list[int] | None:
        if not text:
            return None
        if not all(part.strip().isdigit() for part in text.split(",")):
            raise ValueError(f"--{name} must be comma-separated whole numbers, got {text!r}")
        return [int(part) for part in text.split(",")]

    folds = 5 if args.folds is None else args.folds
    if folds < 2:
        raise UsageError(f"--folds must be a whole number >= 2, got {folds}")
    max_per_class = number_or("max-per-class", args.max_per_class, "auto")
    if max_per_class != "auto" and (not isinstance(max_per_class, int) or max_per_class < 2):
        raise UsageError(f"--max-per-class must be 'auto' or a whole number >= 2, got {args.max_per_class!r}")
    if args.frame_rate is not None and not (math.isfinite(args.frame_rate) and args.frame_rate > 0):
        raise UsageError(f"--frame-rate must be a number of frames/s > 0, got {args.frame_rate:g}")
    if args.target is not None and not (math.isfinite(args.target) and 0 < args.target <= 1):
        raise UsageError(f"--target must be an accuracy in (0, 1], got {args.target:g}")
    options = [f"--data {' '.join(args.data)}", *data_option_words(args), f"--out {args.out}"]
    options += ["--quick"] if args.quick else []
    options += ["--no-breaking"] if args.no_breaking else []
    options += ["--no-tune"] if args.no_tune else []
    defaults = vars(build_parser().parse_args(["tradeoff", "--data", "-"]))
    names = ("folds", "window", "windows", "frame_rate", "threshold", "erosion", "contact", "max_per_class")
    names += ("classifiers", "features", "seed", "target", "deploy", "csv_session")
    for name in names:
        if getattr(args, name) != defaults[name]:
            options.append(f"--{name.replace('_', '-')} {getattr(args, name)}")
    command = "tactile-torch tradeoff " + " ".join(options)
    log = (lambda line: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    import numpy as np

    data = read_data_arg(args)
    if args.csv_session == "file" and all(str(p).lower().endswith(".csv") for p in args.data):
        data.session = np.array([Path(p).stem for p in args.data])  # every log its own session
    data = load_tradeoff_data(data, frame_rate_hz=args.frame_rate, name=_data_name(args.data))
    with staged_output(args.out) as staging:  # a killed or failed run leaves the previous --out as it was
        result = run_tradeoff(
            data,
            quick=args.quick,
            n_folds=folds,
            exact_folds=args.folds is not None,
            window=args.window,
            windows=int_list("windows", args.windows),
            frame_rate_hz=args.frame_rate,
            threshold=number_or("threshold", args.threshold, "auto", "otsu", "display"),
            erosion=number_or("erosion", args.erosion, "relative"),
            contact=args.contact,
            max_per_class=max_per_class,
            classifiers=args.classifiers.split(",") if args.classifiers else None,
            features=args.features.split(",") if args.features else None,
            target=args.target,
            deploy=["recommended", *([args.deploy] if args.deploy else [])],
            csv_session=args.csv_session,
            out_dir=staging,
            random_state=args.seed,
            allow_pickle=args.allow_pickle,
            tune=not args.no_tune,
            backend=args.backend,
            n_jobs=args.n_jobs,
            scheduler=args.scheduler,
            progress=not args.quiet,
            log=log,
        )
        if not args.no_breaking and result.recommended is not None:  # docs/robustness.md
            from .tradeoff.breaking import add_breaking_points

            add_breaking_points(
                result, staging, quick=args.quick, random_state=args.seed, progress=not args.quiet
            )
        paths = write_outputs(result, staging, command=command)
    for line in summary_lines(result):
        print(line)
    out = Path(args.out)
    print(
        f"written: {', '.join(str(out / p.relative_to(staging)) for p in paths.values())} ({result.seconds:.0f} s)"
    )
    if result.status == "none exported":
        return NOT_EXPORTED_EXIT
    return 0 if result.status == "recommended" else NO_RECOMMENDATION_EXIT


def _add_allow_pickle(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--allow-pickle",
        action="store_true",
        help="read the pickled recordings of a trusted vibration .npz written by tactile-torch 0.1",
    )


def catalogue_choices() -> list[str]:
    """The ``--method`` choices: the classifier catalogue's keys and aliases (:mod:`tactile_torch.catalogue`)."""
    from .catalogue import choices

    return choices()


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``tactile-torch CMD: argument --x: ...``), status 2."""

    def error(self, message: str):
        self.exit(BAD_INPUT_EXIT, f"{self.prog}: {' '.join(message.split())}\n")


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every subcommand."""
    from . import __version__

    parser = _Parser(
        prog="tactile-torch",
        description="Recognise surfaces from tactile images and vibration; train, cluster, export, run.",
    )
    parser.add_argument("--version", action="version", version=f"tactile-torch {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)

    p = sub.add_parser("report", help="run every pipeline on the bundled data and write a report (make run)")
    p.add_argument("--out", default="runs/latest", help="output directory (default: runs/latest)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the whole run (default: 0)")
    p.add_argument("--quick", action="store_true", help="smaller data and fewer iterations, for a smoke test")
    p.add_argument(
        "--full", action="store_true", help="also the study-size experiments (minutes, not seconds)"
    )
    p.add_argument("--only", default="", help="comma-separated study names to run (default: all)")
    p.set_defaults(handler=_report)

    p = sub.add_parser(
        "bench", help="run the benchmarks and write their results to --out (make bench: bench/results)"
    )
    p.add_argument("--quick", action="store_true", help="small sizes, for a smoke test")
    p.add_argument("--only", default="", help="comma-separated benchmark names (default: all)")
    p.add_argument(
        "--out",
        default="runs/bench",
        help="directory for the results (default: runs/bench; `make bench` writes bench/results)",
    )
    p.set_defaults(handler=_bench)

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
        type=int,
        default=None,
        metavar="K",
        help="keep the K best-ranked features (the trade-off's 'top K' feature sets; default: all)",
    )
    p.add_argument(
        "--out", default="", help="write the trained model's file here (no pickle), e.g. model.npz"
    )
    p.add_argument("--C", type=float, default=16.0, help="SVM penalty (default: 16)")
    p.add_argument("--gamma", default="scale", help="RBF width, a float or 'scale' (default)")
    p.add_argument("--kernel", default="rbf", choices=["rbf", "linear"], help="SVM kernel (default: rbf)")
    p.add_argument("--window", type=int, default=800, help="vibration window in samples (default: 800)")
    p.add_argument("--step", type=int, default=None, help="vibration window hop (default: the window)")
    p.add_argument("--no-fuse", action="store_true", help="image: per-frame features instead of fused ones")
    p.add_argument(
        "--folds",
        type=int,
        default=5,
        help="held-out folds, grouped by session or recording, or time blocks (default: 5)",
    )
    p.add_argument(
        "--test-size", type=float, default=None, help="(old) held-out share: --folds round(1 / share)"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    _add_allow_pickle(p)
    p.set_defaults(handler=_train)

    p = sub.add_parser(
        "cluster",
        help="discover surfaces with a Bayesian mixture (how many, and which window is which)",
        description="Fit tactile_torch.mixture.PitmanYorGMM to vibration recordings (windows -> 21 features -> "
        "the unsupervised transform -> principal components) or to a 'features' array (n, D); write the point "
        "estimate of the clustering (and the MAP sample, the posterior samples of K) to OUT/clustering.npz, a "
        "summary (posterior of K first) to OUT/summary.txt and the model to OUT/model.npz (for tactile-torch "
        "export).",
    )
    add_data_options(
        p,
        data_help="vibration recordings (.npz with 'signals', CSV logs, ROS 2 bags), or a .npz with "
        "'features' (n, D) and optionally 'labels' (n,)",
    )
    p.add_argument("--out", default="runs/cluster", help="output directory (default: runs/cluster)")
    p.add_argument("--window", type=int, default=800, help="recordings: window in samples (default: 800)")
    p.add_argument("--step", type=int, default=None, help="recordings: window hop (default: the window)")
    p.add_argument("--components", type=int, default=3, help="recordings: principal components (default: 3)")
    _add_allow_pickle(p)
    p.add_argument(
        "--model",
        choices=("mfm", "pyp"),
        default="mfm",
        help="prior: 'mfm' mixture of finite mixtures, consistent for K (default); 'pyp' the study's Pitman-Yor",
    )
    p.add_argument(
        "--coarsen",
        type=float,
        default=None,
        help="coarsened posterior: likelihood to the power a/(a+n) (--model mfm; default: off, see docs/mixture.md)",
    )
    p.add_argument(
        "--n-iter",
        type=_n_iter,
        default="auto",
        help="Gibbs sweeps per chain, burn-in included, or 'auto': until R-hat < 1.01 and ESS of K >= 400 "
        "(default: auto)",
    )
    p.add_argument(
        "--max-iter", type=int, default=16000, help="--n-iter auto: most sweeps per chain (default: 16000)"
    )
    p.add_argument(
        "--burn-in", type=int, default=250, help="sweeps discarded per chain, at least (default: 250)"
    )
    p.add_argument("--chains", type=int, default=4, help="independent chains, run in parallel (default: 4)")
    p.add_argument("--alpha", type=float, default=None, help="fix the concentration (default: sampled)")
    p.add_argument("--discount", type=float, default=None, help="fix the discount; 0 = Dirichlet process")
    p.add_argument(
        "--init", default="kmeans", help="'kmeans' (default), 'one', or a number of k-means clusters"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cluster)

    p = sub.add_parser(
        "export",
        help="export a trained pipeline (raw input -> label and scores) to one ONNX file",
        description="Read a model written by 'tactile-torch train --out' (SVMs) or 'tactile-torch cluster' "
        "and write the whole inference graph, with its metadata, to one .onnx file (dynamic batch).",
    )
    p.add_argument("--model", required=True, help="model file (model.npz) written by train or cluster")
    p.add_argument("--out", required=True, help="the .onnx file to write")
    p.add_argument(
        "--sensor-range",
        metavar="G",
        help="vibration models: the sensor's range in g, kept in the bundle (predict and stream reject "
        "samples beyond it; default: 5, the ADXL345 of the study)",
    )
    p.set_defaults(handler=_export)

    p = sub.add_parser(
        "predict",
        help="classify a data file with an exported ONNX pipeline (onnxruntime, no torch); print a class report",
    )
    p.add_argument("--model", required=True, help="the .onnx bundle written by tactile-torch export")
    add_data_options(p, sensor_range=False)  # predict's --range leaves windows out instead
    p.add_argument("--out", default="", help="also write the predicted labels and names to this .npz")
    p.add_argument("--batch", type=int, default=256, help="samples per onnxruntime call (default: 256)")
    p.add_argument("--threads", type=int, default=1, help="onnxruntime intra-op threads (default: 1)")
    p.add_argument(
        "--range",
        metavar="G",
        help="vibration: windows with a sample beyond +-G g are not classified; inf: off (default: the "
        "bundle's sensor_range_g, else 5)",
    )
    _add_allow_pickle(p)
    p.set_defaults(handler=_predict)

    p = sub.add_parser(
        "stream",
        help="classify a live serial accelerometer stream with an exported vibration bundle",
        description="Read 'x,y,z' or 't,x,y,z' lines (g) from a serial port (any pyserial URL, e.g. "
        "/dev/ttyUSB0, socket://host:port, loop://), cut them into the bundle's windows and print each "
        "window's class. Silence, disconnection, gaps in t, samples out of range and garbage lines are "
        "reported on stderr; no window spans a gap. Exit status: 0 done, 3 no data within the timeout, "
        "4 port failed (see docs/stream.md).",
    )
    p.add_argument("--model", required=True, help="the .onnx vibration bundle")
    p.add_argument("--port", required=True, help="serial port or pyserial URL")
    p.add_argument("--baud", type=int, default=230400, help="baud rate (default: 230400)")
    p.add_argument(
        "--step",
        type=_at_least(1, int),
        default=None,
        help="new samples between windows, >= 1 (default: half a window)",
    )
    p.add_argument(
        "--max-windows",
        type=_at_least(0, int),
        default=0,
        help="stop after this many windows (default: no limit)",
    )
    p.add_argument(
        "--threads", type=_at_least(0, int), default=1, help="onnxruntime intra-op threads (default: 1)"
    )
    p.add_argument(
        "--json", action="store_true", help="one JSON object per window on stdout (docs/stream.md)"
    )
    p.add_argument(
        "--vote",
        type=_at_least(1, int),
        default=1,
        help="also give the vote over the last N windows (default: 1, no vote)",
    )
    p.add_argument(
        "--vote-method",
        default="majority",
        choices=["majority", "mean"],
        help="majority of the labels, or argmax of the mean scores (default: majority)",
    )
    p.add_argument(
        "--reconnect", action="store_true", help="reopen the port with backoff when it fails (default: exit)"
    )
    p.add_argument(
        "--idle-timeout",
        "--timeout",
        type=_at_least(0),
        default=10.0,
        help="give up after this many seconds without a sample; 0: never (default: 10)",
    )
    p.add_argument(
        "--start-timeout",
        type=_at_least(0),
        default=60.0,
        help="wait this long for the first sample; 0: forever (default: 60)",
    )
    p.add_argument(
        "--silence",
        type=_at_least(0.01),
        default=0.5,
        help="seconds without a sample reported as a silence, which ends the window (default: 0.5)",
    )
    p.add_argument(
        "--range",
        help="reject samples beyond +-RANGE g; inf: off (default: the bundle's sensor_range_g, else 5 for the "
        "ADXL345)",
    )
    p.add_argument(
        "--time-unit",
        default="s",
        choices=["s", "ms", "us", "samples"],
        help="unit of the t field of t,x,y,z lines; 'samples' for a sample counter (default: s)",
    )
    p.add_argument(
        "--discover",
        type=int,
        default=0,
        metavar="N",
        help="clustering bundles: propose a new surface after N consecutive novel windows (default: off)",
    )
    p.set_defaults(handler=_stream)

    p = sub.add_parser(
        "simulate-sensor",
        help="emulate the serial accelerometer: write a recorded or synthetic recording as 'x,y,z' lines",
    )
    p.add_argument(
        "--port", default="", help="serial port or pyserial URL (e.g. the other end of a pty pair)"
    )
    p.add_argument(
        "--pty",
        action="store_true",
        help="instead of --port, open a pseudo-terminal and print the port to read",
    )
    p.add_argument("--data", default="", help="vibration .npz to play (default: a synthetic surface)")
    p.add_argument("--recording", type=int, default=0, help="index of the recording to play (default: 0)")
    p.add_argument(
        "--seconds",
        type=_in_range(0, MAX_SIMULATED_S),
        default=10.0,
        help=f"synthetic: length in seconds, at most {MAX_SIMULATED_S} (default: 10)",
    )
    p.add_argument(
        "--rate",
        type=_in_range(0, 1e6),
        default=800.0,
        help="sample rate (Hz) when the file has none, > 0 (default: 800)",
    )
    p.add_argument("--baud", type=int, default=230400, help="baud rate (default: 230400)")
    p.add_argument("--fast", action="store_true", help="write as fast as possible instead of in real time")
    p.add_argument("--timestamps", action="store_true", help="write 't,x,y,z' lines (t in seconds)")
    p.add_argument("--seed", type=int, default=0, help="synthetic: random seed (default: 0)")
    _add_allow_pickle(p)
    p.set_defaults(handler=_simulate_sensor)

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
        type=int,
        default=None,
        help="cross-validation folds (default: 5, or fewer when the data allow fewer; a number the data do "
        "not allow is an error)",
    )
    p.add_argument(
        "--window", type=int, default=None, help="vibration: reference window in samples (default: 800)"
    )
    p.add_argument("--windows", default="", help="vibration: window sizes to try (default: 200,400,800,1600)")
    p.add_argument(
        "--frame-rate", type=float, default=None, help="explorations: frames/s (default: file or 10)"
    )
    p.add_argument(
        "--threshold", default="auto", help="image threshold: auto (default), otsu, display or a number"
    )
    p.add_argument("--erosion", default="relative", help="erosion in pixels, or relative (default)")
    p.add_argument(
        "--contact",
        default="raises",
        choices=["raises", "lowers", "auto"],
        help="pressure maps: does contact raise (default) or lower the reading",
    )
    p.add_argument("--max-per-class", default="auto", help="samples kept per class (default: 60 quick, 300)")
    p.add_argument("--classifiers", default="", help="comma-separated subset of HM-SVM,SVC,LDA,kNN,NCM")
    p.add_argument(
        "--features", default="", help="comma-separated feature-set name prefixes (e.g. fused,top)"
    )
    p.add_argument(
        "--target",
        type=float,
        default=None,
        metavar="ACC",
        help="the accuracy a deployment needs: recommend the cheapest candidate whose interval's lower end "
        "reaches it (default: the one-standard-error rule; docs/tradeoff.md)",
    )
    p.add_argument(
        "--deploy",
        default="",
        metavar="NAME",
        help="also refit candidate NAME (as in tradeoff.json) on all the data and write OUT/<name>.onnx and .npz "
        "(the recommended one always goes to OUT/recommended.onnx)",
    )
    p.add_argument(
        "--csv-session",
        default="number",
        choices=["number", "file"],
        help="CSV logs: session from the file name's trailing number (felt_3.csv -> 3, default) or one per file",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
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
        "--backend",
        default=None,
        choices=["sequential", "loky", "threading", "multiprocessing", "dask"],
        help="where the cross-validation tasks run (default: this process; loky with --n-jobs); dask needs "
        "the optional extra dask",
    )
    p.add_argument("--n-jobs", type=int, default=None, help="parallel workers (-1: every core)")
    p.add_argument(
        "--scheduler",
        default=None,
        help="--backend dask: address of a running dask scheduler (tcp://host:8786)",
    )
    _add_allow_pickle(p)
    p.set_defaults(handler=_tradeoff)

    for p in sub.choices.values():  # --debug is accepted after the command too
        p.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an error"
        )
        p.add_argument(
            "--max-read-mb",
            type=_at_least(0.001),
            default=None,
            metavar="MB",
            help="refuse input files whose arrays would take more than MB MiB in memory (default: 1024; "
            "docs/formats.md)",
        )
    return parser


def _missing_train_modules() -> list[str]:
    import importlib.util

    def missing(name: str) -> bool:
        try:
            return importlib.util.find_spec(name) is None
        except (ImportError, ValueError):  # a broken or blocked installation counts as missing
            return True

    return [name for name in TRAIN_MODULES if missing(name)]


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    if isinstance(err, FileNotFoundError) and err.filename and not text.startswith(str(err.filename)):
        text = f"{err.filename}: {err.strerror or 'no such file'}"  # OSError's own "[Errno 2] ..." form
    return text or type(err).__name__


def _warning_line(prefix: str):
    """A ``warnings.showwarning`` that prints one line, ``<prefix>: warning: <message>``, on stderr:
    no file name, line number or source line (``--debug`` keeps Python's own format)."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        text = " ".join(str(message).split())
        print(f"{prefix}: warning: {text}", file=sys.stderr if file is None else file)

    return show


WRITES_OUT_FILE = ("train", "predict", "export")
"""Commands whose ``--out`` is one file: it is checked against their inputs before any work."""


def _check_out(args: argparse.Namespace) -> None:
    """Refuse an ``--out`` that is an input, a directory, a device or a symbolic link (one line, status 2)."""
    from .robot.safe_write import check_output_path

    out = getattr(args, "out", "")
    if args.command not in WRITES_OUT_FILE or not out:
        return
    inputs = list(getattr(args, "data", None) or [])
    inputs += [args.model] if getattr(args, "model", None) else []
    check_output_path(out, inputs=inputs, what="--out")


class _StdoutGuard:
    """``sys.stdout`` that survives a closed pipe (``tactile-torch train ... | head -1``).

    After the reader of the pipe has gone, further output is discarded (the descriptor is pointed
    at ``os.devnull``, so the interpreter's final flush does not fail either) and the command goes on
    to write its files.
    """

    def __init__(self, stream) -> None:
        self._stream = stream

    def _drop(self) -> None:
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, self._stream.fileno())
        finally:
            os.close(devnull)

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._drop()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._drop()
            try:
                self._stream.flush()
            except BrokenPipeError:
                pass

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _guard_stdout():
    """Return the ``sys.stdout`` to restore; wrap it in :class:`_StdoutGuard` when it is a real file."""
    original = sys.stdout
    try:
        original.fileno()
    except (AttributeError, OSError, ValueError):  # captured output (tests): nothing to guard
        return original
    sys.stdout = _StdoutGuard(original)
    return original


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status.

    Bad input (a missing, empty or malformed file, a model of the wrong kind, a missing optional
    dependency) prints one line ``tactile-torch <command>: <file>: <what is wrong>`` on stderr and
    returns :data:`BAD_INPUT_EXIT`; any other error prints one line and returns
    :data:`INTERNAL_ERROR_EXIT`. ``--debug`` shows the traceback instead. Warnings print as one line
    each (:func:`_warning_line`), with Python's own format under ``--debug``.
    """
    args = build_parser().parse_args(argv)
    debug = bool(getattr(args, "debug", False))
    prefix = f"tactile-torch {args.command}"
    with warnings.catch_warnings():  # restores the caller's warning display when the command ends
        if not debug:
            warnings.showwarning = _warning_line(prefix)
        return _run(args, prefix, debug)


def _run(args: argparse.Namespace, prefix: str, debug: bool) -> int:
    """Run the parsed command and map its errors to one line and an exit status (see :func:`main`)."""
    if args.command in NEEDS_TRAIN_EXTRA:
        missing = _missing_train_modules()
        if missing:
            print(
                f"{prefix}: needs the training extra, which is not installed here (missing: "
                f"{', '.join(missing)}): pip install 'tactile-torch[{TRAIN_EXTRA}]'",
                file=sys.stderr,
            )
            return BAD_INPUT_EXIT
    stdout = _guard_stdout()
    limit_before = os.environ.get(MAX_READ_ENV)
    if getattr(args, "max_read_mb", None) is not None:  # read by every reader (robot.npz.max_read_bytes)
        os.environ[MAX_READ_ENV] = repr(float(args.max_read_mb))
    try:
        _check_out(args)
        return int(args.handler(args))
    except KeyboardInterrupt:
        if debug:
            raise
        print(f"{prefix}: interrupted", file=sys.stderr)
        return 130
    except _Stopped:  # SIGTERM to stream before it was reading: nothing read, a requested end
        print(f"{prefix}: stopped by SIGTERM before reading", file=sys.stderr)
        return STREAM_STOPPED_EXIT
    except ModuleNotFoundError as err:
        if debug:
            raise
        if (err.name or "").split(".")[0] in TRAIN_MODULES:
            print(
                f"{prefix}: needs the training extra ({err.name} is not installed): "
                f"pip install 'tactile-torch[{TRAIN_EXTRA}]'",
                file=sys.stderr,
            )
            return BAD_INPUT_EXIT
        print(f"{prefix}: {_one_line(err)} (rerun with --debug for the traceback)", file=sys.stderr)
        return INTERNAL_ERROR_EXIT
    except (ValueError, TypeError, OSError) as err:
        if debug:
            raise
        print(f"{prefix}: {_one_line(err)}", file=sys.stderr)
        return BAD_INPUT_EXIT
    except MemoryError:
        if debug:
            raise
        print(
            f"{prefix}: not enough memory for this input (reads are bounded by --max-read-mb, "
            "docs/formats.md); use smaller files or a larger machine",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    except Exception as err:
        if debug:
            raise
        print(
            f"{prefix}: internal error: {type(err).__name__}: {_one_line(err)} (rerun with --debug for "
            "the traceback, and please report it)",
            file=sys.stderr,
        )
        return INTERNAL_ERROR_EXIT
    finally:
        sys.stdout = stdout
        if limit_before is None:
            os.environ.pop(MAX_READ_ENV, None)
        else:
            os.environ[MAX_READ_ENV] = limit_before


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
