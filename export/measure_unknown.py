"""Measure "unknown" through an exported bundle: held-in windows against signals no surface gives.

Trains an HM-SVM on the even windows of a data source, exports it, and prints the share of unknown
(label -1) among the odd (held-in) windows and among 200 windows each of zeros, constants, white noise,
pure tones and square waves (:func:`tactile_torch.data.out_of_distribution.out_of_distribution_signals`; the numbers of
``docs/export.md``, "Unknown as an answer").

Examples
--------
python export/measure_unknown.py                                   # 28 synthetic surfaces, W = 800
python export/measure_unknown.py --csv logs/*.csv --columns time,accel_x,accel_y,accel_z --window 100
python export/measure_unknown.py --csv terrain/*/imu_*.csv --columns time,ax,ay,az --scale 0.10197 \\
    --class-from parent --window 100
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import torch

from tactile_torch.data.out_of_distribution import out_of_distribution_signals
from tactile_torch.export.model_graph import export_pipeline, pipeline_from_model
from tactile_torch.features.files import FeatureSet
from tactile_torch.robot.files.formats import read_csv_recordings
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.robot.stream.windows import window_recordings
from tactile_torch.signal import window_features
from tactile_torch.training import save_model, train_classifier


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--csv", nargs="*", default=[], help="CSV logs (default: synthetic surfaces)")
    parser.add_argument("--columns", default="t,x,y,z", help="time and x, y, z column names")
    parser.add_argument("--scale", type=float, default=1.0, help="multiply accelerations by this (to g)")
    parser.add_argument("--class-from", choices=["name", "parent"], default="name", help="class of a log")
    parser.add_argument("--window", type=int, default=800, help="window in samples (default: 800)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    args = parser.parse_args(argv)
    if args.csv:
        names = [Path(p).parent.name for p in args.csv] if args.class_from == "parent" else None
        rec = read_csv_recordings(
            args.csv, class_names=names, columns=args.columns.split(","), scale=args.scale
        )
        signals, labels, classes, rate = rec.signals, rec.labels, rec.class_names, rec.rate_hz
    else:
        from tactile_torch.data import make_vibration_recordings

        rec = make_vibration_recordings(28, duration_s=30, random_state=args.seed)
        signals, labels = [np.asarray(s) for s in rec.signals], np.asarray(rec.labels)
        classes, rate = rec.class_names, rec.rate_hz
    cut = window_recordings(signals, args.window, args.window)
    X = window_features(torch.from_numpy(cut.windows)).double().numpy()
    y = labels[cut.recording]
    held = cut.position % 2 == 1  # odd windows: never trained on
    source = {"kind": "vibration", "window": args.window, "step": args.window, "rate_hz": float(rate)}
    train = FeatureSet(X[~held], y[~held], tuple(classes), source)
    model = train_classifier(train, "hmsvm", test_size=0.2, random_state=args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        path = save_model(Path(tmp) / "model.npz", model, train)
        bundle = OnnxPipeline(export_pipeline(pipeline_from_model(path), Path(tmp) / "model.onnx"))
        pred = bundle.classify(cut.windows[held])
        unknown = pred.labels == -1
        accuracy = float(np.mean(pred.labels[~unknown] == y[held][~unknown]))
        print(
            f"{int(held.sum())} held-in windows: {unknown.mean():.2%} unknown, accuracy of the rest {accuracy:.4f} "
            f"(threshold {bundle.ood_threshold:.3g} at the {float(bundle.metadata['ood_quantile']):.1%} quantile)"
        )
        rng = np.random.default_rng(args.seed + 1)
        for name, raw in out_of_distribution_signals(200, args.window, rate, rng).items():
            print(f"  {name:<24} {np.mean(bundle.predict(raw) == -1):7.1%} unknown")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
