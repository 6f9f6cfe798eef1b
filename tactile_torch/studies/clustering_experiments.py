"""The clustering experiments behind the ``clustering`` report section and ``train/cluster_surfaces.py``.

Each function fits the Pitman-Yor mixture (or its baselines) on a feature matrix and returns table rows:
:func:`cluster_and_compare` (Table 2: the mixture against k-means, EM, EM + BIC and the variational DP
mixture), :func:`learning_curve` (Figs. 12 and 14), :func:`novelty_test` (withheld surfaces), with the
data helpers :func:`synthetic_clusters` and :func:`real_windows`. The section
(:mod:`tactile_torch.studies.clustering`) renders them.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import numpy as np

from ..metrics import pairwise_accuracy
from ..mixture import PitmanYorGMM, baseline_clusterings, window_means

STUDY = {"model": "pyp", "coarsen": None}
"""The study's Pitman-Yor mixture (``PitmanYorGMM``'s defaults are the mixture of finite mixtures)."""
WITHHELD = (3, 10, 17, 24)
"""Surfaces kept out of training in the novelty test (every seventh, from different families)."""


def synthetic_clusters(
    n_clusters: int,
    per_cluster: int,
    *,
    dim: int = 3,
    spread: float = 0.3,
    min_gap: float = 3.0,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (X (n, dim), labels (n,)): seeded Gaussian clusters whose centres are at least ``min_gap`` apart."""
    rng = np.random.default_rng(seed)
    box = 20.0 * (n_clusters / 28) ** (1 / dim)
    centers = rng.uniform(-box, box, size=(n_clusters, dim))
    for _ in range(10_000):
        gaps = np.linalg.norm(centers[:, None] - centers[None], axis=-1)
        np.fill_diagonal(gaps, np.inf)
        if gaps.min() >= min_gap:
            break
        centers[np.argmin(gaps.min(1))] = rng.uniform(-box, box, size=dim)
    X = np.concatenate([rng.normal(c, spread, size=(per_cluster, dim)) for c in centers])
    return X, np.repeat(np.arange(n_clusters), per_cluster)


def k_row(model: PitmanYorGMM) -> dict[str, Any]:
    """The honest K of a fitted mixture: posterior mode, median, 95 % interval, point estimate, MAP sample."""
    ks = model.n_clusters_summary_
    return {
        "K posterior mode": ks["mode"],
        "K median": ks["median"],
        "K 95% interval": f"[{ks['interval'][0]}, {ks['interval'][1]}]",
        "K point estimate": ks["point_estimate"],
        "K MAP sample": ks["map"],
    }


def max_rhat(model: PitmanYorGMM) -> float:
    """The largest rank-normalised split R-hat of K, alpha and d of a fitted mixture (NaN with one chain)."""
    values = [r["R-hat"] for r in model.convergence_ if np.isfinite(r["R-hat"])]
    return round(max(values), 3) if values else float("nan")


