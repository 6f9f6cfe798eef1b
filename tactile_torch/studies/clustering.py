"""Report section: how many surfaces? The Pitman-Yor mixture on unlabelled features (method 2, unsupervised).

Reproduces the unsupervised study on the bundled synthetic stylus recordings (28 surfaces, a slow wear
drift over each recording) and, when present, on the real accelerometer sets of ``../shared/data``:

- the posterior of K (Fig. 9: mode, median, 95 % interval), the point estimate (minimum expected
  Variation of Information), the MAP sample, the similarity matrix, R-hat/ESS, the comparison with
  k-means, EM, EM + BIC and the variational DP mixture (Table 2), the discount d (Fig. 15), K along
  the chains (Fig. 10);
- prediction of unseen windows (Table 1, Fig. 11; a second session on worn surfaces);
- the learning curve (Figs. 12 and 14), Dirichlet process vs Pitman-Yor; new surfaces withheld.

``make run`` runs a reduced size (20 training windows of W = 800 per surface; the study fit at
``n_iter="auto"``, until R-hat of K < 1.01 and bulk ESS of K >= 400, within :data:`FIT_SECONDS`; the
other fits fixed chains of :data:`OTHER_SWEEPS`); ``--full`` the study's size (W = 1600, up to 50
windows per surface, every fit at ``"auto"``, every window size). Without :mod:`tactile_torch.signal`,
seeded Gaussian clusters in 3-D stand in.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import Any

import numpy as np

from ..clustering import NOVELTY_COMPONENTS
from ..metrics import pairwise_accuracy
from ..mixture import PitmanYorGMM
from .clustering_experiments import (
    STUDY,
    WITHHELD,
    cluster_and_compare,
    cluster_to_label,
    have_vibration_features,
    k_row,
    learning_curve,
    max_rhat,
    novelty_test,
    real_windows,
    synthetic_clusters,
)

TITLE = "Clustering: how many surfaces (Pitman-Yor mixture, mixture of finite mixtures)"

FIT_SECONDS = 30.0
"""Wall-clock budget of the default run's study fit (``n_iter="auto"``); its other fits run fixed chains."""
OTHER_SWEEPS = (700, 200)  # sweeps, burn-in of those (a fraction for the smaller ones): make run's time


# data: training period, later windows, a second session on worn surfaces
def _sizes(ctx) -> dict[str, Any]:
    if ctx.quick:
        return dict(W=400, train=6, test=1, surfaces=6, n_iter=150, burn_in=50, chains=2, per=[1, 3, 6])
    if ctx.full:
        return dict(
            W=1600,
            train=30,
            test=6,
            surfaces=28,
            n_iter="auto",
            burn_in=1000,
            chains=4,
            per=[1, 2, 5, 10, 20, 30],
        )
    return dict(
        W=800,
        train=20,
        test=10,
        surfaces=28,
        n_iter="auto",
        burn_in=250,
        chains=4,
        per=[1, 2, 5, 10, 20],
        max_seconds=FIT_SECONDS,
        other_n_iter=OTHER_SWEEPS[0],
        other_burn_in=OTHER_SWEEPS[1],
    )


def _budget(sz: dict, *, study: bool = False) -> dict[str, Any]:
    """The time budget of an ``"auto"`` run (in the default run the study fit's only)."""
    if "max_seconds" not in sz or ("other_n_iter" in sz and not study):
        return {}
    return {"max_seconds": sz["max_seconds"]}


