"""Report section: how many surfaces? The Pitman-Yor mixture on unlabelled features (method 2, unsupervised).

Reproduces the unsupervised study's figures and table: the posterior over the number of surfaces K
(Fig. 9), pairwise accuracy along the chain (Fig. 10), the comparison with k-means, EM, EM + BIC and
the variational Dirichlet-process mixture (Table 2), the posterior of the discount d (Fig. 15), and
Dirichlet process vs Pitman-Yor.

Data: the bundled synthetic stylus recordings (28 surfaces), 50 windows of W = 1600 per surface,
through the 21 window features and the unsupervised transform of :mod:`tactile_torch.signal` (PCA to
3), plus the window sizes W = 200 … 1600 and the real accelerometer sets of ``../shared/data`` when
present. Where :mod:`tactile_torch.signal` is not installed, seeded Gaussian clusters in 3-D stand in.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import numpy as np

from ..metrics import pairwise_accuracy
from ..mixture import PitmanYorGMM, baseline_clusterings

TITLE = "Clustering: how many surfaces (Pitman-Yor mixture)"
CMD = "tactile-torch report --only clustering --out runs/latest"


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


def cluster_and_compare(
    X: np.ndarray,
    y: np.ndarray,
    *,
    n_iter: int,
    burn_in: int,
    random_state: int,
    max_components: int | None = None,
) -> dict[str, Any]:
    """Fit the Pitman-Yor mixture (default start) and the scikit-learn baselines; return models and table rows."""
    n_true = int(np.unique(y).size)
    model = PitmanYorGMM(n_iter=n_iter, burn_in=burn_in, random_state=random_state, progress=False).fit(X)
    post = model.n_clusters_posterior()
    rows = [
        {
            "method": "Pitman-Yor mixture (MAP sample)",
            "K given": "no",
            "K found": model.n_clusters_,
            "posterior mode of K": max(post, key=post.get),
            "pairwise accuracy": pairwise_accuracy(y, model.labels_),
            "seconds": model.fit_seconds_,
        }
    ]
    names = {
        "kmeans": ("k-means", "yes"),
        "em": ("EM (full covariances)", "yes"),
        "em_bic": ("EM, K by BIC/MDL", "no"),
        "variational_dp": ("variational DP mixture (scikit-learn)", "no"),
    }
    for key, res in baseline_clusterings(
        X, n_true, max_components=max_components, random_state=random_state
    ).items():
        rows.append(
            {
                "method": names[key][0],
                "K given": names[key][1],
                "K found": res["n_clusters"],
                "posterior mode of K": "",
                "pairwise accuracy": pairwise_accuracy(y, res["labels"]),
                "seconds": res["seconds"],
            }
        )
    return {"model": model, "rows": rows}


def have_vibration_features() -> bool:
    """Whether :mod:`tactile_torch.signal` (the vibration features) is available in this installation."""
    return importlib.util.find_spec("tactile_torch.signal") is not None


def vibration_features(
    ctx, window_size: int, per_surface: int, n_surfaces: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Clustering features of the bundled recordings: ``per_surface`` windows of ``window_size`` per surface.

    21 window features, then the unsupervised transform of DESIGN.md (drop skew/kurt/m5, sqrt/log,
    standardise, PCA to 3), fitted on these windows; ``n_surfaces`` keeps the first surfaces only
    (quick runs). Returns (X (n, 3) float64, labels (n,)).
    """
    import torch

    from ..signal import ClusteringTransform, window_features
    from .vibration_features import bundled_recordings

    def make() -> tuple[np.ndarray, np.ndarray]:
        ds = bundled_recordings(ctx).windows(window_size, max_per_recording=per_surface)
        keep = torch.ones(len(ds), dtype=torch.bool) if n_surfaces is None else ds.labels < n_surfaces
        feats = window_features(ds.windows[keep].to(torch.float64))
        return ClusteringTransform(n_components=3).fit_transform(feats).numpy(), ds.labels[keep].numpy()

    return ctx.cached(f"clustering_vibration_{window_size}_{per_surface}_{n_surfaces}", make)


def _study_data(ctx) -> tuple[np.ndarray, np.ndarray, str, int | None]:
    """(X, labels, description, window size) of the main experiment."""
    if have_vibration_features():
        size, per, surfaces = (400, 20, 6) if ctx.quick else (1600, 50, 28)
        X, y = vibration_features(ctx, size, per, surfaces)
        what = (
            f"the bundled synthetic stylus recordings, {surfaces} surfaces x {per} windows of W = {size} samples; "
            "21 window features, then the unsupervised transform (drop skew/kurt/m5, sqrt/log, standardise, "
            "PCA to 3)"
        )
        return X, y, what, size
    n_clusters, per = (6, 15) if ctx.quick else (28, 50)
    X, y = ctx.cached(
        f"clustering_synthetic_{n_clusters}x{per}",
        lambda: synthetic_clusters(n_clusters, per, seed=ctx.random_state),
    )
    what = (
        f"{n_clusters} surfaces x {per} windows in a 3-D feature space (seeded Gaussian clusters standing in "
        "for the PCA-3 vibration features, which this installation lacks)"
    )
    return X, y, what, None


