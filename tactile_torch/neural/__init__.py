"""Learned models: small neural networks on the raw inputs, and a method-1 front end learned end to end.

* :mod:`.networks` - the torch networks (1-D CNN on vibration windows in two sizes, temporal CNN over
  the taxels of pressure maps, small CNN on an exploration's mean and maximum darkness);
* :mod:`.training` - mini-batch training with early stopping on an inner (grouped) validation split;
* :mod:`.estimators` - the scikit-learn classifiers around them (clone-able, seeded, ``predict_proba``);
* :mod:`.front_end` - method 1's soft preprocessing with its threshold and temperatures learned through
  the differentiable ops, under a multi-class hinge-loss head; :mod:`.cutoff` - method 2's spectral
  cut-off learned the same way;
Their comparison with the classical and int8 models on the same grouped folds is the trade-off's
(:mod:`tactile_torch.tradeoff.comparison`), and their ONNX bundles the export package's
(:func:`tactile_torch.export.export_classifier`).

docs/neural.md says what they are for and what they showed.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "cutoff": ("LearnedCutoffClassifier",),
        "estimators": ("ExplorationCNNClassifier", "TaxelCNNClassifier", "WindowCNNClassifier"),
        "front_end": ("LearnedFrontEndClassifier",),
    },
)
