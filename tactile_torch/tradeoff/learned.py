"""Learned models and int8 variants in the trade-off study, and the memory column.

* **Learned candidates** (:func:`learned_candidates`): the catalogue's learned models
  (:data:`tactile_torch.catalogue.LEARNED`) on the raw input they take, each a ``Pipeline`` whose
  ``features`` step is :class:`~tactile_torch.features.RawInput` (the raw input itself: nothing to fit, so the engine passes it
  on once for all folds) and whose ``classifier`` is the model. Default (full) set: vibration, the small
  and large 1-D CNN and the learned spectral cut-off on the reference window; image explorations, the
  exploration CNN and the learned method-1 front end; raw pressure maps, the temporal taxel CNN.
  ``quick``: none unless ``classifiers`` names them (then at most :data:`QUICK_EPOCHS` epochs): with
  the small CNN, ``tradeoff --quick`` on the bundled stylus recordings took 194 s, over its 2-minute
  budget. They are exported whole
  (:func:`tactile_torch.export.export_classifier`) and timed like the others.
* **int8** (:func:`add_int8_and_memory`): every exported candidate (``quick``: the learned ones) gets an
  int8 variant (:func:`tactile_torch.export.int8.quantise_bundle`: static, calibrated on 32 samples of
  each training fold; dynamic for the networks, whose labels static int8 kept only 0.55-0.60 of on the
  bundled and HapMat windows against 0.91-0.94 for dynamic; a classical bundle's classifier only, its
  feature graph staying in float, and none when that leaves nothing quantised, said in its notes), a
  candidate of its own: every fold's model is exported (a learned model's
  first-fold file rebound to the fold's weights, a classical head bound to the fold's tensors), quantised
  and scored on that fold's test samples; latency, size and memory are the first fold's file's.
  A classical candidate whose features are fitted per fold (raw pressure maps) gets none (its feature
  graph would be exported once per fold), said in its notes.
* **Memory** (``memory_mib``): the peak resident memory the onnxruntime session of the candidate's
  file adds at batch 1, in a child process (:func:`tactile_torch.tradeoff.memory.peak_memory_mib`);
  ``quick``: only for the Pareto front's candidates and the learned and int8 ones (a child process
  costs about a second).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sklearn.pipeline import Pipeline

from .. import catalogue
from ..features.transformers import RawInput
from ..robot.contract import CLASS_NAMES_KEY
from ..robot.files.naming import slug
from .candidates import is_learned

QUICK_EPOCHS = 30
"""Epochs of the networks under ``quick`` (early stopping may end them sooner)."""
CALIBRATION_SAMPLES = 32
"""Training samples of each fold that calibrate its static int8 quantisation."""
RAW_NAMES = {"windows": "raw window", "frames": "raw frames", "pressure": "raw maps"}


def learned_keys(kind: str, *, quick: bool) -> list[str]:
    """Return the catalogue keys of the learned candidates of a data kind (module notes)."""
    keys = {
        "vibration": ["cnn-small", "cnn-large", "learned-cutoff"],
        "image": ["image-cnn", "learned-front-end"],
        "pressure": ["taxel-cnn"],
    }
    # --quick leaves them out unless named: with the small CNN, `tradeoff --quick` on the bundled stylus
    # recordings took 194 s wall (137 CPU-s, load 3.5-6), over its 2-minute budget.
    return [] if quick else keys.get(kind, [])


def learned_candidates(
    kind: str,
    input_key: str,
    *,
    quick: bool = False,
    classifiers: list[str] | None = None,
    random_state: int = 0,
    threshold: float | str = "auto",
    window: int | None = None,
    progress: bool = True,
) -> list:
    """Return the learned :class:`~.candidates.Candidate`\\ s for ``kind`` on the raw input ``input_key``.

    ``classifiers`` (keys or names, as ``tradeoff --classifiers``) keeps only those named; without it
    the set of the module notes. ``threshold`` (the image pipeline's, when a float) starts the learned
    front end. ``progress``: the networks' own progress bars over their epochs (``tradeoff --quiet``
    turns them off with the others).
    """
    from .candidates import Candidate

    wanted = None
    if classifiers is not None:
        wanted = set()
        for name in classifiers:
            try:
                wanted.add(catalogue.resolve(name))
            except ValueError:
                continue
    keys = learned_keys(kind, quick=quick)
    if wanted is not None:
        keys = [k for k in catalogue.LEARNED if k in wanted and kind_of(k) == kind]
    raw = RAW_NAMES["windows" if kind == "vibration" else "frames" if kind == "image" else "pressure"]
    what = f"{raw}, W = {window}" if window else raw
    out = []
    for key in keys:
        params = {}
        entry = catalogue.entry(key)
        if entry.family == "neural":
            params = {"learning_rate": 1e-2 if key != "cnn-large" else 3e-3}
            if quick:
                params["max_epochs"] = QUICK_EPOCHS
        if key == "learned-front-end" and isinstance(threshold, float):
            params["threshold"] = threshold
        model = catalogue.make_classifier(key, random_state=random_state, **params)
        if "progress" in model.get_params():
            model.set_params(progress=progress)
        pipe = Pipeline([("features", RawInput()), ("classifier", model)])
        out.append(Candidate(f"{entry.name} | {what}", entry.name, what, input_key, pipe, key, None))
    return out


def kind_of(key: str) -> str:
    """Return the data kind (``"vibration"``, ``"image"``, ``"pressure"``) a learned model takes."""
    raw = catalogue.entry(key).raw_input[0]
    return {"windows": "vibration", "frames": "image", "pressure": "pressure"}[raw]


def _fold_file(res: object, k: int, first: Path, samples: object, parts: Path, fold_file) -> Path | None:
    """Return an ONNX file of fold ``k``'s model of ``res`` (the first fold's file for ``k == 0``)."""
    if k == 0:
        return first
    model = res.cv.models[k]
    path = parts / f"{first.stem}-fold{k}.onnx"
    test = samples.folds[k][1]
    if is_learned(model):
        from ..export.fitted import rebind

        clf = model.steps[-1][1]
        done = rebind(first, clf, np.ascontiguousarray(samples.X[test[:5]]), path)
        if done is not None:
            return done
        import onnx

        meta = {p.key: p.value for p in onnx.load(str(first)).metadata_props}
        from ..export import export_classifier

        names = __import__("json").loads(meta[CLASS_NAMES_KEY])
        return export_classifier(clf, path, np.ascontiguousarray(samples.X[test[:2]]), class_names=names)
    return fold_file(res.candidate, model, path)


class _NothingToQuantise(Exception):
    """The quantiser left a bundle as it was: no int8 variant to measure."""


def _quantised_folds(res: object, s: object, parts: Path, fold_file) -> tuple:
    """Quantise ``res``'s file of every fold and test it: ``(fold accuracies, the first fold's int8 file,
    its agreement with the float file, the mode, every sample's out-of-fold label)``; raises
    :class:`_NothingToQuantise` when the quantiser left the first fold's file as it was."""
    from ..export.int8 import CLASSIFIER_PREFIX, quantise_bundle, quantised_nodes
    from ..robot.runtime import OnnxPipeline

    first = Path(res.bare_file)
    fold_accuracy, q_first, agreement, mode = [], None, None, None
    predictions = np.full(len(s.y), -1, dtype=np.int64)
    for k, (train, test) in enumerate(s.folds):
        path = _fold_file(res, k, first, s, parts, fold_file)
        if path is None:
            raise ValueError("features fitted per fold: no int8 variant (one feature graph per fold)")
        calibration = OnnxPipeline(path).validate(np.ascontiguousarray(s.X[train[:CALIBRATION_SAMPLES]]))
        target = parts / f"{first.stem}-int8-{k}.onnx"
        # The networks get dynamic int8: static ranges from the calibration windows kept only
        # 0.55-0.60 of their labels on two data sets (docs/neural.md), dynamic 0.91-0.94. A
        # classical bundle quantises its classifier only: int8 activations of its feature graph
        # (a window's spectrum) lost the small vibration the features measure.
        mode = "dynamic" if res.family == "neural" else "static"
        prefix = None if is_learned(res.model) else CLASSIFIER_PREFIX
        q_path, mode = quantise_bundle(path, target, calibration=calibration, mode=mode, only_prefix=prefix)
        if k == 0 and not quantised_nodes(q_path):
            q_path.unlink()
            raise _NothingToQuantise()
        q = OnnxPipeline(q_path)
        labels = q.predict(s.X[test])
        classes = res.cv.models[k].steps[-1][1].classes_
        predictions[test] = classes[labels]
        fold_accuracy.append(float(np.mean(classes[labels] == s.y[test])))
        if k == 0:
            q_first = q_path
            agreement = float(np.mean(labels == OnnxPipeline(path).predict(s.X[test])))
    return fold_accuracy, q_first, agreement, mode, predictions


