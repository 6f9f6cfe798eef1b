"""One ONNX file per candidate, exported in parts: the feature graph once per feature set, the classifier
graph once per classifier structure, joined per candidate.

Exporting a whole pipeline with the dynamo exporter costs seconds (most of it the feature graph), and
a study has dozens of candidates that share a handful of feature graphs. So (:class:`ExportPool`):

* the **front** (raw input → features: :meth:`to_module` of the ``features`` step) is exported once
  per feature set with :func:`tactile_torch.export.export_onnx`;
* the **head** (features → selected columns → standardisation → classifier → labels, scores) is
  exported once per *structure*, with every fitted tensor (support vectors, coefficients, means,
  column indices ...) as a graph input of dynamic size; each candidate's values are then bound as
  initializers. Candidates whose head has the same structure (module types, their non-tensor settings,
  which tensor dimensions are 1) share one export. An RBF SVM's ``gamma`` is folded into the
  standardisation (``exp(-g ||x - s||^2) = exp(-||sqrt(g) x - sqrt(g) s||^2)``), so that SVMs that
  differ only in ``gamma`` share one too;
* :func:`join` merges front and head (:func:`onnx.compose.merge_models`) into the candidate's file,
  with the metadata :class:`~tactile_torch.robot.runtime.OnnxPipeline` reads; ``onnx.checker`` validates it;
* the exports run at most once per key, the feature graphs in a background process while the study
  cross-validates.

The result computes what the fitted ``Pipeline`` computes (the study checks the labels of every
candidate's file against the pipeline's on held-out samples).
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..robot.contract import FEATURES_NAME, INPUT_NAME, LABELS_OUTPUT, SCORES_OUTPUT, metadata_strings
from ._onnx import drop_unused_initializers, export_onnx, save_onnx, unsealed


class Standardize(nn.Module):
    """``(x - mean) / scale`` in the buffers' dtype (float64: the classifiers run in float64)."""

    def __init__(self, mean: object, scale: object) -> None:
        super().__init__()
        self.register_buffer("mean", torch.as_tensor(np.asarray(mean), dtype=torch.float64).clone())
        self.register_buffer("scale", torch.as_tensor(np.asarray(scale), dtype=torch.float64).clone())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x.to(self.mean.dtype) - self.mean) / self.scale


class _Lifted(nn.Module):
    """``module`` with its buffers taken as inputs: ``forward(x, *buffers)``."""

    def __init__(self, module: nn.Module) -> None:
        super().__init__()
        self.module = module
        self.names = [name for name, _ in module.named_buffers()]

    def forward(self, x: torch.Tensor, *buffers: torch.Tensor) -> object:
        return torch.func.functional_call(self.module, dict(zip(self.names, buffers, strict=True)), (x,))


def _settings(module: nn.Module) -> tuple:
    """What, besides its tensors' values, fixes the graph of ``module``: types, plain attributes, unit dims."""
    out = []
    for name, sub in module.named_modules():
        plain = sorted(
            (k, v)
            for k, v in vars(sub).items()
            if not k.startswith("_") and k != "training" and isinstance(v, bool | int | float | str)
        )
        out.append((name, type(sub).__qualname__, tuple(plain)))
    for name, buf in module.named_buffers():
        out.append((name, str(buf.dtype), tuple(int(s) == 1 for s in buf.shape)))
    return tuple(out)


def absorb_rbf_gamma(scale: Standardize, head: nn.Module) -> None:
    """Fold an RBF ``head``'s ``gamma`` into ``scale`` (in place), leaving the outputs unchanged.

    For a head with ``kernel == "rbf"``, a float ``gamma`` and a ``support_vectors`` buffer (the
    package's :class:`~tactile_torch.svm.SVMInference`): the support vectors and the inputs are
    multiplied by ``sqrt(gamma)`` and ``gamma`` becomes 1. Any other head is left alone.
    """
    gamma = getattr(head, "gamma", None)
    if getattr(head, "kernel", None) != "rbf" or not isinstance(gamma, float) or gamma == 1.0:
        return
    if not isinstance(getattr(head, "support_vectors", None), torch.Tensor):
        return
    root = math.sqrt(gamma)
    head.support_vectors = head.support_vectors * root
    head.gamma = 1.0
    scale.scale = scale.scale / root


DEPTH_STEP = 8
"""Tree heads are exported with their depth rounded up to a multiple of this, so that trees of nearby
depths share one graph (a leaf points to itself, so extra descent steps leave every sample where it is)."""