def _fraction(sz: dict, key: str, k: int, floor: int = 0) -> int | str:
    """``sz[key] // k`` (at least ``floor``; ``other_<key>`` first); ``"auto"`` stays (its burn-in: 250)."""
    if f"other_{key}" in sz:
        return max(floor, sz[f"other_{key}"] // k)
    if sz["n_iter"] == "auto":
        return "auto" if key == "n_iter" else sz["burn_in"]
    return max(floor, sz[key] // k)


def study_windows(ctx) -> dict[str, Any]:
    """Features of the bundled recordings: training period, five later test sets, a worn second session.

    Every recording is cut into windows of W samples in time order; the first ``train`` windows of
    each surface are the training period, the next ``5 x test`` windows the five consecutive test
    sets. The unsupervised transform (21 features, drop skew/kurt/m5, sqrt/log, standardise, PCA to
    3) is fitted on the training windows only. The second session is a later recording of the same
    surfaces, worn: roughness RMS, texture and impacts 15 % weaker (same seed, a new session stream).
    """
    import torch

    from ..data.stylus import make_vibration_recordings, surface_table
    from ..signal import fit_clustering_transform, window_features
    from .vibration_features import bundled_recordings

    sz = _sizes(ctx)

    def make() -> dict[str, Any]:
        rec = bundled_recordings(ctx)
        ds = rec.windows(sz["W"], max_per_recording=sz["train"] + 5 * sz["test"])
        keep = ds.labels.numpy() < sz["surfaces"]
        pos, y = ds.position.numpy()[keep], ds.labels.numpy()[keep]
        feats = window_features(ds.windows[torch.as_tensor(keep)].to(torch.float64))
        train = pos < sz["train"]
        # 5 components, as tactile-torch cluster's graph: K and clusters on the first 3, novelty on all 5
        transform, X5 = fit_clustering_transform(feats, NOVELTY_COMPONENTS, fit_rows=train)
        X = X5[:, :3]
        block = (pos - sz["train"]) // sz["test"]
        worn = [
            replace(s, rms_g=0.85 * s.rms_g, texture=0.85 * s.texture, impact_g=0.85 * s.impact_g)
            for s in surface_table(sz["surfaces"])
        ]
        seconds = (sz["train"] + 1) * sz["W"] / 800.0
        rec2 = make_vibration_recordings(  # the bundled recordings' seed: the same surfaces' jitter
            surfaces=worn,
            duration_s=seconds,
            n_sessions=2,
            random_state=ctx.seed("vibration_features", "bundled recordings"),
        )
        later = rec2.windows(sz["W"])
        second = np.char.endswith(np.asarray(rec2.session, dtype=str)[later.recording.numpy()], "/1")
        f2 = window_features(later.windows[torch.as_tensor(second)].to(torch.float64))
        return {
            "X": X[train],
            "y": y[train],
            "tests": [(X[block == b], y[block == b]) for b in range(5)],
            "X_novelty": X5[train],
            "tests_novelty": [(X5[block == b], y[block == b]) for b in range(5)],
            "session2": (np.asarray(transform.transform(f2))[:, :3], later.labels.numpy()[second]),
            "transform": transform,
            "names": [str(c) for c in rec.class_names[: sz["surfaces"]]],
        }

    return ctx.cached(f"clustering_study_{sz['W']}_{sz['train']}_{sz['surfaces']}", make)


def _synthetic_study(ctx) -> dict[str, Any]:
    n, per = (6, 12) if ctx.quick else (28, 20)
    X, y = synthetic_clusters(n, per + 50, seed=ctx.seed("clustering", "synthetic clusters"))
    first = np.tile(np.arange(per + 50), n) < per
    rest = ~first
    tests = [(X[rest][b::5], y[rest][b::5]) for b in range(5)]
    return {"X": X[first], "y": y[first], "tests": tests, "session2": tests[-1], "transform": None}


# the section
def run(section, ctx) -> None:
    from threadpoolctl import threadpool_limits

    # 3 x 3 matrices and a few hundred points: BLAS threads only contend (the baselines: 24 s with them,
    # 1.4 s without); the chains have their own threads. The fits' convergence warnings become one line.
    with threadpool_limits(1), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        study = _run(section, ctx)
    unconverged = [
        w
        for w in caught
        if issubclass(w.category, RuntimeWarning) and str(w.message).startswith("PitmanYorGMM:")
    ]
    for w in caught:
        if w not in unconverged:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    sz = _sizes(ctx)
    line = convergence_line(sz, study, len(unconverged))
    if sz["n_iter"] == "auto" or unconverged:
        section.text(f"**Convergence:** {line}")
        print(f"[report] clustering: {line}", flush=True)


def convergence_line(sz: dict, study: PitmanYorGMM, n: int) -> str:
    """The section's convergence line: the study fit's outcome and how many of the ``n`` warned."""
    targets = "R-hat < 1.01 for K, alpha and d, bulk ESS of K >= 400"
    line = f"every mixture of this section converged ({targets})"
    if "other_n_iter" in sz:  # the default run: the study fit at "auto", the others fixed chains
        ok = study.stopped_by_ == "converged"
        line = f"the study's fit (the headline K) {'converged' if ok else 'missed the targets'} in "
        line += f"{study.fit_seconds_:.1f} s ({targets}); {n - (not ok)} of the section's other fits, at "
        line += f"fixed chains of {sz['other_n_iter']} sweeps or fewer, missed them"
    elif n:
        where = (
            f"within their {sz['max_seconds']:g} s" if "max_seconds" in sz else f"at {sz['n_iter']} sweeps"
        )
        line = f"{n} of this section's fits missed the convergence targets ({targets}) {where}"
    line += ": read their posteriors of K as indicative (`PitmanYorGMM.summary()` shows R-hat)." if n else "."
    return line


def _run(section, ctx) -> PitmanYorGMM:
    sz = _sizes(ctx)
    vib = have_vibration_features()
    data = study_windows(ctx) if vib else _synthetic_study(ctx)
    X, y = data["X"], data["y"]
    n_surf = int(np.unique(y).size)
    what = (
        f"the bundled synthetic stylus recordings: {n_surf} surfaces, the first {sz['train']} windows of "
        f"W = {sz['W']} samples of each recording (the training period); 21 window features, then the "
        "unsupervised transform (drop skew/kurt/m5, sqrt/log, standardise, PCA to 3)"
        if vib
        else f"{n_surf} seeded Gaussian clusters in 3-D (tactile_torch.signal is not installed)"
    )
    length = (
        "run until R-hat < 1.01 and bulk ESS of K >= 400 (`n_iter='auto'`"
        + (f", at most {sz['max_seconds']:g} s" if "max_seconds" in sz else "")
        + (
            f"; the other fits: fixed chains of {sz['other_n_iter']} sweeps or fewer)"
            if "other_n_iter" in sz
            else ")"
        )
        if sz["n_iter"] == "auto"
        else f"of {sz['n_iter']} Gibbs sweeps ({sz['burn_in']} burn-in)"
    )
    section.text(
        f"Unlabelled data: {what}. The Pitman-Yor mixture is not told K: {sz['chains']} chains {length}, "
        "each from its own k-means start. The "
        "headline is the posterior of K; the clustering is the point estimate that minimises the "
        "posterior expected Variation of Information over the saved samples (Wade & Ghahramani 2018). "
        "The MAP sample is shown and named as such: the joint density over spaces whose dimension grows "
        "with K favours few components, so its K sits in the low tail of the posterior."
        + (
            ""
            if ctx.full
            else " `--full` runs the study's size (W = 1600, longer chains, every window size)."
        )
    )
    section.command(ctx.command("clustering"))
    out = cluster_and_compare(
        X,
        y,
        n_iter=sz["n_iter"],
        burn_in=sz["burn_in"],
        n_chains=sz["chains"],
        random_state=ctx.seed("clustering", "study mixture and baselines"),
        **_budget(sz, study=True),
        max_components=n_surf + (2 if ctx.quick else 6 if ctx.full else 4),
        min_components=None if ctx.full else max(1, n_surf - 6),
        n_init=5 if ctx.full else 2,
    )
    model: PitmanYorGMM = out["model"]
    section.table(out["rows"], caption=f"Clustering {n_surf} surfaces: PYP mixture vs baselines (Table 2)")
    section.text("```\n" + model.summary() + "\n```")
    _robust_k(section, X, y, model, sz, ctx)
    section.table(
        [{k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()} for r in model.convergence_],
        caption="Convergence across chains: rank-normalised split R-hat and ESS (Vehtari et al. 2021; > 1.01 warns)",
    )
    _posterior_figures(section, model, y)
    _prediction(section, model, data, ctx)
    _learning_curve(section, data, sz, ctx)
    if vib:
        _novelty(section, data, sz, ctx)
    if ctx.full and vib:
        _window_sizes(section, ctx, sz)
    real_data(
        section, ctx, n_iter=_fraction(sz, "n_iter", 2), burn_in=_fraction(sz, "burn_in", 2), **_budget(sz)
    )
    return model


def _robust_k(section, X: np.ndarray, y: np.ndarray, study: PitmanYorGMM, sz: dict, ctx) -> None:
    """The posterior of K of the study's Pitman-Yor mixture and of the mixture of finite mixtures."""
    from .clustering_k import SETTINGS, coverage_row, gaussian_three, k_coverage

    fit = dict(
        random_state=ctx.seed("clustering", "posterior of K"),
        n_iter=_fraction(sz, "n_iter", 1),
        burn_in=_fraction(sz, "burn_in", 1),
        n_chains=sz["chains"],
        **_budget(sz),
    )
    rows = [coverage_row("this section's data", y, "pyp (study)", study, study.fit_seconds_)]
    rows += k_coverage({"this section's data": (X, y)}, {"mfm": SETTINGS["mfm"]}, **fit)
    if ctx.full:  # the default run keeps its time; docs/mixture.md has every source (clustering_k)
        rows += k_coverage(
            {
                "3 Gaussian clusters (sd 1, 5 apart)": gaussian_three(
                    ctx.seed("clustering", "three gaussian clusters")
                )
            },
            {k: SETTINGS[k] for k in ("pyp (study)", "mfm")},
            **fit,
        )
    section.text(
        "The posterior of K of a Dirichlet- or Pitman-Yor-process mixture is not consistent for the number of "
        "components (Miller & Harrison 2014); a mixture of finite mixtures (MFM: a prior on K, Miller & Harrison "
        "2018) is, with the same Gibbs sampler and other weights. `PitmanYorGMM`'s default model is the MFM; this "
        "section's other tables use the study's Pitman-Yor mixture (`model='pyp'`). All five data sources, with "
        "and without the coarsened posterior: `python -m tactile_torch.studies.clustering_k` (docs/mixture.md)."
    )
    section.table(
        rows, caption="Posterior of K: the study's Pitman-Yor mixture vs the mixture of finite mixtures"
    )


def _posterior_figures(section, model: PitmanYorGMM, y: np.ndarray) -> None:
    import matplotlib.pyplot as plt

    n_true = int(np.unique(y).size)
    ks = model.n_clusters_summary_
    post = model.n_clusters_posterior()
    fig, ax = plt.subplots(figsize=(6, 3.2))
    ax.bar(list(post), list(post.values()), color="tab:blue", label="posterior of K")
    ax.axvspan(
        ks["interval"][0] - 0.5, ks["interval"][1] + 0.5, color="tab:blue", alpha=0.1, label="95% interval"
    )
    ax.axvline(n_true, color="k", ls="--", lw=1, label=f"true K = {n_true}")
    ax.axvline(
        ks["point_estimate"], color="tab:green", lw=1.5, label=f"point estimate {ks['point_estimate']}"
    )
    ax.axvline(ks["map"], color="tab:red", ls=":", lw=1.5, label=f"MAP sample {ks['map']}")
    ax.set_xlabel("number of surfaces K")
    ax.set_ylabel("posterior probability")
    ax.legend(fontsize=7)
    section.figure(
        fig,
        "clustering posterior K",
        "Posterior over the number of surfaces K (all chains, after burn-in), Fig. 9",
    )

    order = np.lexsort((y, model.labels_))
    sim = model.posterior_similarity()[np.ix_(order, order)]
    fig, ax = plt.subplots(figsize=(4.6, 4))
    im = ax.imshow(sim, cmap="viridis", vmin=0, vmax=1, interpolation="nearest")
    ax.set_xlabel("window (sorted by point-estimate cluster)")
    ax.set_ylabel("window (same order)")
    fig.colorbar(im, ax=ax, label="P(same component)")
    section.figure(
        fig,
        "clustering similarity",
        "Posterior similarity matrix, windows sorted by the point estimate's clusters",
    )

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.4))
    burn_in = model.n_iter_ - model.n_clusters_samples_.size // model.trace_["n_clusters"].shape[0]
    for c in range(model.trace_["n_clusters"].shape[0]):
        acc = [pairwise_accuracy(y, z) for z in model.labels_samples_[c]]
        ax1.plot(model.labels_sweeps_ + 1, acc, lw=1, label=f"chain {c}")
        ax2.plot(np.arange(1, model.n_iter_ + 1), model.trace_["n_clusters"][c], lw=0.8, label=f"chain {c}")
    ax2.axhline(n_true, color="k", ls="--", lw=1, label=f"true K = {n_true}")
    ax1.axhline(1.0, color="k", ls=":", lw=0.8, label="perfect clustering")
    for ax in (ax1, ax2):
        ax.set_xscale("log")
        ax.set_xlabel("sweep (log scale)")
        ax.axvline(burn_in + 1, color="grey", lw=0.8, label=f"end of burn-in ({burn_in} sweeps)")
        ax.legend(fontsize=7)
    ax1.set_ylabel("pairwise accuracy")
    ax2.set_ylabel("number of components K")
    fig.tight_layout()
    section.figure(
        fig,
        "clustering accuracy along chain",
        "Pairwise accuracy (saved partitions) and K along each chain, Fig. 10",
    )

    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist(model.discount_samples_, bins=40, range=(0, 1), color="tab:orange")
    ax.set_xlabel("discount d")
    ax.set_ylabel("sweeps")
    section.figure(
        fig,
        "clustering discount",
        "Posterior of the Pitman-Yor discount d (d = 0: Dirichlet process), Fig. 15",
    )


