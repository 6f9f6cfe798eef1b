"""Data and settings shared by the mixture tests."""

from __future__ import annotations

import numpy as np

PYP = {"model": "pyp", "coarsen": None}
"""The study's Pitman-Yor mixture (the estimator's default model is the mixture of finite mixtures)."""


def blobs(n_clusters=28, per=50, dim=3, spread=0.3, box=20.0, seed=0):
    """Well-separated Gaussian clusters (the study's 28 surfaces x 50 windows in PCA-3 space)."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-box, box, size=(n_clusters, dim))
    while True:  # keep the centres at least 3 units apart so that the clusters are well separated
        d = np.linalg.norm(centers[:, None] - centers[None], axis=-1) + np.eye(n_clusters) * 1e9
        if d.min() > 3.0:
            break
        centers[np.argmin(d.min(1))] = rng.uniform(-box, box, size=dim)
    X = np.concatenate([rng.normal(c, spread, size=(per, dim)) for c in centers])
    return X, np.repeat(np.arange(n_clusters), per)
