"""Benchmark of the exported pipelines: onnxruntime against the eager torch pipeline.

The three default pipelines (:func:`tactile_torch.default_bundles.build_default_bundles`: vibration window
→ HM-SVM, vibration window → Pitman-Yor component, exploration of 100 frames of 96 x 96 → HM-SVM) are
trained on the bundled synthetic data and exported. For each:

- latency of one sample (batch 1): median and p99 over many calls, onnxruntime with one intra-op
  thread (:class:`tactile_torch.robot.runtime.OnnxPipeline`, input validation included) against the eager
  torch pipeline at one thread; the targets are a W = 800 window under 1 ms and an
  exploration under 20 ms (median), both faster than eager torch;
- throughput (samples per second) on a batch, at one thread and at the default thread count;
- the file size, and the agreement of the labels (must be 1.0) and the largest score difference.
"""

from __future__ import annotations

import tempfile

import torch

from bench.common import threads, time_call
from tactile_torch.default_bundles import build_default_bundles
from tactile_torch.export.model_graph import compare_with_runtime
from tactile_torch.robot.runtime import OnnxPipeline

TITLE = "Exported pipelines: onnxruntime vs eager torch (latency at batch 1, throughput)"


def _measure(name: str, bundle, quick: bool) -> dict:
    image = name.startswith("image")
    one = bundle.raw[:1]
    batch = bundle.raw[: (8 if image else 256)]
    pipe = bundle.pipeline.eval()
    onnx_1 = OnnxPipeline(bundle.path, intra_op_threads=1)
    onnx_default = OnnxPipeline(bundle.path, intra_op_threads=0)
    agree, diff = compare_with_runtime(pipe, onnx_1, bundle.raw)
    labels = onnx_1.predict(bundle.raw)
    accuracy = float((labels == bundle.labels).mean()) if not name.endswith("pyp") else float("nan")
    n_calls = 20 if quick else (100 if image else 2000)
    x1, xb = torch.from_numpy(one), torch.from_numpy(batch)
    with torch.no_grad(), threads(1):
        ort_1 = time_call(lambda: onnx_1.predict_scores(one), repeat=n_calls, warmup=5)
        eager_1 = time_call(lambda: pipe(x1), repeat=n_calls, warmup=5)
        ort_tp = time_call(lambda: onnx_1.predict_scores(batch), repeat=5, warmup=1)
        eager_tp = time_call(lambda: pipe(xb), repeat=5, warmup=1)
    with torch.no_grad(), threads(None) as n_default:
        ort_tp_d = time_call(lambda: onnx_default.predict_scores(batch), repeat=5, warmup=1)
        eager_tp_d = time_call(lambda: pipe(xb), repeat=5, warmup=1)
        eager_1_d = time_call(lambda: pipe(x1), repeat=max(20, n_calls // 4), warmup=5)
    return {
        "pipeline": name,
        "input": "x".join(str(d) for d in one.shape[1:]),
        "onnx ms median (1 thr)": round(ort_1["median_s"] * 1e3, 3),
        "onnx ms p99 (1 thr)": round(ort_1["p99_s"] * 1e3, 3),
        "torch ms median (1 thr)": round(eager_1["median_s"] * 1e3, 3),
        "torch ms p99 (1 thr)": round(eager_1["p99_s"] * 1e3, 3),
        f"torch ms median ({n_default} thr)": round(eager_1_d["median_s"] * 1e3, 3),
        "speed-up vs torch (1 thr)": round(eager_1["median_s"] / ort_1["median_s"], 2),
        "batch": len(batch),
        "onnx samples/s (1 thr)": round(len(batch) / ort_tp["median_s"], 1),
        "torch samples/s (1 thr)": round(len(batch) / eager_tp["median_s"], 1),
        f"onnx samples/s ({n_default} thr)": round(len(batch) / ort_tp_d["median_s"], 1),
        f"torch samples/s ({n_default} thr)": round(len(batch) / eager_tp_d["median_s"], 1),
        "file KiB": round(bundle.path.stat().st_size / 1024, 1),
        "labels agree": agree,
        "max score diff (rel.)": float(f"{diff:.2g}"),
        "held-out accuracy": round(accuracy, 4),
    }


def run(quick: bool) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        bundles = build_default_bundles(tmp, quick=quick, random_state=0, log=lambda *_: None)
        rows = [_measure(name, bundle, quick) for name, bundle in bundles.items()]
    notes = [
        "Latency: one sample per call, median and p99 of the calls; onnxruntime through "
        "OnnxPipeline.predict_scores (input validation and dtype conversion included), torch: the eager "
        "InferencePipeline under no_grad. Targets: vibration-hmsvm (W = 800) < 1 ms and image-hmsvm "
        "(100 x 96 x 96 frames) < 20 ms median, both faster than eager torch.",
        "Models: trained by tactile_torch.default_bundles.build_default_bundles on the seeded synthetic data "
        "(28 surfaces, 60 s each; 20 explorations per class), exported with the dynamo exporter.",
        "labels agree / max score diff: onnxruntime against torch on every held-out sample "
        "(a batch size different from the export's); the difference is relative to max(|score|, 1), "
        "since the mixture's log responsibilities reach magnitudes of hundreds in float32.",
    ]
    return {"rows": rows, "notes": notes}
