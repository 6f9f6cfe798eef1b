"""Plain NumPy reference of the Pitman-Yor Gaussian-mixture Gibbs sampler (no numba, no split-merge).

The same model and the same updates as :class:`tactile_torch.mixture.PitmanYorGMM` (see its
docstring), written the way a careful user would write them without a compiler: Neal's algorithm 8
one point at a time, every step vectorised over the components with NumPy; component and
hyperparameter updates with ``numpy.linalg``; slice sampling for beta, alpha and d. Written
independently of :mod:`tactile_torch.mixture._gibbs`, it serves the tests as an independent check of the
posterior and the benchmark as the baseline whose per-sweep time is compared.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln, multigammaln

W_FLOOR = 1e-10


def whiten(X: np.ndarray) -> np.ndarray:
    """Return ``A^{-1}(X - mean)`` with ``A A^T`` the covariance (ddof=1, ridge 1e-9 of the mean variance)."""
    n, D = X.shape
    cov = np.cov(X, rowvar=False, ddof=1).reshape(D, D) if n > 1 else np.zeros((D, D))
    level = np.trace(cov) / D
    A = np.linalg.cholesky(cov + 1e-9 * level * np.eye(D)) if level > 0 else np.eye(D)
    return np.linalg.solve(A, (X - X.mean(axis=0)).T).T


def wishart_rvs_chol(rng: np.random.Generator, dof: float, scale: np.ndarray, size: int) -> np.ndarray:
    """Cholesky factors (size, D, D) of Wishart(dof, scale) draws (Bartlett decomposition)."""
    D = scale.shape[0]
    C = np.linalg.cholesky(scale)
    A = np.zeros((size, D, D))
    rows, cols = np.tril_indices(D, -1)
    A[:, rows, cols] = rng.standard_normal((size, rows.size))
    chi2 = np.maximum(rng.chisquare(dof - np.arange(D), size=(size, D)), 1e-300)
    A[:, np.arange(D), np.arange(D)] = np.sqrt(chi2)
    return C @ A


def _chol_logdet(L: np.ndarray) -> np.ndarray:
    return 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(-1)


def _slice(rng, f, x0, lo=-np.inf, hi=np.inf, width=1.0):
    logy = f(x0) + math.log(rng.random())
    if np.isfinite(lo) and np.isfinite(hi):
        left, right = lo, hi
    else:
        left = x0 - width * rng.random()
        right = left + width
        while left > lo and f(left) > logy:
            left -= width
        while right < hi and f(right) > logy:
            right += width
    while True:
        x1 = left + (right - left) * rng.random()
        if lo < x1 < hi and f(x1) > logy:
            return x1
        if x1 < x0:
            left = x1
        else:
            right = x1


def reference_gibbs(
    X: np.ndarray,
    *,
    n_iter: int,
    alpha: float | None = None,
    discount: float | None = None,
    n_aux: int = 5,
    init_labels: np.ndarray | None = None,
    prior_only: bool = False,
    random_state: int = 0,
    on_sweep=None,
) -> dict:
    """Run the reference sampler for ``n_iter`` sweeps; return traces of K, alpha, d, beta and the last labels.

    ``on_sweep(sweep, labels)`` is called after every sweep if given.
    """
    rng = np.random.default_rng(random_state)
    X = whiten(np.asarray(X, dtype=np.float64))
    n, D = X.shape
    eye = np.eye(D)
    z = np.zeros(n, dtype=np.int64) if init_labels is None else np.unique(init_labels, return_inverse=True)[1]
    K = int(z.max()) + 1
    counts = np.bincount(z, minlength=K)
    a = 1.0 if alpha is None else float(alpha)
    d = 0.25 if discount is None else float(discount)
    beta = float(D)
    xi, R, W = np.zeros(D), eye.copy(), eye.copy()
    mus = np.array([X[z == k].mean(axis=0) for k in range(K)])
    Ls = wishart_rvs_chol(rng, beta, np.linalg.inv(beta * W), K)
    ldets = _chol_logdet(Ls)
    trace = {k: np.zeros(n_iter) for k in ("n_clusters", "alpha", "discount", "beta")}
    half = 0.5 * D * math.log(2 * math.pi)
    for sweep in range(n_iter):
        # ---- Neal's algorithm 8 (auxiliary precisions integrated out: Student-t weights)
        R_inv_chol = np.linalg.cholesky(np.linalg.inv(R))
        V0 = np.linalg.inv(beta * W)
        t_norm = (
            gammaln(0.5 * (beta + 1))
            - gammaln(0.5 * (beta - D + 1))
            - 0.5 * D * math.log(math.pi)
            + 0.5 * np.linalg.slogdet(V0)[1]
        )
        for i in range(n):
            c = z[i]
            counts[c] -= 1
            aux_mu = xi + rng.standard_normal((n_aux, D)) @ R_inv_chol.T
            if counts[c] == 0:
                aux_mu[0] = mus[c]
                mus, Ls, ldets, counts = (np.delete(v, c, axis=0) for v in (mus, Ls, ldets, counts))
                z[z > c] -= 1
                K -= 1
            new_prior = math.log(a + d * K) - math.log(n_aux) if K > 0 else -math.log(n_aux)
            if prior_only:
                lw = np.concatenate([np.log(counts - d), np.full(n_aux, new_prior)])
            else:
                y = np.einsum("kab,ka->kb", Ls, X[i] - mus)
                old = np.log(counts - d) + 0.5 * ldets - half - 0.5 * (y * y).sum(1)
                dev = X[i] - aux_mu
                q = np.einsum("ka,ab,kb->k", dev, V0, dev)
                lw = np.concatenate([old, new_prior + t_norm - 0.5 * (beta + 1) * np.log1p(q)])
            p = np.exp(lw - lw.max())
            t = int(np.searchsorted(np.cumsum(p), rng.random() * p.sum(), side="right"))
            t = min(t, K + n_aux - 1)
            if t < K:
                z[i] = t
                counts[t] += 1
            else:
                v = X[i] - aux_mu[t - K]
                scale = V0 if prior_only else np.linalg.inv(beta * W + np.outer(v, v))
                L_new = wishart_rvs_chol(rng, beta if prior_only else beta + 1, scale, 1)
                mus = np.concatenate([mus, aux_mu[t - K][None]])
                Ls = np.concatenate([Ls, L_new])
                ldets = np.concatenate([ldets, _chol_logdet(L_new)])
                counts = np.concatenate([counts, [1]])
                z[i] = K
                K += 1
        # ---- components: S | mu, then mu | S
        for k in range(K):
            pts = X[z == k] if not prior_only else X[:0]
            dev = pts - mus[k]
            Lk = wishart_rvs_chol(rng, beta + len(pts), np.linalg.inv(beta * W + dev.T @ dev), 1)[0]
            S = Lk @ Lk.T
            lam = R + len(pts) * S
            cov = np.linalg.inv(lam)
            mean = cov @ (R @ xi + S @ pts.sum(axis=0))
            mus[k] = mean + np.linalg.cholesky(cov) @ rng.standard_normal(D)
            Ls[k] = Lk
            ldets[k] = _chol_logdet(Lk)
        # ---- hyperparameters
        lam = eye + K * R
        cov = np.linalg.inv(lam)
        xi = cov @ (R @ mus.sum(axis=0)) + np.linalg.cholesky(cov) @ rng.standard_normal(D)
        dev = mus - xi
        GR = wishart_rvs_chol(rng, D + K, np.linalg.inv(D * eye + dev.T @ dev), 1)[0]
        R = GR @ GR.T
        Ss = Ls @ np.transpose(Ls, (0, 2, 1))
        GW = wishart_rvs_chol(rng, D + K * beta, np.linalg.inv(D * eye + beta * Ss.sum(0)), 1)[0]
        if np.linalg.eigvalsh(GW @ GW.T).min() >= W_FLOOR:
            W = GW @ GW.T
        ldet_w = np.linalg.slogdet(W)[1]
        sum_ldet = ldets.sum()
        sum_tr = np.einsum("ab,kab->", W, Ss)

        def log_beta(u, K=K, ldet_w=ldet_w, sum_ldet=sum_ldet, sum_tr=sum_tr):
            b = D - 1 + math.exp(u)
            return (
                -0.5 * u
                - 0.5 * D * math.exp(-u)
                + K * (0.5 * b * D * math.log(0.5 * b) + 0.5 * b * ldet_w - multigammaln(0.5 * b, D))
                + 0.5 * (b - D - 1) * sum_ldet
                - 0.5 * b * sum_tr
            )

        beta = D - 1 + math.exp(_slice(rng, log_beta, math.log(beta - D + 1)))
        ks = np.arange(1, K)
        if alpha is None:

            def log_alpha(v, ks=ks, d=d):
                al = math.exp(v)
                return -0.5 * v - 0.5 / al + gammaln(al + 1) - gammaln(al + n) + np.log(al + ks * d).sum()

            a = math.exp(_slice(rng, log_alpha, math.log(a)))
        if discount is None:

            def log_d(dd, ks=ks, a=a, counts=counts):
                v = a + ks * dd
                if (v <= 0).any():
                    return -np.inf
                return np.log(v).sum() + (gammaln(counts - dd) - gammaln(1 - dd)).sum()

            d = _slice(rng, log_d, d, lo=max(0.0, -a) if alpha is not None else 0.0, hi=1.0)
        trace["n_clusters"][sweep] = K
        trace["alpha"][sweep] = a
        trace["discount"][sweep] = d
        trace["beta"][sweep] = beta
        if on_sweep is not None:
            on_sweep(sweep, z)
    return {**trace, "labels": z.copy()}