def _prediction(section, model: PitmanYorGMM, data: dict, ctx) -> None:
    """Table 1 (five later test sets), Fig. 11 (confusion matrix) and the worn second session."""
    import matplotlib.pyplot as plt

    y = data["y"]
    mapping = cluster_to_label(model.labels_, y, model.n_clusters_)
    rows, pooled_true, pooled_pred = [], [], []
    sets = [(f"test set {b + 1}", Xt, yt) for b, (Xt, yt) in enumerate(data["tests"])]
    sets.append(("second session (worn surfaces)", *data["session2"]))
    for name, Xt, yt in sets:
        if len(yt) == 0:
            continue
        row = {"windows": name, "n": len(yt)}
        for using in ("samples", "point"):
            pred = mapping[model.predict(Xt, using=using)]
            row[f"success rate ({using})"] = float(np.mean(pred == yt))
            row[f"novel ({using})"] = float(np.mean(pred == -1))
        rows.append(row)
        if name.startswith("test"):
            pooled_true.append(yt)
            pooled_pred.append(mapping[model.predict(Xt)])
    section.text(
        "Prediction of unseen windows: the mixture fitted on the training period labels later windows; each "
        "cluster is mapped to the most frequent true surface of its training windows. `samples`: posterior "
        "predictive averaged over the saved samples; `point`: the point estimate's components (what the "
        "exported ONNX graph computes). Novel windows (label -1, a new component explains them better) count "
        "as failures. The recordings drift slowly (wear of the probe), so later sets are harder."
    )
    section.table(rows, caption="Table 1: success rate on five consecutive test sets and a second session")
    yt, pt = np.concatenate(pooled_true), np.concatenate(pooled_pred)
    n = int(max(y.max(), yt.max())) + 1
    cm = np.zeros((n, n + 1))
    np.add.at(cm, (yt, np.where(pt < 0, n, pt)), 1)
    cm /= np.maximum(cm.sum(axis=1, keepdims=True), 1)
    names = list(data.get("names") or [str(k) for k in range(n)])[:n]
    names += [str(k) for k in range(len(names), n)]
    fig, ax = plt.subplots(figsize=(8.2, 7.4))
    im = ax.imshow(cm, cmap="Blues", vmin=0, vmax=1)
    ax.set_xticks(np.arange(n + 1), [*names, "novel"], rotation=90, fontsize=6)
    ax.set_yticks(np.arange(n), names, fontsize=6)
    ax.set_xlabel("predicted surface (cluster mapped to its most frequent surface; last column: novel)")
    ax.set_ylabel("true surface")
    fig.colorbar(im, ax=ax, label="share of the true surface's windows", shrink=0.8)
    fig.tight_layout()
    section.figure(
        fig,
        "clustering confusion",
        "Confusion matrix of the pooled test sets after mapping clusters to labels, Fig. 11",
    )