def share_tree_depth(head: nn.Module) -> None:
    """Round a tree head's ``depth`` (descent steps) up to a multiple of :data:`DEPTH_STEP`, in place."""
    depth = getattr(head, "depth", None)
    if getattr(head, "mode", None) == "tree" and isinstance(depth, int) and depth > 0:
        head.depth = -(-depth // DEPTH_STEP) * DEPTH_STEP


def export_front(step: object, example: np.ndarray, path: str | Path) -> Path:
    """Export the fitted ``features`` step's module (input ``raw``, dynamic batch; output ``features``).

    Takes the scikit-learn step, not its module, so that a background process builds the module
    itself (:class:`~tactile_torch.image.ExplorationFeatures` prepares its export when constructed).
    """
    example = np.ascontiguousarray(example[:2])
    if (
        example.dtype == np.float64
    ):  # onnxruntime pipelines take float32 (tactile_torch.robot.runtime casts to it)
        example = example.astype(np.float32)
    return export_onnx(
        step.to_module().eval(),
        (torch.from_numpy(example),),
        path,
        input_names=[INPUT_NAME],
        output_names=[FEATURES_NAME],
    )


def head_key(modules: list[nn.Module], n_inputs: int) -> tuple:
    """The structure of a head: heads with equal keys share one exported graph."""
    return _settings(nn.Sequential(*modules)), n_inputs == 1


def export_head(
    modules: list[nn.Module],
    n_inputs: int,
    path: str | Path,
    *,
    output_names: tuple[str, ...] = (LABELS_OUTPUT, SCORES_OUTPUT),
) -> Path:
    """Export ``nn.Sequential(*modules)`` with every buffer as an input of dynamic size to ``path``.

    Inputs: ``features`` ``(B, n_inputs)`` and one per buffer (named after it); outputs ``labels``
    and ``scores`` (or ``output_names``: the "unknown" rule's distance part has one,
    ``ood_distance``). :func:`bind_head` turns the buffer inputs into a candidate's initializers.
    """
    lifted = _Lifted(nn.Sequential(*modules).eval())
    buffers = dict(lifted.module.named_buffers())
    example = torch.zeros(2, n_inputs, dtype=torch.float32)
    values = tuple(buffers[name] for name in lifted.names)
    # Every dimension dynamic, except those of size 1 (torch.export specialises them: they are in the key).
    dims = [
        {i: torch.export.Dim.DYNAMIC for i in range(t.ndim) if t.shape[i] > 1} for t in (example, *values)
    ]
    return export_onnx(
        lifted,
        (example, *values),
        path,
        input_names=[FEATURES_NAME, *lifted.names],
        output_names=list(output_names),
        dynamic_shapes=(dims[0], tuple(dims[1:])),
    )


def export_fixed_head(modules: list[nn.Module], n_inputs: int, path: str | Path) -> Path:
    """Export ``nn.Sequential(*modules)`` with its fitted tensors as constants (the fallback when a
    structure cannot be exported with free sizes); input ``features`` ``(B, n_inputs)``."""
    return export_onnx(
        nn.Sequential(*modules).eval(),
        (torch.zeros(2, n_inputs, dtype=torch.float32),),
        path,
        input_names=[FEATURES_NAME],
        output_names=[LABELS_OUTPUT, SCORES_OUTPUT],
    )


def bind_head(template: object, modules: list[nn.Module]) -> object:
    """Return a copy of an exported head ``template`` with the buffers of ``modules`` as initializers."""
    import onnx
    from onnx import numpy_helper

    model = onnx.ModelProto()
    model.CopyFrom(template)
    graph = model.graph
    bound = {name: b.detach().cpu().numpy() for name, b in nn.Sequential(*modules).named_buffers()}
    kept = [i for i in graph.input if i.name not in bound]
    for name, value in bound.items():
        graph.initializer.append(numpy_helper.from_array(np.ascontiguousarray(value), name))
    del graph.input[:]
    graph.input.extend(kept)
    # Buffers the graph does not read (the one-vs-one SVM's n_support, kept for its model file) would
    # make onnxruntime log a warning at every session start.
    drop_unused_initializers(model)
    return model


def join(front: object, head: object, path: str | Path, metadata: dict[str, object]) -> Path:
    """Join ``front`` and ``head`` into one checked ONNX file at ``path`` with ``metadata``; return it."""
    import onnx
    from onnx import compose

    # the parts were written sealed, each with its own digest: merge_models refuses two values of one
    # key, and the joined file gets its own (save_onnx)
    front, head = (unsealed(part) for part in (front, head))
    head = compose.add_prefix(head, "head.", rename_outputs=False)
    model = compose.merge_models(front, head, io_map=[(FEATURES_NAME, f"head.{FEATURES_NAME}")])
    for key, value in metadata_strings(metadata).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model)  # the parts were fully checked (shapes inferred) when exported
    return save_onnx(model, path)  # atomic; never onto a directory, a device or a symbolic link