def cluster_and_compare(
    X: np.ndarray,
    y: np.ndarray,
    *,
    n_iter: int,
    burn_in: int,
    random_state: int,
    max_components: int | None = None,
    n_chains: int = 4,
    n_init: int = 5,
    min_components: int | None = None,
    **fit: Any,
) -> dict[str, Any]:
    """Fit the Pitman-Yor mixture and the scikit-learn baselines; return the model and Table 2's rows.

    ``fit``: further keyword arguments of the mixture (``max_seconds``).
    """
    model = PitmanYorGMM(
        n_iter=n_iter,
        burn_in=burn_in,
        n_chains=n_chains,
        random_state=random_state,
        progress=False,
        **STUDY,
        **fit,
    ).fit(X)
    n_true = int(np.unique(y).size)
    ks = model.n_clusters_summary_
    rows = [
        {
            "method": "Pitman-Yor mixture: point estimate (min. expected VI)",
            "K given": "no",
            "K found": ks["point_estimate"],
            "posterior of K": f"mode {ks['mode']}, median {ks['median']:g}, 95% [{ks['interval'][0]}, {ks['interval'][1]}]",
            "pairwise accuracy": pairwise_accuracy(y, model.labels_),
            "seconds": model.fit_seconds_,
        },
        {
            "method": "Pitman-Yor mixture: MAP sample",
            "K given": "no",
            "K found": ks["map"],
            "posterior of K": "",
            "pairwise accuracy": pairwise_accuracy(y, model.map_labels_),
            "seconds": "",
        },
    ]
    names = {
        "kmeans": ("k-means", "yes"),
        "em": ("EM (full covariances)", "yes"),
        "em_bic": ("EM, K by BIC/MDL", "no"),
        "variational_dp": ("variational DP mixture (scikit-learn)", "no"),
    }
    for key, res in baseline_clusterings(
        X,
        n_true,
        max_components=max_components,
        min_components=min_components,
        n_init=n_init,
        random_state=random_state,
    ).items():
        rows.append(
            {
                "method": names[key][0],
                "K given": names[key][1],
                "K found": res["n_clusters"],
                "posterior of K": "",
                "pairwise accuracy": pairwise_accuracy(y, res["labels"]),
                "seconds": res["seconds"],
            }
        )
    return {"model": model, "rows": rows}


def have_vibration_features() -> bool:
    """Whether :mod:`tactile_torch.signal` (the vibration features) is available in this installation."""
    return importlib.util.find_spec("tactile_torch.signal") is not None


def cluster_to_label(labels: np.ndarray, y: np.ndarray, n_clusters: int) -> np.ndarray:
    """Map each cluster to the most frequent true label of its training points (-1 stays -1)."""
    table = np.zeros((n_clusters, int(y.max()) + 1))
    np.add.at(table, (labels, y), 1)
    return np.r_[table.argmax(axis=1), -1]  # index -1 (novel) maps to -1


def learning_curve(
    X: np.ndarray,
    y: np.ndarray,
    per_class: list[int],
    *,
    n_iter: int,
    burn_in: int,
    random_state: int,
    n_chains: int = 2,
    discounts: tuple[float | None, ...] = (0.0, None),
    **fit: Any,
) -> list[dict[str, Any]]:
    """Expected K, the point estimate's K and pairwise accuracy with the first ``m`` windows of every class.

    One row per ``m`` in ``per_class`` and per prior (``discount=0``: Dirichlet process, ``None``:
    Pitman-Yor with d sampled); ``fit``: further keyword arguments of the mixture (``max_seconds``).
    """
    rows = []
    classes = np.unique(y)
    for m in per_class:
        keep = np.concatenate([np.flatnonzero(y == c)[:m] for c in classes])
        for discount in discounts:
            model = PitmanYorGMM(
                **STUDY,
                discount=discount,
                n_iter=n_iter,
                burn_in=burn_in,
                n_chains=n_chains,
                random_state=random_state,
                **fit,
            )
            model.set_params(progress=False).fit(X[keep])
            rows.append(
                {
                    "per class": m,
                    "points": keep.size,
                    "prior": "DP" if discount == 0.0 else "PYP",
                    "expected K": float(model.n_clusters_samples_.mean()),
                    **k_row(model),
                    "pairwise accuracy": pairwise_accuracy(y[keep], model.labels_),
                    "max R-hat": max_rhat(model),
                }
            )
    return rows