def _learning_curve(section, data: dict, sz: dict, ctx) -> None:
    import matplotlib.pyplot as plt

    X, y = data["X"], data["y"]
    per = [m for m in sz["per"] if m <= np.bincount(y).min()]
    rows = learning_curve(
        X,
        y,
        per,
        n_iter=_fraction(sz, "n_iter", 3, 150),
        burn_in=_fraction(sz, "burn_in", 3, 50),
        random_state=ctx.seed("clustering", "learning curve"),
        **_budget(sz),
    )
    section.table(
        rows,
        caption="Learning curve: K and pairwise accuracy with m windows per surface, DP vs PYP (Figs. 12, 14)",
    )
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.4))
    for prior, style in (("DP", "o-"), ("PYP", "s--")):
        sel = [r for r in rows if r["prior"] == prior]
        ax1.plot([r["per class"] for r in sel], [r["expected K"] for r in sel], style, label=prior)
        ax2.plot([r["per class"] for r in sel], [r["pairwise accuracy"] for r in sel], style, label=prior)
    ax1.axhline(int(np.unique(y).size), color="k", ls="--", lw=1, label="true K")
    ax1.set_ylabel("expected K (posterior mean)")
    ax2.set_ylabel("pairwise accuracy (point estimate)")
    for ax in (ax1, ax2):
        ax.set_xscale("log")
        ax.set_xticks(per)  # the measured sizes, as plain numbers (not 10^0, 10^1)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("windows per surface (log scale)")
        ax.legend(fontsize=7)
    fig.tight_layout(w_pad=2.0)  # the right panel's y-label clear of the left panel
    section.figure(
        fig, "clustering learning curve", "Learning curve, Dirichlet process vs Pitman-Yor (Figs. 12, 14)"
    )


