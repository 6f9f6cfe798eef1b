"""Where the whole image chain's gradients can be trusted: float64 gradcheck over temperatures.

    python bench/gradcheck_sweep.py [--seeds 8] [--temperatures 0.02 0.05 0.1 0.2 0.5]

For each temperature, runs ``torch.autograd.gradcheck`` (full Jacobian, ``eps=1e-6``, ``atol=1e-5``,
``rtol=1e-3``) on ``exploration_features`` (erosion 2, threshold 0.5, edge threshold 0.5) with respect
to the frames, the threshold, the edge threshold and the temperature, on random frames and on pressed
blobs (``tests/image/test_soft_parameters.py``'s inputs: 2 frames of 6 x 6), one seed each, and
prints a Markdown table of how many seeds pass. docs/image.md quotes its output. Not part of
``make bench`` (about 30 s per check on one core).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tactile_torch import image  # noqa: E402
from tests.image.test_soft_parameters import scalar, soft_frames  # noqa: E402


def passes(temperature: float, seed: int, blob: bool) -> bool:
    """Whether the full-Jacobian gradcheck of the whole chain passes at this temperature and input."""

    def chain(x, threshold, edge_threshold, t):
        return image.exploration_features(
            x, threshold=threshold, erosion=2, edge_threshold=edge_threshold, temperature=t
        )

    args = (soft_frames(seed, blob=blob).requires_grad_(), scalar(0.5), scalar(0.5), scalar(temperature))
    return torch.autograd.gradcheck(chain, args, eps=1e-6, atol=1e-5, rtol=1e-3, raise_exception=False)


def main() -> None:
    """Print the table (one row per temperature)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--temperatures", type=float, nargs="+", default=[0.02, 0.05, 0.1, 0.2, 0.5])
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"| temperature | random frames (of {args.seeds}) | pressed blobs (of {args.seeds}) |")
    print("|---|---|---|")
    for t in args.temperatures:
        counts = [sum(passes(t, s, blob) for s in range(args.seeds)) for blob in (False, True)]
        print(f"| {t:g} | {counts[0]} | {counts[1]} |", flush=True)


if __name__ == "__main__":
    main()
