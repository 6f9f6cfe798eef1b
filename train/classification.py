"""Reproduce the supervised part of either study, or train its classifier on a data file.

    python train/classification.py image --out runs/method1          # method 1 on the bundled data
    python train/classification.py vibration --out runs/method2      # method 2 on the bundled data
    python train/classification.py image --quick --out runs/smoke    # a smoke run
    python train/classification.py vibration --data recordings.npz --out runs/mine

Without ``--data`` it writes the report sections of the study (``image``: HM-SVM vs LDA and kNN on
fused and unfused features, 5 rounds of 60/20/20 with C and gamma chosen on validation, class
report, McNemar, timing, robustness to feature and image noise; ``vibration``: the HM-SVM on the 21
scaled features, stratified 10-fold grid search, odd/even accuracy, feature ranking, agreement with
libsvm). With ``--data`` (a ``.npz`` of image explorations or vibration recordings) it trains the study's classifier on that file
(``tactile-torch train``) and saves it. The logic lives in ``tactile_torch.studies`` and
``tactile_torch.training``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tactile_torch.cli import main as cli
from tactile_torch.model_selection import VIBRATION_STUDY_C, VIBRATION_STUDY_GAMMA
from tactile_torch.studies import run_report

SECTIONS = {
    "image": ["image_features", "image_classification"],
    "vibration": ["vibration_features", "vibration_classification"],
}
# The classifier each study trains on a user's file, and its defaults (method 2: the study's C, gamma).
TRAIN = {
    "image": ["--method", "hmsvm"],
    "vibration": ["--method", "hmsvm", "--C", str(VIBRATION_STUDY_C), "--gamma", str(VIBRATION_STUDY_GAMMA)],
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("study", choices=sorted(SECTIONS), help="method 1 (image) or method 2 (vibration)")
    parser.add_argument("--out", default="runs/classification", help="output directory")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="small data, for a smoke run")
    parser.add_argument("--data", default="", help="train on this .npz instead of running the study")
    args, extra = parser.parse_known_args(argv)
    if args.data:
        model = str(Path(args.out) / f"{args.study}.npz")
        cmd = ["train", "--data", args.data, *TRAIN[args.study], "--seed", str(args.seed), "--out", model]
        return cli([*cmd, *extra])  # e.g. --window 400 --C 64 (later options win)
    path = run_report(args.out, random_state=args.seed, quick=args.quick, only=SECTIONS[args.study])
    print(f"report written to {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