def _novelty(section, data: dict, sz: dict, ctx) -> None:
    withheld = tuple(c for c in WITHHELD if c < sz["surfaces"]) or (0,)
    rows = []
    for prior in ("pyp", "mfm"):
        row = novelty_test(
            data.get("X_novelty", data["X"]),
            data["y"],
            data.get("tests_novelty", data["tests"]),
            withheld,
            cluster_features=3 if "X_novelty" in data else None,
            model=prior,
            coarsen=None,
            n_iter=_fraction(sz, "n_iter", 2),
            burn_in=_fraction(sz, "burn_in", 2),
            n_chains=2,
            random_state=ctx.seed("clustering", "novelty"),
            **_budget(sz),
        )
        rows.append({"data": "bundled stylus recordings", "model": prior, **row})
    section.text(
        f"New surfaces: surfaces {list(withheld)} are withheld from training; the test windows of all surfaces "
        "are then labelled. A window is novel (label -1) when the prior predictive of a new component, weighted "
        "by the prior's new-component weight (Pitman-Yor: alpha + d K; MFM: gamma V_n(K+1)/V_n(K)), beats every "
        "existing component: a new surface is a new component of the model. `tactile-torch stream --discover N` "
        "proposes a new surface after N novel windows in a row; the columns 'after 3 in a row' decide so (N = 3). "
        "The 'calibrated' columns are the rule of `tactile-torch cluster` bundles: a window is novel when minus "
        "its log density (over 5 principal components, with the partition found on the first 3) exceeds the 98 % quantile of the same on windows of known surfaces the fit did not see "
        "(here the first half of each known surface's test windows; decided on the second halves), or, for "
        "'mean of 3', when the mean of 3 consecutive windows exceeds the quantile of such means (docs/mixture.md)."
    )
    section.table(
        rows, caption="Novelty: recall on withheld surfaces, false alarms on known ones (per window)"
    )


