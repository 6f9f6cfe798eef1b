"""The study's scikit-learn baselines of the Pitman-Yor mixture (Table 2): k-means, EM, EM + BIC, variational DP."""

from __future__ import annotations

import numbers
import time
from collections.abc import Mapping

import numpy as np


def baseline_clusterings(
    X: object,
    n_clusters: int,
    *,
    max_components: int | None = None,
    min_components: int | None = None,
    n_init: int = 5,
    random_state: object = None,
) -> dict[str, Mapping[str, object]]:
    """Return the labels of the study's scikit-learn baselines on ``X`` (n, D).

    - ``kmeans``: :class:`sklearn.cluster.KMeans` given the true K (10 restarts);
    - ``em``: :class:`sklearn.mixture.GaussianMixture` (full covariances) given K (``n_init`` restarts);
    - ``em_bic``: EM with K chosen in ``min_components`` … ``max_components`` by BIC (= MDL up to a
      factor 1/2; ``min_components`` defaults to ``ceil(n_clusters / 2)``: the lower half of the range
      is never chosen on the study's data, and fitting it doubled the time);
    - ``variational_dp``: :class:`sklearn.mixture.BayesianGaussianMixture` with a Dirichlet-process
      prior and ``max_components`` components; its K is the number of components that own points.

    ``max_components`` defaults to ``min(n, max(2 n_clusters, 10))``. Each value is a dict with
    ``labels`` (n,), ``n_clusters`` and ``seconds`` (fit time).
    """
    from sklearn.cluster import KMeans
    from sklearn.mixture import BayesianGaussianMixture, GaussianMixture

    from ..validation import as_feature_matrix, numpy_rng

    X = as_feature_matrix(X)
    n = X.shape[0]
    if (
        isinstance(n_clusters, bool)
        or not isinstance(n_clusters, numbers.Integral)
        or not 1 <= n_clusters <= n
    ):
        raise ValueError(
            f"n_clusters must be an integer in [1, {n}] (the number of samples), got {n_clusters!r}"
        )
    if max_components is None:
        kmax = min(n, max(2 * n_clusters, 10))
    elif (
        isinstance(max_components, bool)
        or not isinstance(max_components, numbers.Integral)
        or max_components < 1
    ):
        raise ValueError(f"max_components must be an integer >= 1 or None, got {max_components!r}")
    else:
        kmax = int(max_components)
    kmin = min(kmax, (n_clusters + 1) // 2 if min_components is None else max(1, int(min_components)))
    seed = int(numpy_rng(random_state).integers(2**31 - 1))
    out: dict[str, Mapping[str, object]] = {}

    def record(name: str, fn) -> None:
        t0 = time.perf_counter()
        labels = np.asarray(fn())
        out[name] = {
            "labels": labels,
            "n_clusters": int(np.unique(labels).size),
            "seconds": time.perf_counter() - t0,
        }

    record("kmeans", lambda: KMeans(n_clusters, n_init=10, random_state=seed).fit_predict(X))
    record("em", lambda: GaussianMixture(n_clusters, n_init=n_init, random_state=seed).fit(X).predict(X))

    def em_bic() -> np.ndarray:
        fits = [GaussianMixture(k, n_init=1, random_state=seed).fit(X) for k in range(kmin, kmax + 1)]
        return min(fits, key=lambda gm: gm.bic(X)).predict(X)

    record("em_bic", em_bic)
    record(
        "variational_dp",
        lambda: (
            BayesianGaussianMixture(
                n_components=kmax,
                weight_concentration_prior_type="dirichlet_process",
                max_iter=500,
                random_state=seed,
            )
            .fit(X)
            .predict(X)
        ),
    )
    return out
