"""The deployed 4 x 4 temporal CNN against its bare network, timed by the trade-off's harness (issue 39).

The fingertip set of ``bench/tradeoff_sets.py`` (186 explorations of 200 frames, 7 fabrics), a quick
study of the temporal CNN alone, the CNN deployed as the study deploys it (refitted on all the data, its
"unknown" rule on its embedding: ``tactile_torch.tradeoff.bundle``) and its bare network
(``export_classifier`` of the study's first-fold model); both files timed in turns by
``tactile_torch.tradeoff.bundle.measure_file`` (median of ``OnnxPipeline.predict`` on one exploration,
one thread), ``--repeats`` times. The issue's goal: the deployed file within 2x the bare network.

    python -m bench.tradeoff_cnn_cost OUT_DIR [--repeats 5]     # from the repository root
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

CNN = "temporal CNN | raw maps"


def measure(out: Path, repeats: int) -> list[tuple[float, float]]:
    """Return ``(deployed ms, bare ms)`` per repeat (the study's and the files' in ``out``)."""
    from bench.tradeoff_sets import fingertip_explorations
    from tactile_torch.export import export_classifier
    from tactile_torch.tradeoff import run_tradeoff
    from tactile_torch.tradeoff.bundle import measure_file
    from tactile_torch.tradeoff.inputs import TradeoffData

    d = fingertip_explorations()
    data = TradeoffData(
        "pressure", tuple(str(c) for c in d["class_names"]), "fingertip", raw=d["frames"], labels=d["labels"],
        groups=d["groups"], rate_hz=float(d["rate_hz"]),
    )  # fmt: skip
    result = run_tradeoff(
        data,
        out_dir=out,
        quick=True,
        classifiers=["taxel-cnn"],
        progress=False,
        deploy=[CNN],
        log=lambda *_: None,
    )
    res = result.result(CNN)
    s = result.inputs[res.candidate.input]
    deployed = next(d for d in result.deployed if d["name"] == CNN)["onnx"]
    bare = export_classifier(res.model.steps[-1][1], out / "bare-cnn.onnx", s.X[:2])
    one = s.X[:1]
    return [
        (
            measure_file(deployed, one, s.acquisition_s)["latency_ms"],
            measure_file(bare, one, s.acquisition_s)["latency_ms"],
        )
        for _ in range(repeats)
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="directory for the study's files")
    parser.add_argument("--repeats", type=int, default=5, help="timings of each file, in turns (default: 5)")
    args = parser.parse_args()
    pairs = measure(args.out, args.repeats)
    for deployed, bare in pairs:
        print(f"deployed {deployed:.3f} ms, bare {bare:.3f} ms, ratio {deployed / bare:.2f}")
    print(f"median ratio {np.median([a / b for a, b in pairs]):.2f}")


if __name__ == "__main__":
    main()
