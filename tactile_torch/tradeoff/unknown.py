"""The "unknown" rule of a trade-off bundle, fitted on what the bundle already computes.

Every file the study writes for a candidate (its timing file and, when deployed, ``recommended.onnx``)
carries the "unknown" rule of :mod:`tactile_torch.ood`: a Mahalanobis distance to the training data, as
an ``ood_distance`` output with its threshold in the metadata. It is measured on a tensor the bundle
computes anyway, so that the rule costs a few small matrix products and not a second pass over the
raw input:

* a **classical** candidate (features → selection → standardisation → classifier): on its own
  features, the front's ``features`` tensor, selected and standardised as its head does (as ``train``
  + ``export`` measure it): :func:`classical_rule`;
* a **learned** candidate (a network, or a learned front end with a linear head): on its
  **embedding**, the input of its last linear layer (a network's pooled channels, a front end's
  standardised features), as Lee et al. (2018) measure the Mahalanobis distance on a network's
  penultimate layer: :func:`embedding_rule`. (Before this version a network got the distance on the
  reference features of its raw input, computed by a second feature graph beside it: on a 4 x 4
  fingertip's 200 frames the fused image features cost 70 times the taxel CNN itself.)
* except the **1-D CNNs on vibration windows** (:func:`on_reference_features`), whose rule stays on the
  reference features of their window (the 21 window features), charged honestly in their latency: on
  their embedding it missed what the window features catch (measured with
  ``export/measure_unknown_deployed.py`` on 8 generated surfaces: white noise of 0.1 g answered
  "unknown" 20 % of the time against 100 %, and the int8 network's embedding let a still sensor and 0.01 g
  noise pass, 0 % against 100 %), and the 21 features of an 800-sample window cost a fraction of a
  millisecond beside its 0.8 s of sensor data.

The distance part (:class:`tactile_torch.ood.DistanceHead`) is exported once per structure with its
fitted arrays as inputs, bound per candidate and attached to the bundle
(:func:`tactile_torch.export.ood_branch.attach_distance`; :func:`~.bundle.finish_bundle` does it).
"""

from __future__ import annotations

import numpy as np


def classical_rule(model: object, features: np.ndarray, y: np.ndarray) -> tuple[dict, object]:
    """Return the rule of a fitted classical candidate and its distance part, from its training
    ``features`` ``(N, F)`` (the ``features`` step's output) and labels."""
    from ..ood import DistanceHead, fit_rule

    features = np.asarray(features, dtype=np.float64)
    steps = model.named_steps
    columns = steps["select"].columns_ if "select" in steps else np.arange(features.shape[1])
    scaler = steps["scale"]
    rule = fit_rule(features[:, columns], y, scale=scaler.scale_, center=scaler.mean_)
    return rule, DistanceHead(rule, scale=scaler.scale_, center=scaler.mean_, select=columns)


def embedding_rule(E: np.ndarray, y: np.ndarray) -> tuple[dict, object]:
    """Return the rule of a learned candidate fitted on its training embeddings ``E`` ``(N, E)`` (what its
    file computes for the training raw input) and labels, and its distance part (standardised on ``E``)."""
    from ..ood import DistanceHead, fit_rule

    E = np.asarray(E, dtype=np.float64)
    center = E.mean(axis=0)
    scale = E.std(axis=0, ddof=1) if len(E) > 1 else np.ones(E.shape[1])
    scale = np.where(scale > 0, scale, 1.0)
    rule = fit_rule(E, y, scale=scale, center=center)
    return rule, DistanceHead(rule, scale=scale, center=center)


def on_reference_features(model: object) -> bool:
    """Whether a learned candidate's rule is measured on the reference features of its raw input (the 1-D
    CNNs on vibration windows, module notes) rather than on its embedding."""
    from ..neural import WindowCNNClassifier

    return isinstance(model.steps[-1][1], WindowCNNClassifier)


def reference_rule(step: object, X: np.ndarray, y: np.ndarray) -> tuple[dict, object, np.ndarray]:
    """Return the rule of a learned candidate measured on the reference features (``step``, a fitted
    features step) of its training raw input ``X``, its distance part and the features."""
    from sklearn.preprocessing import StandardScaler

    from ..ood import DistanceHead, fit_rule

    features = np.asarray(step.transform(X), dtype=np.float64)
    scaler = StandardScaler().fit(features)
    rule = fit_rule(features, y, scale=scaler.scale_, center=scaler.mean_)
    return rule, DistanceHead(rule, scale=scaler.scale_, center=scaler.mean_), features


__all__ = ["classical_rule", "embedding_rule", "on_reference_features", "reference_rule"]
