"""Posterior summaries of a fitted :class:`PitmanYorGMM`: the posterior of K, and the readable summary."""

from __future__ import annotations

import numpy as np

from ._diagnostics import RHAT_THRESHOLD

_POINT_ESTIMATE_NAMES = {
    "vi": "minimises the expected VI",
    "binder": "minimises Binder's loss",
    "map": "the MAP sample",
}


def n_clusters_posterior(ks: np.ndarray) -> dict[int, float]:
    """Return the posterior distribution of K from its samples ``ks``, as {K: share of the samples}."""
    values, counts = np.unique(ks, return_counts=True)
    return {int(v): float(c) / ks.size for v, c in zip(values, counts, strict=True)}


def n_clusters_summary(ks: np.ndarray, point_estimate: int, map_k: int) -> dict:
    """Return the summary of the posterior of K from its samples ``ks`` (see ``n_clusters_summary_``)."""
    values, counts = np.unique(ks, return_counts=True)
    # K is an integer: the interval's ends are sampled values (inverted-CDF quantiles), never 6.025
    lo, hi = (int(v) for v in np.quantile(ks, [0.025, 0.975], method="inverted_cdf"))
    return {
        "mode": int(values[np.argmax(counts)]),
        "mode_probability": float(counts.max() / ks.size),
        "median": float(np.median(ks)),
        "mean": float(ks.mean()),
        "interval": (lo, hi),
        "point_estimate": point_estimate,
        "map": map_k,
    }


def _versus_mode(k: int, ks: dict) -> str:
    """Where ``k`` sits in the posterior of K summarised by ``ks``: the words are computed, never fixed."""
    lo, hi = ks["interval"]
    side = "equal to" if k == ks["mode"] else ("below" if k < ks["mode"] else "above")
    where = "inside" if lo <= k <= hi else "outside"
    return f"{side} the posterior mode {ks['mode']}, {where} the 95% interval"


_STOPPED = {
    "converged": "; stopped: convergence targets met",
    "max_iter": "; stopped: the sweep budget max_iter ran out",
    "max_seconds": "; stopped: the time budget max_seconds ran out",
    "stuck": "; stopped early: the chains are stuck in different modes of K",
    "ceiling": "; stopped early: K reached the prior's ceiling",
    "projected": "; stopped early: the budget cannot reach the convergence targets",
}


def summary_text(model) -> str:
    """Return the summary of the fitted ``model``: the posterior of K first, then the point estimate, the MAP sample, convergence."""
    ks = model.n_clusters_summary_
    post = n_clusters_posterior(model.n_clusters_samples_)
    chains, n_iter = model.trace_["n_clusters"].shape
    loss = "expected VI" if model.point_estimate != "binder" else "expected Binder loss"
    lines = [
        f"PitmanYorGMM: {chains} chain(s) x {n_iter} sweeps ({model.n_clusters_samples_.size // chains} "
        f"per chain after burn-in), {model.sweep_seconds_ * 1e3:.2f} ms/sweep, {model.fit_seconds_:.1f} s"
        + _STOPPED.get(getattr(model, "stopped_by_", ""), ""),
        f"K, posterior: mode {ks['mode']} (p = {ks['mode_probability']:.3f}), median {ks['median']:g}, "
        f"95% interval [{ks['interval'][0]}, {ks['interval'][1]}]",
        f"point estimate ({_POINT_ESTIMATE_NAMES[model.point_estimate]}; {loss} {model.expected_loss_:.4f}): "
        f"{model.n_clusters_} clusters",
        f"MAP sample (largest joint density): K = {model.map_n_clusters_}, {_versus_mode(model.map_n_clusters_, ks)} "
        f"(chain {model.map_chain_}, sweep {model.map_sweep_})",
        "P(K): " + ", ".join(f"{k}: {p:.3f}" for k, p in sorted(post.items(), key=lambda kv: -kv[1])[:8]),
        "convergence (rank-normalised split R-hat; bulk / tail ESS): "
        + "; ".join(
            f"{r['quantity']} {r['R-hat']:.3f} ({r['ESS bulk']:.0f} / {r['ESS tail']:.0f})"
            for r in model.convergence_
        ),
    ]
    bad = [r["quantity"] for r in model.convergence_ if np.isfinite(r["R-hat"]) and not r["converged"]]
    if getattr(model, "stop_reason_", None):
        lines.append(f"WARNING: {model.stop_reason_}")
    elif bad:
        lines.append(
            f"WARNING: R-hat > {RHAT_THRESHOLD} for {', '.join(bad)}: the chains disagree, run longer"
        )
    if getattr(model, "session_scale_", None) is not None:
        lam, omega = model.session_scale_samples_, model.offset_variance_samples_
        lines.insert(
            2,
            f"sessions: {model.n_sessions_}; a session moves every component by an offset (variance omega, "
            f"posterior mean {omega.mean():.3g}, whitened units) and each by its own effect (lambda, its variance "
            f"relative to the component's, posterior mean {lam.mean():.3g}, 95% [{np.quantile(lam, 0.025):.3g}, "
            f"{np.quantile(lam, 0.975):.3g}]); K counts components across sessions",
        )
    if model.model == "mfm":
        lines.insert(
            2,
            f"model: mixture of finite mixtures (K ~ geometric, mean {model.k_prior_mean:g}; weights ~ "
            f"Dirichlet({model.weight_concentration:g})), likelihood power zeta = {model.zeta_:.4g}"
            + (" (not coarsened)" if model.zeta_ == 1.0 else f" (coarsened, coarsen = {model.coarsen:g})"),
        )
        hyper = (("beta", model.beta_samples_),)
    else:
        lines.insert(2, "model: Pitman-Yor process mixture (the study's)")
        hyper = (
            ("alpha", model.alpha_samples_),
            ("d", model.discount_samples_),
            ("beta", model.beta_samples_),
        )
    for name, s in hyper:
        q = np.quantile(s, [0.025, 0.5, 0.975])
        lines.append(f"{name}: median {q[1]:.3g}, 95% interval [{q[0]:.3g}, {q[2]:.3g}]")
    st = model.split_merge_stats_
    lines.append(
        f"split-merge: {st['split_accepted']}/{st['split_proposed']} splits, "
        f"{st['merge_accepted']}/{st['merge_proposed']} merges accepted"
    )
    return "\n".join(lines)
