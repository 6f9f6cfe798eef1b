"""The ``tactile-torch`` command line.

Every subcommand of DESIGN.md is listed; the handlers import their modules lazily so that
``tactile-torch predict`` can run on a robot with onnxruntime and no torch.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

NOT_BUILT_EXIT = 2
"""Exit status when a command cannot do its work (e.g. ``bench`` outside a source checkout)."""


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
    print(
        f"{args.method}: trained on {len(model.train_index)}, tested on {len(model.test_index)} held-out samples"
    )
    _print_class_report(model.report)
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


def _cluster_data(args: argparse.Namespace):
    """Return (X, true labels or None, source, transform) of the cluster command's --data, or an error line."""
    import numpy as np
    import torch

    with np.load(args.data, allow_pickle=args.allow_pickle) as npz:
        keys = set(npz.files)
        labels = np.asarray(npz["labels"]) if "labels" in keys else None
        if "features" in keys:  # labels optional: clustering does not need them
            X = np.asarray(npz["features"])
            if X.ndim != 2 or (labels is not None and labels.shape != (len(X),)):
                shape = None if labels is None else labels.shape
                return f"{args.data}: 'features' must be (n, D) and 'labels' (n,), got {X.shape} and {shape}"
            return X, labels, {"kind": "features", "n_features": int(X.shape[1])}, None
        if "signals" not in keys:
            return f"{args.data} must hold vibration recordings ('signals') or a 'features' array (n, D), found {sorted(keys)}"
        if "rate_hz" not in keys:
            return f"{args.data}: vibration recordings need 'rate_hz' (the sample rate) next to 'signals'"
        try:
            signals = list(npz["signals"])
        except ValueError:
            return f"{args.data} stores recordings of different lengths as an object array: pass --allow-pickle if you trust it"
        rate = float(npz["rate_hz"])
        names = [str(c) for c in npz["class_names"]] if "class_names" in keys else None
    from .data.vibration import VibrationRecordings
    from .signal import ClusteringTransform, window_features

    # labels and class names are optional: without them every recording is its own "class" for the
    # window cutter, and no accuracy is reported
    codes = np.arange(len(signals)) if labels is None else np.unique(labels, return_inverse=True)[1]
    if names is None or labels is None:
        names = [str(v) for v in (np.arange(len(signals)) if labels is None else np.unique(labels))]
    rec = VibrationRecordings(signals=signals, labels=codes, class_names=tuple(names), rate_hz=rate)
    ds = rec.windows(args.window, args.step)
    if len(ds) == 0:
        return f"{args.data}: no recording holds --window {args.window} samples"
    feats = window_features(ds.windows.to(torch.float64))
    transform = ClusteringTransform(args.components).fit(feats)
    X = transform(feats).numpy()
    print(f"{args.data}: {len(X)} windows of {args.window} samples -> {X.shape[1]} principal components")
    source = {"kind": "vibration", "window": args.window, "step": args.step or args.window, "rate_hz": rate}
    return X, (None if labels is None else ds.labels.numpy()), source, transform


