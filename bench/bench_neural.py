"""Benchmark of the learned models: training time, and latency, size and memory of their ONNX files,
float against int8 (static and dynamic).

Each network of :mod:`tactile_torch.neural` is trained on seeded synthetic data of its input (stylus
windows of W = 800, bundled explorations of 100 frames of 96 x 96, their pressure maps on a 12 x 12
array) for a fixed number of epochs (no early stopping: ``patience`` = epochs), exported, and quantised
both ways (:func:`tactile_torch.export.int8.quantise_bundle`, static calibrated on 32 training samples).
Rows: trained scalars, seconds per training epoch (the estimator's own thread setting: one intra-op
thread), onnxruntime latency at batch 1 (median, one thread, input validation included), file size,
peak memory of the session (:func:`tactile_torch.tradeoff.memory.peak_memory_mib`), and the share of
held-out labels the int8 file shares with the float one.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

TITLE = "Learned models: training time, ONNX latency, size and memory, float vs int8"


def _data(kind: str, quick: bool) -> tuple[np.ndarray, np.ndarray]:
    if kind == "windows":
        from tactile_torch.data.stylus import make_vibration_recordings

        rec = make_vibration_recordings(8, duration_s=10 if quick else 40, random_state=0)
        ds = rec.windows(800)
        return ds.windows.numpy(), ds.labels.numpy()
    from tactile_torch.data.images import make_explorations

    data = make_explorations(4 if quick else 12, random_state=0, keep_pressure=kind == "pressure")
    if kind == "pressure":
        return data.pressure.numpy().astype(np.float32), data.labels.numpy()
    return data.frames.numpy(), data.labels.numpy()


def run(quick: bool = False) -> dict:
    from tactile_torch.export import export_classifier
    from tactile_torch.export.int8 import quantise_bundle
    from tactile_torch.metrics import time_per_sample
    from tactile_torch.neural import ExplorationCNNClassifier, TaxelCNNClassifier, WindowCNNClassifier
    from tactile_torch.robot.runtime import OnnxPipeline
    from tactile_torch.tradeoff.memory import peak_memory_mib

    epochs = 3 if quick else 20
    models = [
        ("1-D CNN small", "windows", lambda: WindowCNNClassifier("small", learning_rate=1e-2)),
        ("1-D CNN large", "windows", lambda: WindowCNNClassifier("large")),
        ("temporal taxel CNN", "pressure", lambda: TaxelCNNClassifier(learning_rate=1e-2)),
        ("exploration CNN", "frames", lambda: ExplorationCNNClassifier(learning_rate=1e-2)),
    ]
    rows, cache = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, kind, make in models:
            if kind not in cache:
                cache[kind] = _data(kind, quick)
            X, y = cache[kind]
            train = np.arange(len(y)) % 4 != 3
            clf = make().set_params(max_epochs=epochs, patience=epochs, progress=False, random_state=0)
            start = time.perf_counter()
            clf.fit(X[train], y[train])
            per_epoch = (time.perf_counter() - start) / clf.n_epochs_
            path = export_classifier(clf, Path(tmp) / f"{kind}-{len(rows)}.onnx", X[:2])
            held = X[~train]
            float_labels = OnnxPipeline(path).predict(held)
            variants = [("float", path)]
            for mode in ("static", "dynamic"):
                q, _ = quantise_bundle(
                    path, Path(tmp) / f"{path.stem}-{mode}.onnx", calibration=X[train][:32], mode=mode
                )
                variants.append((f"int8 {mode}", q))
            for label, file in variants:
                pipe = OnnxPipeline(file)
                rows.append(
                    {
                        "model": name,
                        "variant": label,
                        "input": "x".join(map(str, X.shape[1:])),
                        "parameters": clf.n_parameters_,
                        "s per epoch": round(per_epoch, 3),
                        "latency ms (1 thr)": round(1e3 * time_per_sample(pipe.predict, held[:1]), 3),
                        "size KiB": round(file.stat().st_size / 1024, 1),
                        "memory MiB": round(peak_memory_mib(file, pipe.validate(held[:1])), 1),
                        "labels = float": round(float(np.mean(pipe.predict(held) == float_labels)), 3),
                        "accuracy": round(float(np.mean(clf.classes_[pipe.predict(held)] == y[~train])), 3),
                    }
                )
    notes = [
        f"{epochs} epochs each on a quarter-held-out split; accuracy is on that split (small data, not a study)",
        "memory: increase of the peak resident set of a child process when the session is created and run",
    ]
    return {"rows": rows, "notes": notes}
