"""Every file the trade-off writes agrees with its model, and the cost it reports is the deployed file's.

Whole studies on three data sets of the kinds users bring (a 4 x 4 fingertip's raw pressure maps, the
bundled generator's RGB explorations, stylus recordings), every candidate (classical, networks, learned
front ends): each candidate's timing file (what deploying its first-fold model writes) gives the fold
model's label on every held-out sample of that fold, ties of kNN included; and ``recommended.onnx``,
timed again here with the study's harness, runs at the latency the study reports for it.
"""

import numpy as np
import pytest

from tactile_torch.tradeoff import run_tradeoff
from tactile_torch.tradeoff.bundle import measure_file
from tactile_torch.tradeoff.inputs import TradeoffData, vibration_data

AGREEMENT = 0.995
"""The issue's bar: at least this share of a candidate's held-out labels equal its model's (every one, here)."""
TIMING_FACTOR = 3.0
"""Two medians of ``time_per_sample`` on one file differ by this factor at most: up to 1.6x between
timings of one file at a load of 13-14 on the shared 2-core machine (docs/tradeoff.md, "What is
measured": ``python -m bench.tradeoff_cnn_cost OUT_DIR``)."""


def _fingertip():
    from bench.tradeoff_sets import fingertip_explorations

    d = fingertip_explorations(n_frames=24, sessions=3, total=42, random_state=1)
    return TradeoffData(
        "pressure",
        tuple(str(c) for c in d["class_names"]),
        "fingertip",
        raw=d["frames"],
        labels=d["labels"],
        groups=d["groups"],
        rate_hz=float(d["rate_hz"]),
    )


def _images():
    from tactile_torch.data.images import make_explorations

    data = make_explorations(6, n_frames=8, frame_size=32, sensels=8, random_state=2)
    frames = np.ascontiguousarray(data.frames.numpy())  # (N, T, 3, H, W), as the study reads RGB frames
    return TradeoffData(
        "image", data.class_names, "images", raw=frames, labels=data.labels.numpy(), groups=data.groups.numpy(),
        rate_hz=10.0,
    )  # fmt: skip


def _vibration():
    from tactile_torch.data import make_vibration_recordings

    return vibration_data(make_vibration_recordings(4, duration_s=12, n_sessions=2, random_state=3), "stylus")


CASES = {
    "fingertip": (_fingertip, ["lda", "knn", "ncm", "svc", "hmsvm", "taxel-cnn"]),
    "images": (_images, ["lda", "knn", "ncm", "svc", "hmsvm", "image-cnn", "learned-front-end"]),
    "vibration": (_vibration, ["lda", "knn", "ncm", "svc", "hmsvm", "cnn-small", "learned-cutoff"]),
}


@pytest.mark.slow  # a quick study with networks per data set: 1-3 min each on a loaded 2-core machine
@pytest.mark.parametrize("case", sorted(CASES))
def test_every_candidates_file_gives_its_models_labels_and_the_deployed_cost_is_reported(tmp_path, case):
    make, classifiers = CASES[case]
    result = run_tradeoff(
        make(), out_dir=tmp_path, quick=True, classifiers=classifiers, progress=False, log=lambda *_: None,
        exhaustive=True,
    )  # fmt: skip
    checked = [r for r in result.rows if r["quantisation"] is None and r["onnx_agreement"] is not None]
    families = {r["family"] for r in checked}
    assert (
        len(checked) == len([r for r in result.rows if r["quantisation"] is None]) and "classical" in families
    )
    assert families - {"classical"}, "no learned candidate was exported"
    low = {r["name"]: r["onnx_agreement"] for r in checked if r["onnx_agreement"] < AGREEMENT}
    assert not low, f"files that disagree with their models on held-out samples: {low}"
    if result.recommended is None:
        return
    row = result.row(result.recommended)
    deployed = result.deployed[0]
    assert (
        row["measured_on"] == "recommended.onnx"
        and row["size_bytes"] == (tmp_path / "recommended.onnx").stat().st_size
    )
    s = result.inputs[result.result(result.recommended).candidate.input]
    again = measure_file(tmp_path / "recommended.onnx", s.X[:1], s.acquisition_s)["latency_ms"]
    assert 1 / TIMING_FACTOR <= again / row["latency_ms"] <= TIMING_FACTOR
    assert deployed["latency_ms"] == row["latency_ms"]