def _cluster(args: argparse.Namespace) -> int:
    import numpy as np

    from .metrics import pairwise_accuracy
    from .mixture import PitmanYorGMM
    from .pipeline import save_clustering_model

    data = _cluster_data(args)
    if isinstance(data, str):
        print(f"tactile-torch cluster: {data}", file=sys.stderr)
        return 2
    X, truth, source, transform = data
    init = int(args.init) if args.init.isdigit() else args.init
    model = PitmanYorGMM(
        alpha=args.alpha,
        discount=args.discount,
        n_iter=args.n_iter,
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
    save_clustering_model(out / "model.pt", model, source=source, transform=transform)
    summary = model.summary()
    if truth is not None:
        summary += (
            f"\npairwise accuracy: point estimate {pairwise_accuracy(truth, model.labels_):.4f}, "
            f"MAP sample {pairwise_accuracy(truth, model.map_labels_):.4f}"
        )
    (out / "summary.txt").write_text(summary + "\n")
    print(summary)
    print(
        f"written: {out / 'clustering.npz'}, {out / 'summary.txt'}, {out / 'model.pt'} (tactile-torch export: "
        f"the point estimate's {model.n_clusters_} components)"
    )
    return 0


def _export(args: argparse.Namespace) -> int:
    from .pipeline import export_pipeline, load_model_file, pipeline_from_model

    pipeline = pipeline_from_model(load_model_file(args.model))
    path = export_pipeline(pipeline, args.out)
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
    from .runtime import OnnxPipeline

    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    data = pipe.read_npz(args.data, allow_pickle=args.allow_pickle)
    labels = np.concatenate(
        [pipe.predict(data.raw[i : i + args.batch]) for i in range(0, len(data.raw), args.batch)]
    )
    print(f"{pipe!r}: {len(labels)} samples of {args.data}")
    if args.out:
        np.savez(args.out, labels=labels, names=np.array(pipe.class_names)[labels])
        print(f"labels written to {args.out}")
    if data.labels is None:
        counts = np.bincount(labels, minlength=len(pipe.class_names))
        for name, n in zip(pipe.class_names, counts, strict=True):
            print(f"{name:<24} {n:>7}")
        return 0
    if pipe.pipeline.endswith("-pyp"):
        from .metrics import pairwise_accuracy

        print(
            f"{len(np.unique(labels))} components used; pairwise accuracy {pairwise_accuracy(data.labels, labels):.4f}"
        )
        return 0
    known = data.labels >= 0
    if not known.all():
        print(f"{int((~known).sum())} samples of classes the model does not know are left out")
    n = len(pipe.class_names)
    _print_class_report(
        class_report(data.labels[known], labels[known], labels=np.arange(n), names=pipe.class_names)
    )
    return 0


def _stream(args: argparse.Namespace) -> int:
    # torch-free: pyserial, numpy and onnxruntime only, as on the robot.
    import time

    import serial

    from .runtime import OnnxPipeline
    from .stream import WindowReader

    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    if "window_size" not in pipe.metadata:
        print(f"tactile-torch stream: {args.model} does not take vibration windows", file=sys.stderr)
        return 2
    size = int(pipe.metadata["window_size"])
    step = args.step or size // 2
    port = serial.serial_for_url(args.port, baudrate=args.baud, timeout=args.timeout)
    reader = WindowReader(port, window_size=size, step=step, max_windows=args.max_windows or None)
    print(f"{pipe!r}: reading {args.port}, windows of {size} samples every {step}", flush=True)
    discovery = _stream_discovery(args, pipe)
    if isinstance(discovery, str):
        print(f"tactile-torch stream: {discovery}", file=sys.stderr)
        return 2
    for i, window in enumerate(reader):
        start = time.perf_counter()
        out = pipe.run(window)
        labels, scores = out["labels"], out["scores"]
        ms = (time.perf_counter() - start) * 1e3
        name = pipe.class_names[int(labels[0])] if pipe.class_names else str(int(labels[0]))
        if discovery is not None:
            verdict = discovery.update(int(labels[0]), bool(out["novel"][0]))
            name = verdict.name + (" (novel)" if verdict.novel else "")
            if verdict.proposed:
                print(
                    f"new surface proposed: {verdict.name} ({verdict.run} novel windows in a row)", flush=True
                )
        print(
            f"{i:>6} {reader.samples:>9} {name:<24} score {float(scores[0].max()):+.3f} ({ms:.2f} ms)",
            flush=True,
        )
    print(f"{reader.samples} samples read, {reader.skipped} lines skipped")
    port.close()
    return 0


def _stream_discovery(args: argparse.Namespace, pipe):
    """The stream's SurfaceDiscovery for --discover N (None without it), or an error line."""
    if not args.discover:
        return None
    from .discovery import NOVEL_OUTPUT, SurfaceDiscovery

    if NOVEL_OUTPUT not in [o.name for o in pipe.session.get_outputs()]:
        return f"--discover needs a clustering bundle with a '{NOVEL_OUTPUT}' output (tactile-torch cluster, then export)"
    return SurfaceDiscovery(args.discover, pipe.class_names)


def _simulate_sensor(args: argparse.Namespace) -> int:
    import numpy as np
    import serial

    from .stream import simulate_sensor

    if args.data:
        with np.load(args.data, allow_pickle=args.allow_pickle) as npz:
            signals, rate = npz["signals"], float(npz["rate_hz"]) if "rate_hz" in npz.files else args.rate
        recording = np.asarray(signals[args.recording], dtype=np.float32)
    else:
        from .data import make_vibration_recordings

        rec = make_vibration_recordings(28, duration_s=args.seconds, random_state=args.seed)
        recording, rate = rec.signals[args.recording % 28], rec.rate_hz
    port = serial.serial_for_url(args.port, baudrate=args.baud)
    print(f"writing {len(recording)} samples at {rate:g} Hz to {args.port}", flush=True)
    n = simulate_sensor(port, recording, rate_hz=rate, realtime=not args.fast)
    port.close()
    print(f"{n} samples written")
    return 0


def _add_allow_pickle(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--allow-pickle", action="store_true", help="allow object arrays in a trusted vibration .npz"
    )


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
    p.add_argument(
        "--full", action="store_true", help="also the study-size experiments (minutes, not seconds)"
    )
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
    _add_allow_pickle(p)
    p.set_defaults(handler=_train)

    p = sub.add_parser(
        "cluster",
        help="discover surfaces with the Pitman-Yor mixture (how many, and which window is which)",
        description="Fit tactile_torch.mixture.PitmanYorGMM to vibration recordings (windows -> 21 features -> "
        "the unsupervised transform -> principal components) or to a 'features' array (n, D); labels and "
        "class names are optional. Write the point estimate of the clustering (and the MAP sample, the "
        "posterior samples of K) to OUT/clustering.npz, a summary (posterior of K first) to OUT/summary.txt "
        "and the model to OUT/model.pt (for tactile-torch export).",
    )
    p.add_argument(
        "--data",
        required=True,
        help="vibration recordings .npz ('signals', 'rate_hz'; 'labels', 'class_names' optional), or "
        "'features' (n, D) and optionally 'labels' (n,)",
    )
    p.add_argument("--out", default="runs/cluster", help="output directory (default: runs/cluster)")
    p.add_argument("--window", type=int, default=800, help="recordings: window in samples (default: 800)")
    p.add_argument("--step", type=int, default=None, help="recordings: window hop (default: the window)")
    p.add_argument("--components", type=int, default=3, help="recordings: principal components (default: 3)")
    _add_allow_pickle(p)
    p.add_argument(
        "--n-iter", type=int, default=1000, help="Gibbs sweeps per chain, burn-in included (default: 1000)"
    )
    p.add_argument("--burn-in", type=int, default=250, help="sweeps discarded per chain (default: 250)")
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
    p.add_argument("--model", required=True, help="model file (model.pt) written by train or cluster")
    p.add_argument("--out", required=True, help="the .onnx file to write")
    p.set_defaults(handler=_export)

    p = sub.add_parser(
        "predict",
        help="classify a data file with an exported ONNX pipeline (onnxruntime, no torch); print a class report",
    )
    p.add_argument("--model", required=True, help="the .onnx bundle written by tactile-torch export")
    p.add_argument("--data", required=True, help=".npz of DESIGN.md's formats (frames, signals or features)")
    p.add_argument("--out", default="", help="also write the predicted labels and names to this .npz")
    p.add_argument("--batch", type=int, default=256, help="samples per onnxruntime call (default: 256)")
    p.add_argument("--threads", type=int, default=1, help="onnxruntime intra-op threads (default: 1)")
    _add_allow_pickle(p)
    p.set_defaults(handler=_predict)

    p = sub.add_parser(
        "stream",
        help="classify a live serial accelerometer stream with an exported vibration bundle",
        description="Read 'x,y,z' lines (g) from a serial port (any pyserial URL, e.g. /dev/ttyUSB0, "
        "socket://host:port, loop://), cut them into the bundle's windows and print each window's class.",
    )
    p.add_argument("--model", required=True, help="the .onnx vibration bundle")
    p.add_argument("--port", required=True, help="serial port or pyserial URL")
    p.add_argument("--baud", type=int, default=230400, help="baud rate (default: 230400)")
    p.add_argument("--step", type=int, default=0, help="new samples between windows (default: half a window)")
    p.add_argument(
        "--timeout", type=float, default=2.0, help="stop after this many silent seconds (default: 2)"
    )
    p.add_argument(
        "--max-windows", type=int, default=0, help="stop after this many windows (default: no limit)"
    )
    p.add_argument("--threads", type=int, default=1, help="onnxruntime intra-op threads (default: 1)")
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
        "--port", required=True, help="serial port or pyserial URL (e.g. the other end of a pty pair)"
    )
    p.add_argument("--data", default="", help="vibration .npz to play (default: a synthetic surface)")
    p.add_argument("--recording", type=int, default=0, help="index of the recording to play (default: 0)")
    p.add_argument("--seconds", type=float, default=10.0, help="synthetic: length in seconds (default: 10)")
    p.add_argument(
        "--rate", type=float, default=800.0, help="sample rate when the file has none (default: 800)"
    )
    p.add_argument("--baud", type=int, default=230400, help="baud rate (default: 230400)")
    p.add_argument("--fast", action="store_true", help="write as fast as possible instead of in real time")
    p.add_argument("--seed", type=int, default=0, help="synthetic: random seed (default: 0)")
    _add_allow_pickle(p)
    p.set_defaults(handler=_simulate_sensor)

    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    return int(args.handler(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
