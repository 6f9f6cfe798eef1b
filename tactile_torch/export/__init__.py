"""The one export package: fitted estimators and model files to one ONNX bundle each.

Every ``.onnx`` file of the library is written here: :func:`export_onnx` (the dynamo exporter, a
dynamic batch, ``onnx.checker``, the metadata) and :func:`save_onnx` (a changed model, sealed with its
digest: :mod:`tactile_torch.robot.integrity`). The ONNX names come from
:mod:`tactile_torch.robot.contract`.

Modules: ``model_graph`` (the whole inference graph of a model file, :func:`pipeline_from_model`, and
:func:`export_pipeline`), ``classifier_inference`` (torch graphs of scikit-learn's baselines,
:func:`inference_module`), ``neural`` (a network's bundle, :func:`export_classifier`), ``parts`` (the
trade-off's candidates exported in parts and joined), ``fitted`` (the graph and bundle of any fitted
model the trade-off compares), ``int8`` (int8 copies, :func:`quantise_bundle`), ``ood_branch`` (the
"unknown" rule as a part of a bundle, :func:`attach_distance`). The SVMs' and the mixture's graphs
belong to their estimators (:mod:`tactile_torch.svm.inference`, ``tactile_torch.mixture._inference``).

Examples
--------
>>> import torch
>>> from tactile_torch.export import export_onnx, run_onnx
>>> path = export_onnx(torch.nn.ReLU(), (torch.randn(2, 3),), "relu.onnx")  # doctest: +SKIP
>>> run_onnx(path, torch.randn(5, 3))[0].shape                              # doctest: +SKIP
(5, 3)
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_onnx": ("export_onnx", "run_onnx", "save_onnx"),
        "model_graph": (
            "InferencePipeline",
            "compare_with_runtime",
            "export_pipeline",
            "pipeline_from_model",
        ),
        "neural": ("export_classifier",),
        "int8": ("quantise_bundle",),
        "classifier_inference": ("inference_module",),
        "ood_branch": ("attach_distance",),
    },
)
