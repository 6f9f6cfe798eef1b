"""Reproduce method 2's supervised part: an RBF SVM on the 21 scaled vibration features, C and gamma
by stratified 10-fold grid search, odd/even window split accuracy, features ranked by the accuracy
each reaches alone, and the agreement of our solver with libsvm on the real and synthetic sets;
or train the SVM on a vibration data file and save it.

    python train/method2_vibration_classification.py --out runs/method2            # bundled synthetic data
    python train/method2_vibration_classification.py --out runs/method2 --quick    # smoke run
    python train/method2_vibration_classification.py --data recordings.npz --out runs/mine --window 800

The logic lives in ``tactile_torch.studies.vibration_classification`` and ``tactile_torch.training``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tactile_torch.cli import main as cli
from tactile_torch.studies import run_report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", default="runs/method2", help="output directory")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="small data, for a smoke run")
    parser.add_argument(
        "--data", default="", help="train on this vibration .npz instead of running the study"
    )
    parser.add_argument("--window", default="800", help="window size in samples for --data (default 800)")
    parser.add_argument("--C", default="16", help="SVM C for --data (the study's 16)")
    parser.add_argument("--gamma", default="0.0186", help="SVM gamma for --data (the study's 0.0186)")
    args = parser.parse_args(argv)
    if args.data:
        model = str(Path(args.out) / "svm.pt")
        return cli(
            [
                "train",
                "--data",
                args.data,
                "--method",
                "svm",
                "--window",
                args.window,
                "--C",
                args.C,
                "--gamma",
                args.gamma,
                "--seed",
                str(args.seed),
                "--out",
                model,
            ]
        )
    only = ["vibration_features", "vibration_classification"]
    path = run_report(args.out, random_state=args.seed, quick=args.quick, only=only)
    print(f"report written to {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