def run(section, ctx) -> None:
    import matplotlib.pyplot as plt

    quick = ctx.quick
    n_iter, burn_in = (120, 40) if quick else (3000, 1000)
    X, y, what, window_size = _study_data(ctx)
    n_clusters = int(np.unique(y).size)
    section.text(
        f"Unlabelled data: {what}. The Pitman-Yor mixture is not told K; it runs {n_iter} Gibbs sweeps "
        f"({burn_in} burn-in) from a k-means start with a generous number of clusters. The baselines "
        "k-means and EM are given the true K."
    )
    section.command(CMD + (" --quick" if quick else ""))
    out = cluster_and_compare(
        X,
        y,
        n_iter=n_iter,
        burn_in=burn_in,
        random_state=ctx.random_state,
        max_components=n_clusters + (2 if quick else 6),
    )
    model: PitmanYorGMM = out["model"]
    section.table(
        out["rows"], caption=f"Clustering {n_clusters} surfaces: PYP mixture vs baselines (Table 2)"
    )
    section.text("```\n" + model.summary() + "\n```")

    # Fig. 9: posterior over K
    post = model.n_clusters_posterior()
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.bar(list(post), list(post.values()), color="tab:blue")
    ax.axvline(n_clusters, color="k", ls="--", lw=1, label=f"true K = {n_clusters}")
    ax.set_xlabel("number of surfaces K")
    ax.set_ylabel("posterior probability")
    ax.legend()
    section.figure(
        fig, "clustering posterior K", "Posterior over the number of surfaces K (post burn-in sweeps)"
    )

    # Fig. 10: pairwise accuracy along the chain, from a one-cluster start and from the default start
    one = PitmanYorGMM(
        n_iter=n_iter // 3, burn_in=1, init="one", thin=max(1, n_iter // 300), random_state=ctx.random_state
    )
    one.set_params(progress=False).fit(X)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3))
    for m, label in ((model, "k-means start"), (one, "one-cluster start")):
        acc = [pairwise_accuracy(y, z) for z in m.labels_samples_]
        ax1.plot(m.labels_sweeps_, acc, label=label)
        ax2.plot(m.trace_["n_clusters"], label=label)
    ax1.set_xlabel("sweep")
    ax1.set_ylabel("pairwise accuracy")
    ax1.set_xscale("symlog")
    ax2.axhline(n_clusters, color="k", ls="--", lw=1)
    ax2.set_xlabel("sweep")
    ax2.set_ylabel("K")
    ax2.set_xscale("symlog")
    ax1.legend()
    section.figure(fig, "clustering accuracy along chain", "Pairwise accuracy and K along the chain")
    hit = np.flatnonzero(one.trace_["n_clusters"] == n_clusters)
    section.text(
        "From a one-cluster start the chain first reaches the true K at sweep "
        + (f"{int(hit[0])}" if hit.size else "(not reached)")
        + f"; split-merge moves accepted: {one.split_merge_stats_['split_accepted']} splits, "
        f"{one.split_merge_stats_['merge_accepted']} merges."
    )

    # Fig. 15: posterior of the discount d
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist(model.discount_samples_, bins=40, range=(0, 1), color="tab:orange")
    ax.set_xlabel("discount d")
    ax.set_ylabel("sweeps")
    section.figure(
        fig, "clustering discount", "Posterior of the Pitman-Yor discount d (d = 0: Dirichlet process)"
    )

    # Dirichlet process vs Pitman-Yor
    rows = []
    for label, discount in (("Dirichlet process (d = 0)", 0.0), ("Pitman-Yor (d sampled)", None)):
        m = model if discount is None else PitmanYorGMM(discount=0.0, n_iter=n_iter, burn_in=burn_in)
        if discount is not None:
            m.set_params(random_state=ctx.random_state, progress=False).fit(X)
        p = m.n_clusters_posterior()
        rows.append(
            {
                "prior": label,
                "posterior mode of K": max(p, key=p.get),
                "P(K = truth)": p.get(n_clusters, 0.0),
                "MAP K": m.n_clusters_,
                "pairwise accuracy (MAP)": pairwise_accuracy(y, m.labels_),
                "alpha (median)": float(np.median(m.alpha_samples_)),
            }
        )
    section.table(rows, caption="Dirichlet process vs Pitman-Yor prior")
    if window_size is not None:
        _window_sizes(section, ctx, n_iter=n_iter // 2, burn_in=burn_in // 2)
        if quick:
            section.text("Real accelerometer sets: skipped in quick mode.")
        else:
            real_data(section, ctx, n_iter=n_iter // 2, burn_in=burn_in // 2)


def _window_sizes(section, ctx, *, n_iter: int, burn_in: int) -> None:
    """K and pairwise accuracy for several window sizes W (the study: K = 28 found for W >= 400)."""
    sizes, per, surfaces = ((200, 400), 20, 6) if ctx.quick else ((200, 400, 800, 1600), 50, 28)
    rows = []
    for size in sizes:
        X, y = vibration_features(ctx, size, per, surfaces)
        model = PitmanYorGMM(
            n_iter=n_iter, burn_in=burn_in, random_state=ctx.random_state, progress=False
        ).fit(X)
        post = model.n_clusters_posterior()
        rows.append(
            {
                "W": size,
                "windows": len(y),
                "true K": int(np.unique(y).size),
                "posterior mode of K": max(post, key=post.get),
                "MAP K": model.n_clusters_,
                "pairwise accuracy (MAP)": pairwise_accuracy(y, model.labels_),
            }
        )
    section.table(rows, caption=f"Window size: K found on the bundled recordings ({per} windows per surface)")


def real_data(section, ctx, *, n_iter: int, burn_in: int) -> None:
    """The same pipeline on the real accelerometer sets of ``../shared/data`` when present."""
    import torch

    from ..data import shared_data_dir
    from ..data.recordings import load_borealtc_imu, load_hapmat_imu5
    from ..signal import ClusteringTransform, window_features

    loaders = {"hapmat_imu5": load_hapmat_imu5, "borealtc_imu": load_borealtc_imu}
    present = {name: load for name, load in loaders.items() if shared_data_dir(name) is not None}
    if not present:
        section.text(
            "The real accelerometer sets (`../shared/data/hapmat_imu5`, `borealtc_imu`) are absent: skipped."
        )
        return
    per = 20 if ctx.quick else 50
    rows = []
    for name, load in present.items():
        rec = load()
        ds = rec.windows(int(2 * rec.rate_hz))  # 2 s windows at the native rate
        labels = ds.labels.numpy()
        # up to `per` windows per class, evenly spread over its recordings
        keep = np.concatenate(
            [
                idx[np.linspace(0, idx.size - 1, min(per, idx.size)).astype(int)]
                for idx in map(np.flatnonzero, (labels == c for c in np.unique(labels)))
            ]
        )
        feats = window_features(ds.windows[torch.as_tensor(keep)].to(torch.float64))
        X = ClusteringTransform(n_components=3).fit_transform(feats).numpy()
        y = labels[keep]
        out = cluster_and_compare(
            X,
            y,
            n_iter=n_iter,
            burn_in=burn_in,
            random_state=ctx.random_state,
            max_components=len(rec.class_names) + 5,
        )
        for row in out["rows"]:
            rows.append({"data set": name, "classes": len(rec.class_names), "windows": len(y), **row})
    section.text(
        "Real accelerometer data (`tactile_torch.data.load_hapmat_imu5` / `load_borealtc_imu`: 100 Hz IMU logs, "
        "not an 800 Hz stylus): 2 s windows, up to "
        f"{per} per class, the same features and transform; a check of the pipeline on real signals."
    )
    section.table(rows, caption="Real data sets under ../shared/data: PYP mixture vs baselines")


def learning_curve(
    X: np.ndarray,
    y: np.ndarray,
    per_class: list[int],
    *,
    n_iter: int,
    burn_in: int,
    random_state: int,
    discounts: tuple[float | None, ...] = (0.0, None),
) -> list[dict[str, Any]]:
    """K found and pairwise accuracy when only the first ``m`` points of every class are clustered.

    One row per ``m`` in ``per_class`` and per prior (``discount=0``: Dirichlet process, ``None``:
    Pitman-Yor with d sampled).
    """
    rows = []
    classes = np.unique(y)
    for m in per_class:
        keep = np.concatenate([np.flatnonzero(y == c)[:m] for c in classes])
        for discount in discounts:
            model = PitmanYorGMM(discount=discount, n_iter=n_iter, burn_in=burn_in, random_state=random_state)
            model.set_params(progress=False).fit(X[keep])
            post = model.n_clusters_posterior()
            rows.append(
                {
                    "per class": m,
                    "points": keep.size,
                    "prior": "DP" if discount == 0.0 else "PYP",
                    "posterior mode of K": max(post, key=post.get),
                    "MAP K": model.n_clusters_,
                    "pairwise accuracy (MAP)": pairwise_accuracy(y[keep], model.labels_),
                }
            )
    return rows
