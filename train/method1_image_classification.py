"""Reproduce method 1's supervised part: HM-SVM vs LDA and kNN on fused and unfused tactile-image
features (5 rounds of 60/20/20, C and gamma chosen on validation, class report, McNemar, timing,
robustness to feature and image noise), then train the HM-SVM on a data file and save it.

    python train/method1_image_classification.py --out runs/method1            # bundled synthetic data
    python train/method1_image_classification.py --out runs/method1 --quick    # smoke run
    python train/method1_image_classification.py --data explorations.npz --out runs/mine

With ``--data`` (an image ``.npz`` of DESIGN.md), the report is skipped and the HM-SVM is trained on
that file (``tactile-torch train``); the study itself runs on the bundled data. The logic lives in
``tactile_torch.studies.image_classification`` and ``tactile_torch.training``.
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
    parser.add_argument("--out", default="runs/method1", help="output directory")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="small data, for a smoke run")
    parser.add_argument("--data", default="", help="train on this image .npz instead of running the study")
    parser.add_argument("--C", default="16", help="HM-SVM C for --data (default 16)")
    parser.add_argument("--gamma", default="scale", help="HM-SVM gamma for --data (default 'scale')")
    args = parser.parse_args(argv)
    if args.data:
        model = str(Path(args.out) / "hmsvm.pt")
        return cli(
            [
                "train",
                "--data",
                args.data,
                "--method",
                "hmsvm",
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
    path = run_report(
        args.out, random_state=args.seed, quick=args.quick, only=["image_features", "image_classification"]
    )
    print(f"report written to {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