def novelty_test(
    X: np.ndarray,
    y: np.ndarray,
    tests: list[tuple[np.ndarray, np.ndarray]],
    withheld: tuple[int, ...],
    n_consecutive: int = 3,
    **fit: Any,
) -> dict[str, Any]:
    """Fit without the ``withheld`` classes; return novelty recall on them and false alarms on the others.

    Recall: share of the withheld classes' test windows labelled -1 by :meth:`PitmanYorGMM.predict`;
    false-alarm rate: share of the known classes' test windows labelled -1. The calibrated rule
    (``tactile-torch cluster``'s): the first half (in time) of each known class's test windows sets
    the thresholds (:meth:`PitmanYorGMM.calibrate_novelty`, 2 % false alarms), the second half of
    every class's test windows is decided (:meth:`PitmanYorGMM.novel_after`, after 1 and
    ``n_consecutive`` windows).
    """
    known = ~np.isin(y, withheld)
    model = PitmanYorGMM(progress=False, **(STUDY | fit)).fit(X[known])
    Xt = np.concatenate([t[0] for t in tests])
    yt = np.concatenate([t[1] for t in tests])
    new = np.isin(yt, withheld)
    row = {
        "withheld classes": len(withheld),
        "test windows (new / known)": f"{int(new.sum())} / {int((~new).sum())}",
    }
    for using in ("samples", "point"):
        novel = model.predict(Xt, using=using) == -1
        row[f"recall ({using})"] = float(novel[new].mean()) if new.any() else float("nan")
        row[f"false alarms ({using})"] = float(novel[~new].mean())
    # decided after n consecutive novel windows of one surface (tactile-torch stream --discover n)
    novel = model.predict(Xt, using="point") == -1
    run = consecutive_flags(novel, yt, n_consecutive)
    row[f"recall after {n_consecutive} in a row (point)"] = (
        float(run[new].mean()) if new.any() else float("nan")
    )
    row[f"false alarms after {n_consecutive} in a row (point)"] = float(run[~new].mean())
    # calibrated: first half of each known class's test windows calibrates, the second halves are decided
    rank = np.zeros(len(yt))
    for c in np.unique(yt):
        idx = np.flatnonzero(yt == c)
        rank[idx] = np.arange(idx.size) / idx.size
    calibration, decided = ~new & (rank < 0.5), rank >= 0.5
    if calibration.any() and new[decided].any():
        model.calibrate_novelty(
            Xt[calibration], false_alarm=0.02, max_windows=n_consecutive, groups=yt[calibration]
        )
        for n, label in ((1, "calibrated 2 %"), (n_consecutive, f"calibrated, mean of {n_consecutive}")):
            flags = model.novel_after(Xt[decided], n, groups=yt[decided])
            ran = np.isfinite(window_means(np.zeros(int(decided.sum())), n, yt[decided]))
            is_new = new[decided][ran]
            row[f"recall ({label})"] = float(flags[ran][is_new].mean())
            row[f"false alarms ({label})"] = float(flags[ran][~is_new].mean())
    row["max R-hat"] = max_rhat(model)
    return row


def consecutive_flags(novel: np.ndarray, labels: np.ndarray, n: int) -> np.ndarray:
    """Return, per window, whether it ends a run of ``n`` novel windows of its own class (windows in time order per class)."""
    out = np.zeros(novel.shape, dtype=bool)
    for c in np.unique(labels):
        idx = np.flatnonzero(labels == c)
        run = 0
        for i in idx:
            run = run + 1 if novel[i] else 0
            out[i] = run >= n
    return out


def real_windows(name: str, per: int, components: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Features (PCA-3, or ``components``) of up to ``per`` 2 s windows per class of a shared real set, their labels and time order.

    Returns (X, labels, position of each window in its recording, number of classes).
    """
    import torch

    from ..data.recordings import load_borealtc_imu, load_hapmat_imu5
    from ..signal import fit_clustering_transform, window_features

    rec = {"hapmat_imu5": load_hapmat_imu5, "borealtc_imu": load_borealtc_imu}[name]()
    ds = rec.windows(int(2 * rec.rate_hz))  # 2 s windows at the native rate
    labels = ds.labels.numpy()
    keep = np.concatenate(
        [
            idx[np.linspace(0, idx.size - 1, min(per, idx.size)).astype(int)]
            for idx in map(np.flatnonzero, (labels == c for c in np.unique(labels)))
        ]
    )
    feats = window_features(ds.windows[torch.as_tensor(keep)].to(torch.float64))
    _, X = fit_clustering_transform(feats, components)
    return X, labels[keep], ds.position.numpy()[keep], len(rec.class_names)
