"""Discover surfaces in a data file and write the results: what ``tactile-torch cluster`` runs.

The twin of :mod:`tactile_torch.training` for the unsupervised path (the clustering *study* of the
report is :mod:`tactile_torch.studies.clustering`). :func:`fit_clustering` turns data read by
:func:`tactile_torch.robot.data_sources.read_source` into what the mixture clusters (vibration recordings:
windows, their features (:func:`tactile_torch.training.load_features`), then the fitted
:class:`~tactile_torch.signal.ClusteringTransform` and its principal components; a ``features``
array as it is) and fits :class:`~tactile_torch.mixture.PitmanYorGMM` to it.
:func:`write_clustering` writes the results into a directory: ``clustering.npz`` (the point estimate,
the MAP sample, the posterior samples of K and of the prior's parameters), ``model.npz`` (the model
file :func:`tactile_torch.clustering_model.save_clustering_model` writes, for ``tactile-torch export``) and
``summary.txt`` (:func:`clustering_summary`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CLUSTERED_KINDS = ("vibration", "features")
"""Kinds of data (``.kind`` of what ``read_source`` returns) that can be clustered."""
RESULTS_FILE = "clustering.npz"
MODEL_FILE = "model.npz"
SUMMARY_FILE = "summary.txt"


@dataclass
class Clustering:
    """A fitted clustering of one data set.

    Attributes
    ----------
    mixture : PitmanYorGMM
        Fitted to ``X``.
    X : ndarray of shape (N, D)
        What the mixture was fitted to: principal components of the windows' features, or the
        file's features.
    truth : ndarray of shape (N,) or None
        The file's class of each row, when it has labels (for the pairwise accuracy only).
    source : dict
        How a row is made from raw input (the model file's ``source``).
    transform : ClusteringTransform or None
        Vibration windows: the fitted features-to-components transform.
    """

    mixture: object
    X: np.ndarray
    truth: np.ndarray | None
    source: dict
    transform: object | None = None


def fit_clustering(
    data,
    *,
    window: int = 800,
    step: int | None = None,
    components: int = 3,
    sensor_range_g: float | None = None,
    name: str = "data",
    log: Callable[[str], None] | None = None,
    **mixture_params,
) -> Clustering:
    """Return the clustering of ``data``: its rows, and the mixture fitted to them.

    Parameters
    ----------
    data : DataArrays
        What :func:`tactile_torch.robot.data_sources.read_source` returned, of kind ``"vibration"``
        (recordings) or ``"features"`` (a matrix ``(N, D)``, labels optional).
    window, step : int
        Vibration: window length and hop in samples (default hop: ``window``).
    components : int
        Vibration: principal components kept by the transform.
    sensor_range_g : float, optional
        Vibration: the sensor's range declared by the user, kept in ``source`` (the export's
        default range). ``None`` or ``inf``: not kept.
    name : str
        How messages name the data.
    log : callable, optional
        Called with one line once the rows are ready, before the (long) fit.
    **mixture_params
        Passed to :class:`~tactile_torch.mixture.PitmanYorGMM` (``model``, ``coarsen``, ``alpha``,
        ``n_iter``, ``random_state``, ``progress``, ...), which validates them at ``fit``.

    Raises
    ------
    ValueError
        ``data`` of another kind (images), or data and parameters the readers or the mixture refuse.
    """
    from .mixture import PitmanYorGMM

    transform = None
    if data.kind == "features":  # labels optional: clustering does not need them
        X, truth = data.features, data.labels
        source = {"kind": "features", "n_features": int(X.shape[1])}
    elif data.kind == "vibration":
        from .signal import ClusteringTransform
        from .training import load_features

        features = load_features(data, window=window, step=step, name=name)
        truth, source = features.y, dict(features.source)
        if sensor_range_g is not None and sensor_range_g != float("inf"):
            source["sensor_range_g"] = float(sensor_range_g)
        transform = ClusteringTransform(components).fit(features.X)
        X = transform.transform(features.X)
        if log is not None:
            log(f"{name}: {len(X)} windows of {window} samples -> {X.shape[1]} principal components")
    else:
        raise ValueError(
            f"{name}: data must hold vibration recordings ('signals') or a 'features' array (n, D) to "
            f"cluster, got {data.kind} data"
        )
    mixture = PitmanYorGMM(**mixture_params).fit(X)
    return Clustering(mixture, X, truth, source, transform)


def clustering_summary(clustering: Clustering) -> str:
    """Return the mixture's summary (posterior of K first) and, with labels, the pairwise accuracies."""
    from .metrics import pairwise_accuracy

    model, truth = clustering.mixture, clustering.truth
    summary = model.summary()
    if truth is not None:
        summary += (
            f"\npairwise accuracy: point estimate {pairwise_accuracy(truth, model.labels_):.4f}, "
            f"MAP sample {pairwise_accuracy(truth, model.map_labels_):.4f}"
        )
    return summary


def write_clustering(out_dir: str | Path, clustering: Clustering) -> dict[str, Path]:
    """Write the results of ``clustering`` into ``out_dir`` (made if missing); return the paths by role.

    The roles are ``"results"`` (``clustering.npz``: ``labels``, ``map_labels``, ``means``,
    ``covariances``, ``precisions_cholesky``, ``weights``, ``n_clusters_samples``,
    ``n_clusters_interval``, ``alpha_samples``, ``discount_samples``), ``"summary"``
    (``summary.txt``) and ``"model"`` (``model.npz``, for ``tactile-torch export``).
    """
    from .clustering_model import save_clustering_model

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = clustering.mixture
    ks = model.n_clusters_summary_
    np.savez(
        out / RESULTS_FILE,
        labels=model.labels_,
        map_labels=model.map_labels_,
        means=model.means_,
        covariances=model.covariances_,
        precisions_cholesky=model.precisions_cholesky_,
        weights=model.weights_,
        n_clusters_samples=model.n_clusters_samples_,
        n_clusters_interval=np.array(ks["interval"]),
        alpha_samples=model.alpha_samples_,
        discount_samples=model.discount_samples_,
    )
    save_clustering_model(out / MODEL_FILE, model, source=clustering.source, transform=clustering.transform)
    (out / SUMMARY_FILE).write_text(clustering_summary(clustering) + "\n")
    return {"results": out / RESULTS_FILE, "summary": out / SUMMARY_FILE, "model": out / MODEL_FILE}
