"""Classical, neural, learned-front-end and int8 models on the same folds: accuracy, latency, size, memory.

:func:`compare_models` is the evaluation behind the report section "Does a learned model earn its
cost?" (:mod:`tactile_torch.studies.learned_models`). For every :class:`ModelSpec`:

* **accuracy**: out-of-fold predictions on the folds of a :class:`~tactile_torch.tradeoff.inputs.Samples`
  (grouped by recording, time block or object, as the trade-off study makes them); the interval is
  **group-level**: the accuracy of every held-out group (a group is tested once, by the model that did
  not see it), then mean and 95 % Student-t interval over the groups
  (:func:`~tactile_torch.tradeoff.selection.fold_interval`). Without groups, the folds take their place;
* **ONNX**: the first fold's model is exported (:func:`tactile_torch.export.fitted.export_model`); ``onnx_agreement`` is the share of
  equal labels between the file (onnxruntime) and the model on that fold's held-out samples, run at a
  batch size other than the export's; ``latency_ms`` the median time of
  :meth:`~tactile_torch.robot.runtime.OnnxPipeline.predict` on one sample (batch 1, one thread; input
  validation included: :func:`tactile_torch.metrics.time_per_sample`), ``size_bytes`` the file's size,
  ``memory_mib`` the peak resident memory the session adds (:func:`tactile_torch.tradeoff.memory.peak_memory_mib`);
* **int8** (``spec.int8``): every fold's model is exported and quantised both ways
  (:func:`tactile_torch.export.int8.quantise_bundle`: static, with 32 training samples of that fold
  as the calibration set, and dynamic), and each int8 file's labels on the held-out samples give its
  row's accuracy; ``onnx_agreement`` is then the share of labels equal to the float file's (first
  fold); latency, size and memory are measured like the float one's.

``n_parameters`` (:func:`tactile_torch.export.fitted.n_parameters`): the trained scalars of a network (plus the learned front-end settings), or for a
classical model the numbers its classifier stores (support vectors and coefficients, class means ...).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sklearn.base import clone

CALIBRATION_SAMPLES = 32
"""Training samples of each fold that calibrate the static int8 variant."""
PARITY_BATCH = 5
"""Held-out samples run through each exported file at once (the export traces a batch of 2)."""


@dataclass
class ModelSpec:
    """One model of a comparison.

    Attributes
    ----------
    name : str
    family : {"classical", "neural", "learned front end"}
    estimator : object
        Unfitted scikit-learn estimator taking the raw input (a neural classifier, a learned front end or a
        ``Pipeline`` whose first step is a features transformer with ``to_module``).
    int8 : bool
        Also evaluate its int8 variant.
    """

    name: str
    family: str
    estimator: object
    int8: bool = False


def _group_interval(correct: np.ndarray, groups: np.ndarray | None, folds: list) -> dict[str, float]:
    from .selection import fold_interval

    if groups is not None and len(np.unique(groups)) >= 2:
        units = [correct[groups == g].mean() for g in np.unique(groups)]
        by = "group"
    else:
        units = [correct[test].mean() for _, test in folds]
        by = "fold"
    mean, se, low, high = fold_interval(units)
    return {
        "accuracy": mean,
        "accuracy_se": se,
        "accuracy_low": low,
        "accuracy_high": high,
        "units": len(units),
        "by": by,
    }


def _measure(path: Path, raw: np.ndarray) -> dict[str, float]:
    from ..metrics import time_per_sample
    from ..robot.runtime import OnnxPipeline
    from .memory import peak_memory_mib

    pipe = OnnxPipeline(path)
    return {
        "latency_ms": 1e3 * time_per_sample(pipe.predict, raw[:1]),
        "size_bytes": int(path.stat().st_size),
        "memory_mib": peak_memory_mib(path, pipe.validate(raw[:1])),
    }


def _fit(estimator: object, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None) -> object:
    import inspect

    model = clone(estimator)
    if groups is not None and "groups" in inspect.signature(model.fit).parameters:
        return model.fit(X, y, groups=groups)
    return model.fit(X, y)


def compare_models(
    specs: list[ModelSpec],
    samples: object,
    class_names: list[str],
    out_dir: str | Path,
    *,
    log: Callable[[str], None] = print,
) -> list[dict]:
    """Evaluate every spec on ``samples`` (a trade-off ``Samples``: ``X``, ``y``, ``folds``, ``groups``);
    return one row per model and int8 variant (the fields of the module notes).

    Files go to ``out_dir`` (``<slug>.onnx``, ``<slug>-int8.onnx``).
    """
    from ..export.fitted import export_model, model_classes, n_parameters, rebind
    from ..export.int8 import MODES, quantise_bundle
    from ..robot.files.naming import slug
    from ..robot.runtime import OnnxPipeline

    out_dir = Path(out_dir)
    X, y, folds, groups = samples.X, samples.y, samples.folds, samples.groups
    rows = []
    for spec in specs:
        start = time.perf_counter()
        predicted = np.full(len(y), -1, dtype=np.int64)
        predicted_int8 = {mode: np.full(len(y), -1, dtype=np.int64) for mode in MODES}
        int8_first = {}
        fit_s, first, extra = [], None, {}
        for k, (train, test) in enumerate(folds):
            t0 = time.perf_counter()
            model = _fit(spec.estimator, X[train], y[train], None if groups is None else groups[train])
            fit_s.append(time.perf_counter() - t0)
            predicted[test] = model.predict(X[test])
            if k == 0:
                first = model
                path = export_model(model, out_dir / f"{slug(spec.name)}.onnx", X[train[:2]], class_names)
                raw = X[test[:PARITY_BATCH]]
                onnx_labels = model_classes(model)[OnnxPipeline(path).predict(raw)]
                agreement = float(np.mean(onnx_labels == model.predict(raw)))
                measured = _measure(path, X[test])
                if hasattr(model, "learned_settings"):
                    extra["settings"] = model.learned_settings()
            if spec.int8:
                fold_path = path
                if k > 0:
                    part = out_dir / "parts" / f"{slug(spec.name)}-{k}.onnx"
                    fold_path = rebind(path, model, X[test[:PARITY_BATCH]], part) or export_model(
                        model, part, X[train[:2]], class_names
                    )
                for mode in MODES:
                    q_path, _ = quantise_bundle(
                        fold_path,
                        out_dir / f"{slug(spec.name)}-int8-{mode}-{k}.onnx",
                        calibration=X[train[:CALIBRATION_SAMPLES]],
                        mode=mode,
                    )
                    q = OnnxPipeline(q_path)
                    predicted_int8[mode][test] = model_classes(model)[q.predict(X[test])]
                    if k == 0:  # agreement of the int8 labels with the float file's on the held-out samples
                        same = q.predict(X[test]) == OnnxPipeline(fold_path).predict(X[test])
                        int8_first[mode] = (q_path, float(np.mean(same)))
        correct = predicted == y
        row = {
            "name": spec.name,
            "family": spec.family,
            "n_parameters": n_parameters(first),
            **_group_interval(correct, groups, folds),
            "fit_s": float(np.mean(fit_s)),
            "onnx_agreement": agreement,
            **measured,
            "onnx_file": path.name,
            "quantisation": None,
            **extra,
        }
        rows.append(row)
        log(f"[learned] {spec.name}: accuracy {row['accuracy']:.3f} ({time.perf_counter() - start:.1f} s)")
        for mode, (q_path, agree) in int8_first.items():
            rows.append(
                {
                    **row,
                    "name": f"{spec.name} (int8 {mode})",
                    **_group_interval(predicted_int8[mode] == y, groups, folds),
                    "onnx_agreement": agree,
                    **_measure(q_path, X[folds[0][1]]),
                    "onnx_file": q_path.name,
                    "quantisation": mode,
                }
            )
    return rows


__all__ = [
    "PARITY_BATCH",
    "ModelSpec",
    "compare_models",
]
