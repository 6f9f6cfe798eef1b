"""Nearest-neighbour classification whose ties an exported graph resolves the same way.

:class:`StableKNeighborsClassifier` is scikit-learn's ``KNeighborsClassifier`` with one rule fixed:
of training samples at equal distance, the earlier one is nearer. scikit-learn leaves ties to its
search structure (a ball tree and brute force may keep different samples at the k-th distance), so an
exported graph cannot reproduce them; with the order fixed, the graph
(:class:`tactile_torch.export.classifier_inference.NeighboursInference`, ONNX ``TopK``) gives the
model's labels on every sample, ties included (duplicated feature vectors are common on small taxel
arrays: a touch that presses no taxel gives the same features as any other).
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {"_classification": ("StableKNeighborsClassifier",)})