def _window_sizes(section, ctx, sz: dict) -> None:
    """K and pairwise accuracy for several window sizes W (the study: K = 28 found for W >= 400)."""
    import torch

    from ..signal import fit_clustering_transform, window_features
    from .vibration_features import bundled_recordings

    rows = []
    for size in (200, 400, 800, 1600):
        ds = bundled_recordings(ctx).windows(size, max_per_recording=50)
        feats = window_features(ds.windows.to(torch.float64))
        _, X = fit_clustering_transform(feats, 3)
        y = ds.labels.numpy()
        model = PitmanYorGMM(
            **STUDY,
            n_iter=_fraction(sz, "n_iter", 2),
            burn_in=_fraction(sz, "burn_in", 2),
            random_state=ctx.seed("clustering", "window sizes"),
            **_budget(sz),
            progress=False,
        ).fit(X)
        rows.append(
            {
                "W": size,
                "windows": len(y),
                **k_row(model),
                "pairwise accuracy": pairwise_accuracy(y, model.labels_),
            }
        )
    section.table(rows, caption="Window size: K found on the bundled recordings (50 windows per surface)")


def real_data(section, ctx, *, n_iter: int | str, burn_in: int, **budget: Any) -> None:
    """The honest K, accuracy and novelty on the real accelerometer sets of ``../shared/data`` when present."""
    from sklearn.cluster import KMeans

    from ..data import shared_data_dir

    present = [name for name in ("hapmat_imu5", "borealtc_imu") if shared_data_dir(name) is not None]
    if not present or not have_vibration_features():
        section.text("The real accelerometer sets (hapmat_imu5, borealtc_imu) are absent: skipped.")
        return
    per = 20 if ctx.quick else 40
    rows, nov = [], []
    for name in present:
        X, y, pos, n_classes = real_windows(name, per)
        seed = ctx.seed("clustering", f"real data {name}")
        model = PitmanYorGMM(
            n_iter=n_iter, burn_in=burn_in, random_state=seed, progress=False, **STUDY, **budget
        ).fit(X)
        robust = PitmanYorGMM(
            n_iter=n_iter, burn_in=burn_in, random_state=seed, progress=False, **budget
        ).fit(X)
        km_labels = KMeans(n_classes, n_init=10, random_state=seed).fit_predict(X)
        rows.append(
            {
                "data set": name,
                "classes": n_classes,
                "windows": len(y),
                **k_row(model),
                "MFM: K 95% interval": "[{}, {}]".format(*robust.n_clusters_summary_["interval"]),
                "MFM: K point estimate": robust.n_clusters_,
                "pairwise accuracy (point estimate)": pairwise_accuracy(y, model.labels_),
                "pairwise accuracy (MAP)": pairwise_accuracy(y, model.map_labels_),
                "k-means given K": pairwise_accuracy(y, km_labels),
                "max R-hat": max_rhat(model),
            }
        )
        # novelty: withhold the last class; train on the first half of each class's windows (in time)
        first = np.zeros(len(y), dtype=bool)
        for c in np.unique(y):
            idx = np.flatnonzero(y == c)
            first[idx[np.argsort(pos[idx])[: idx.size // 2]]] = True
        withheld = (int(y.max()),)
        for prior in ("pyp", "mfm"):
            row = novelty_test(
                X[first], y[first], [(X[~first], y[~first])], withheld, model=prior, coarsen=None,
                n_iter=n_iter, burn_in=burn_in, n_chains=2, random_state=seed, **budget,
            )  # fmt: skip
            nov.append({"data": name, "model": prior, **row})
    section.text(
        "Real accelerometer data (`tactile_torch.data.load_hapmat_imu5` / `load_borealtc_imu`: 100 Hz IMU logs, "
        f"not an 800 Hz stylus): 2 s windows, up to {per} per class, the same features and transform."
    )
    section.table(
        rows,
        caption="Real data sets: the posterior of K, the point estimate and the MAP sample (Pitman-Yor, the "
        "study's), and the mixture of finite mixtures (MFM, PitmanYorGMM's default model) at the same chain length",
    )
    section.table(
        nov, caption="Real data sets: novelty of a withheld class (trained on the first half of each class)"
    )