class ExportPool:
    """Runs the dynamo exports of a study, at most once per key, some of them in a background process.

    With ``background=True`` a second Python process (:mod:`~tactile_torch.tradeoff._worker`, a plain subprocess) takes the
    jobs :meth:`submit` sends it while this one goes on (cross-validation, the heads): on a machine
    with a free core the slow feature-graph exports overlap the rest of the study. Jobs travel as
    pickles in a private temporary directory (written by this process, read by its child). Use it as
    a context manager.

    Parameters
    ----------
    parts_dir : path
        Where exported parts are written (removed on exit).
    background : bool
    """

    def __init__(self, parts_dir: str | Path, *, background: bool = True) -> None:
        self.parts_dir = Path(parts_dir)
        self.background = background
        self._process = None
        self._private = None
        self._jobs: dict[object, object] = {}
        self._queue: list[object] = []  # keys sent to the background process, in order
        self._answers: dict[object, str] = {}
        self._models: dict[object, object] = {}
        self.exports = 0

    def __enter__(self) -> ExportPool:
        self.parts_dir.mkdir(parents=True, exist_ok=True)
        if self.background:
            import subprocess
            import sys
            import tempfile

            self._private = Path(tempfile.mkdtemp(prefix="tactile-torch-export-"))
            self._process = subprocess.Popen(
                [sys.executable, "-m", "tactile_torch.tradeoff._worker"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                text=True,
                bufsize=1,
            )
        return self

    def __exit__(self, *exc: object) -> None:
        import shutil

        if self._process is not None:
            if exc[0] is not None:  # an error here: the queued exports are not wanted any more
                self._process.kill()
            with contextlib.suppress(OSError):  # a process that died has left a broken pipe
                self._process.stdin.close()
            self._process.wait()
            self._process.stdout.close()
        if self._private is not None:
            shutil.rmtree(self._private, ignore_errors=True)
        for path in self.parts_dir.glob("part-*.onnx"):
            path.unlink()
        with contextlib.suppress(OSError):
            self.parts_dir.rmdir()

    def submit(self, key: object, fn, *args: object, background: bool = True) -> None:
        """Queue ``fn(*args, path)`` (an export that writes ``path``) under ``key``, unless already queued."""
        import pickle

        if key in self._jobs:
            return
        path = self.parts_dir / f"part-{len(self._jobs)}.onnx"
        self.exports += 1
        self._jobs[key] = (fn, (*args, path))
        if self._process is None or not background:
            return
        job = self._private / f"job-{len(self._jobs)}.pkl"
        job.write_bytes(pickle.dumps((fn, (*args, path))))
        try:
            self._process.stdin.write(f"{job}\n")
            self._process.stdin.flush()
        except OSError:  # the background process is gone: the job runs here when needed
            return
        self._queue.append(key)

    def _wait(self, key: object) -> Path | None:
        """The background answer for ``key``: its file, or ``None`` if it failed there."""
        while key not in self._answers:
            line = self._process.stdout.readline()
            if not line:  # the process died: what it had not answered runs here
                self._answers.update((k, "error") for k in self._queue if k not in self._answers)
                break
            self._answers[self._queue[len(self._answers)]] = line.rstrip("\n")
        status, _, message = self._answers[key].partition(" ")
        return Path(message) if status == "ok" else None

    def result(self, key: object) -> object:
        """Return the ONNX model of job ``key``.

        A job that was not sent to the background, or that failed there, runs here; an error is
        raised again for every later request of the same key (no second attempt).
        """
        import onnx

        if key not in self._models:
            fn, args = self._jobs[key]
            path = self._wait(key) if key in self._queue else None
            try:
                self._models[key] = onnx.load(str(path if path is not None else fn(*args)))
            except Exception as err:
                self._models[key] = err
        if isinstance(self._models[key], Exception):
            raise self._models[key]
        return self._models[key]


def head_modules(model: object) -> list:
    """Return the fitted steps of a ``Pipeline`` after ``features`` as torch modules: selection,
    standardisation, classifier (the head :func:`export_head` exports).

    A learned candidate (:mod:`~tactile_torch.tradeoff.learned`) has no such head: it is exported whole. The one builder of
    heads from fitted pipelines: the trade-off's export, its deployment, touch times and the
    learned-model comparison (:mod:`tactile_torch.tradeoff.comparison`) all call it.
    """
    from ..features.transformers import ColumnSelect
    from .classifier_inference import inference_module

    modules = []
    if "select" not in model.named_steps:  # an identity selection: heads with and without one share a graph
        n = model.named_steps["scale"].n_features_in_
        modules.append(ColumnSelect(np.arange(n)))
    for name, step in model.steps[1:]:
        if name == "classifier":
            head = inference_module(step)
            if modules and isinstance(modules[-1], Standardize):
                absorb_rbf_gamma(modules[-1], head)
            share_tree_depth(head)
            modules.append(head)
        elif hasattr(step, "to_module"):
            modules.append(step.to_module())
        elif hasattr(step, "scale_") and hasattr(step, "mean_"):  # StandardScaler
            modules.append(Standardize(step.mean_, step.scale_))
        else:
            raise TypeError(f"pipeline step {name!r} ({type(step).__name__}) has no export path")
    return modules


__all__ = [
    "DEPTH_STEP",
    "ExportPool",
    "Standardize",
    "absorb_rbf_gamma",
    "bind_head",
    "export_fixed_head",
    "export_front",
    "export_head",
    "head_key",
    "head_modules",
    "join",
    "share_tree_depth",
]