def add_int8_and_memory(
    results: list,
    samples: dict,
    out_dir: str | Path,
    *,
    fold_file,
    pool: object,
    quick: bool,
    progress: bool = True,
    notes: list | None = None,
) -> list:
    """Append the int8 variants to ``results`` (module notes); return ``results``.

    ``notes`` receives one line naming the candidates that get no variant (nothing to quantise).

    ``fold_file(candidate, model, path)`` writes a classical fold model's file (the trade-off's export pool) and
    returns its path, or ``None`` when it cannot (features fitted per fold). The variant's timing file is
    its first fold's quantised file with its "unknown" rule (:func:`~.bundle.finish_bundle`: a classical
    file keeps its float twin's rule, its features being float; a learned one's is fitted on the int8
    embedding), timed as every other (:func:`~.evaluation.measure_file`). Candidates stopped early get
    none.
    """
    import dataclasses

    from ..model_selection import progress_bar
    from .candidates import CandidateResult

    out_dir = Path(out_dir)
    parts = out_dir / "parts-int8"
    added, unchanged = [], []
    chosen = [
        r
        for r in results
        if r.onnx_file and r.bare_file and not r.stopped and (not quick or is_learned(r.model))
    ]
    for res in progress_bar(chosen, "int8", progress):
        s = samples[res.candidate.input]
        try:
            fold_accuracy, q_first, agreement, mode, predictions = _quantised_folds(res, s, parts, fold_file)
        except _NothingToQuantise:
            unchanged.append(res.candidate.name)
            continue
        except Exception as err:
            lines = [line for line in str(err).splitlines() if line.strip()]
            res.notes.append(f"int8: {type(err).__name__}: {(lines or [''])[-1][:200]}")
            continue
        from ..export.neural import EMBEDDING_OUTPUT
        from .bundle import finish_bundle, measure_file

        train = s.folds[0][0]
        try:
            timing, _ = finish_bundle(
                q_first,
                out_dir / f"{slug(res.candidate.name)}-int8.onnx",
                res.model,
                s.X[train],
                s.y[train],
                pool,
                # a rule on the embedding is fitted again on the int8 file's own; one on float features kept
                distance=None
                if res.distance is None or res.distance[3] == EMBEDDING_OUTPUT
                else res.distance,
            )
        except Exception as err:
            lines = [line for line in str(err).splitlines() if line.strip()]
            res.notes.append(f"int8: {type(err).__name__}: {(lines or [''])[-1][:200]}")
            continue
        cand = dataclasses.replace(res.candidate, name=f"{res.candidate.name} (int8)")
        variant = CandidateResult(
            cand,
            fold_accuracy,
            res.fit_s,
            None,
            onnx_agreement=agreement,
            onnx_file=timing.name,
            notes=[
                f"int8 ({mode}) copy of {res.candidate.name}; its agreement is with the float file's labels on "
                "the first fold"
            ],
            **measure_file(timing, np.ascontiguousarray(s.X[s.folds[0][1][:1]]), s.acquisition_s),
        )
        variant.predictions = predictions  # every sample's out-of-fold int8 label (per-unit intervals)
        variant.n_parameters = res.n_parameters
        variant.quantisation = mode
        variant.family = res.family
        variant.variant_of = res.candidate.name
        added.append(variant)
    results.extend(added)
    if unchanged and notes is not None:
        notes.append(
            f"int8: no variant of {len(unchanged)} classical candidate(s) ({', '.join(unchanged[:3])}"
            f"{', ...' if len(unchanged) > 3 else ''}): a classical file quantises its classifier only (its "
            "feature graph stays in float), and theirs holds no operator onnxruntime quantises"
        )
    import shutil

    shutil.rmtree(parts, ignore_errors=True)
    return results


def measure_memory(
    results: list, samples: dict, out_dir: str | Path, *, only: set[str] | None, progress: bool
) -> None:
    """Fill ``memory_mib`` of the results with a file (only those named in ``only`` when given)."""
    from ..model_selection import progress_bar
    from ..robot.runtime import OnnxPipeline
    from .memory import peak_memory_mib

    chosen = [r for r in results if r.onnx_file and (only is None or r.candidate.name in only)]
    for res in progress_bar(chosen, "memory", progress):
        s = samples[res.candidate.input]
        path = Path(out_dir) / res.onnx_file
        try:
            sample = OnnxPipeline(path).validate(np.ascontiguousarray(s.X[s.folds[0][1][:1]]))
            res.memory_mib = peak_memory_mib(path, sample)
        except Exception as err:
            res.notes.append(f"memory not measured: {type(err).__name__}: {str(err)[:200]}")


__all__ = [
    "CALIBRATION_SAMPLES",
    "QUICK_EPOCHS",
    "add_int8_and_memory",
    "kind_of",
    "learned_candidates",
    "learned_keys",
    "measure_memory",
]
