"""Measure "unknown" through the files ``tactile-torch tradeoff`` deploys, family by family.

Runs the trade-off study on the first part of every recording (the rest is held in: known surfaces the
models never trained on), deploys every candidate of the chosen classifiers (classical, neural and their
int8 variants, :func:`tactile_torch.tradeoff.deploy.deploy_candidate`), re-exports each model file
(``tactile-torch export``'s path), and prints the share of held-in windows answered "unknown" and the
share of 200 windows of each signal no surface gives (:func:`tactile_torch.data.out_of_distribution.out_of_distribution_signals`:
zeros, constants, white noise, tones, square waves, a still sensor) answered "unknown". The numbers of
``docs/export.md`` ("Unknown as an answer").

Examples
--------
python export/measure_unknown_deployed.py                                  # 8 generated surfaces x 4 sessions
python export/measure_unknown_deployed.py --hapmat DIR --window 100        # HapMat IMU (real, 100 Hz)
python export/measure_unknown_deployed.py --borealtc DIR --window 100      # BorealTC IMU (real, 100 Hz)
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

TRAIN_SHARE = 0.7
"""Share of every recording the study trains on; the rest is held in."""


def _split(rec, share: float):
    """The recordings cut at ``share`` of their length: (training part, held-in part)."""
    from tactile_torch.data.vibration import VibrationRecordings

    first, rest = [], []
    for signal in rec.signals:
        cut = int(len(signal) * share)
        first.append(np.asarray(signal[:cut]))
        rest.append(np.asarray(signal[cut:]))

    def part(signals):
        return VibrationRecordings(
            signals=signals, labels=np.asarray(rec.labels), class_names=tuple(rec.class_names),
            rate_hz=float(rec.rate_hz), session=None if rec.session is None else np.asarray(rec.session),
        )  # fmt: skip

    return part(first), part(rest)


def main(argv: list[str] | None = None) -> int:
    from tactile_torch.data.out_of_distribution import out_of_distribution_signals
    from tactile_torch.export.model_graph import export_pipeline, pipeline_from_model
    from tactile_torch.export.parts import ExportPool
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.robot.stream.windows import window_recordings
    from tactile_torch.tradeoff.execution import execute_plan
    from tactile_torch.tradeoff.inputs import vibration_data
    from tactile_torch.tradeoff.runner import plan_tradeoff

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--hapmat", help="the hapmat_imu5 data set's directory")
    source.add_argument("--borealtc", help="the borealtc_imu data set's directory")
    parser.add_argument("--window", type=int, default=800, help="window in samples (default: 800)")
    parser.add_argument("--classifiers", default="lda,hmsvm,knn,cnn-small", help="the families to deploy")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    args = parser.parse_args(argv)
    if args.hapmat:
        from tactile_torch.data import load_hapmat_imu5

        rec, what = load_hapmat_imu5(args.hapmat), "HapMat IMU"
    elif args.borealtc:
        from tactile_torch.data import load_borealtc_imu

        rec, what = load_borealtc_imu(args.borealtc), "BorealTC IMU"
    else:
        from tactile_torch.data import make_vibration_recordings

        rec = make_vibration_recordings(8, duration_s=30, n_sessions=4, random_state=args.seed)
        what = "generator, 8 surfaces x 4 sessions x 30 s"
    train, held = _split(rec, TRAIN_SHARE)
    data = vibration_data(train, what)
    plan = plan_tradeoff(
        data, quick=False, windows=[args.window], features=["21"], classifiers=args.classifiers.split(","),
        random_state=args.seed, progress=False, log=lambda s: None,
    )  # fmt: skip
    cut = window_recordings(held.signals, args.window, args.window)
    junk = out_of_distribution_signals(200, args.window, rec.rate_hz, np.random.default_rng(args.seed + 1))
    print(f"{what}: W = {args.window}, {len(cut.windows)} held-in windows; share answered unknown")
    print("| file | held-in | " + " | ".join(junk) + " |")
    print("|---|---|" + "---|" * len(junk))
    with tempfile.TemporaryDirectory() as tmp, ExportPool(Path(tmp) / "parts", background=False) as pool:
        out = Path(tmp)
        result = execute_plan(
            plan,
            pool,
            out_dir=out,
            progress=False,
            log=lambda s: None,
            random_state=args.seed,
            exhaustive=True,
        )
        from tactile_torch.tradeoff.deploy import deploy_candidate

        files = []
        for r in result.results:
            if r.decision_s is None:
                continue
            d = deploy_candidate(result, r.candidate.name, out, pool, random_state=args.seed)
            files.append((r.candidate.name, d["onnx"]))
            if d["model_file"]:
                again = export_pipeline(
                    pipeline_from_model(d["model_file"]), Path(d["model_file"]).with_suffix(".re.onnx")
                )
                files.append((f"{r.candidate.name}, re-exported from its .npz", again))
        for name, path in files:
            bundle = OnnxPipeline(path)
            shares = [np.mean(bundle.predict(cut.windows) == -1)]
            shares += [np.mean(bundle.predict(x) == -1) for x in junk.values()]
            print(f"| {name} | " + " | ".join(f"{100 * v:.1f} %" for v in shares) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
