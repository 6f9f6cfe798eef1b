"""Plain NumPy reference of the Pitman-Yor Gaussian-mixture Gibbs sampler (no numba, no split-merge).

The same model and the same updates as :class:`tactile_torch.mixture.PitmanYorGMM` (see its
docstring), written the way a careful user would write them without a compiler: Neal's algorithm 8
one point at a time, every step vectorised over the components with NumPy; component and
hyperparameter updates with ``numpy.linalg``; slice sampling for beta, alpha and d. Written
independently of :mod:`tactile_torch.mixture._gibbs`, it serves the tests as an independent check of the
posterior and the benchmark as the baseline whose per-sweep time is compared.

With ``sessions``: the session offsets ``c_s ~ N(0, omega I)`` and the random effect ``b_(s,k) ~
N(0, lambda S_k^{-1})`` of every (component, session) group, the latter integrated out given
``(mu_k, S_k, lambda)`` the plain way: a point's weight is the Gaussian conditional of its row (minus
its session's offset) given the other rows of its group (row covariance ``I + lambda 1 1^T`` built
as a matrix), the component updates use ``sum_s R_s^T A_s^{-1} R_s`` with ``A_s`` inverted by
``numpy.linalg.inv``, the offsets are drawn from their normal conditional written with the same
matrices, lambda is slice-sampled on ``log lambda`` (standard logistic prior) from the groups'
matrix-normal log densities and omega on ``log omega`` (half-Cauchy on its square root).
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
    sessions: np.ndarray | None = None,
    session_scale: float | None = None,
) -> dict:
    """Run the reference sampler for ``n_iter`` sweeps; return traces of K, alpha, d, beta and the last labels.

    ``on_sweep(sweep, labels)`` is called after every sweep if given. ``sessions`` (n,) ints: session
    effects with lambda fixed at ``session_scale`` or, when None, sampled (trace ``"session_scale"``).
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
    trace = {
        k: np.zeros(n_iter)
        for k in ("n_clusters", "alpha", "discount", "beta", "session_scale", "offset_variance")
    }
    half = 0.5 * D * math.log(2 * math.pi)
    sess = None if sessions is None else np.asarray(sessions)
    lam = 0.0 if sess is None else (1.0 if session_scale is None else float(session_scale))
    X_raw = X.copy()
    if sess is not None:
        offsets = np.zeros((int(sess.max()) + 1, D))
        omega = lam
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
                if sess is None:
                    y = np.einsum("kab,ka->kb", Ls, X[i] - mus)
                    old = np.log(counts - d) + 0.5 * ldets - half - 0.5 * (y * y).sum(1)
                else:
                    others = (np.arange(n) != i) & (sess == sess[i])  # X holds x - c_s (below)
                    old = np.log(counts - d) + np.array(
                        [_row_given_group(X[i], X[others & (z == k)], mus[k], Ls[k], lam) for k in range(K)]
                    ).reshape(K)
                dev = X[i] - aux_mu
                q = np.einsum("ka,ab,kb->k", dev, V0, dev) / (1.0 + lam)
                aux = new_prior + t_norm - 0.5 * D * math.log1p(lam) - 0.5 * (beta + 1) * np.log1p(q)
                lw = np.concatenate([old, aux])
            p = np.exp(lw - lw.max())
            t = int(np.searchsorted(np.cumsum(p), rng.random() * p.sum(), side="right"))
            t = min(t, K + n_aux - 1)
            if t < K:
                z[i] = t
                counts[t] += 1
            else:
                v = X[i] - aux_mu[t - K]
                scale = V0 if prior_only else np.linalg.inv(beta * W + np.outer(v, v) / (1.0 + lam))
                L_new = wishart_rvs_chol(rng, beta if prior_only else beta + 1, scale, 1)
                mus = np.concatenate([mus, aux_mu[t - K][None]])
                Ls = np.concatenate([Ls, L_new])
                ldets = np.concatenate([ldets, _chol_logdet(L_new)])
                counts = np.concatenate([counts, [1]])
                z[i] = K
                K += 1
        # ---- session offsets c_s | rest, then omega (sampled with lambda)
        if sess is not None and session_scale is None:
            for s_ in range(offsets.shape[0]):
                prec = np.eye(D) / omega
                h = np.zeros(D)
                for k in range(K if not prior_only else 0):
                    g = X_raw[(z == k) & (sess == s_)]
                    if not len(g):
                        continue
                    S = Ls[k] @ Ls[k].T
                    w = np.linalg.inv(_row_covariance(len(g), lam)).sum(0)  # A^{-1} 1
                    prec += w.sum() * S
                    h += S @ (w @ (g - mus[k]))
                cov = np.linalg.inv(prec)
                offsets[s_] = cov @ h + np.linalg.cholesky(cov) @ rng.standard_normal(D)

            ss_off = float((offsets**2).sum())

            def log_omega(u, ss=ss_off, m=offsets.size):
                if abs(u) > 30:
                    return -np.inf
                return -math.log1p(math.exp(u)) + 0.5 * u - 0.5 * m * u - 0.5 * ss / math.exp(u)

            omega = math.exp(_slice(rng, log_omega, math.log(omega)))
            X = X_raw - offsets[sess]
        # ---- components: S | mu, then mu | S
        for k in range(K):
            pts = X[z == k] if not prior_only else X[:0]
            if sess is None or prior_only:
                dev = pts - mus[k]
                Lk = wishart_rvs_chol(rng, beta + len(pts), np.linalg.inv(beta * W + dev.T @ dev), 1)[0]
                S = Lk @ Lk.T
                prec = R + len(pts) * S
                cov = np.linalg.inv(prec)
                mean = cov @ (R @ xi + S @ pts.sum(axis=0))
            else:
                groups = [X[(z == k) & (sess == s)] for s in np.unique(sess)]
                groups = [g for g in groups if len(g)]
                Q = sum(_group_quadratic(g - mus[k], lam) for g in groups)
                Lk = wishart_rvs_chol(rng, beta + len(pts), np.linalg.inv(beta * W + Q), 1)[0]
                S = Lk @ Lk.T
                # mu's likelihood: 1^T A^{-1} 1 per group times S, and 1^T A^{-1} X_g
                ones = [np.linalg.inv(_row_covariance(len(g), lam)).sum(0) for g in groups]
                prec = R + sum(o.sum() for o in ones) * S
                cov = np.linalg.inv(prec)
                mean = cov @ (R @ xi + S @ sum(o @ g for o, g in zip(ones, groups, strict=True)))
            mus[k] = mean + np.linalg.cholesky(cov) @ rng.standard_normal(D)
            Ls[k] = Lk
            ldets[k] = _chol_logdet(Lk)
        if sess is not None and session_scale is None:
            if prior_only:
                groups_k = []
            else:
                groups_k = [
                    (X[(z == k) & (sess == s)] - mus[k], Ls[k] @ Ls[k].T)
                    for k in range(K)
                    for s in np.unique(sess)
                    if np.any((z == k) & (sess == s))
                ]

            def log_lambda(u, groups_k=groups_k):
                if abs(u) > 30:
                    return -np.inf
                lm = math.exp(u)
                out = u - 2.0 * math.log1p(lm)
                for r, S in groups_k:
                    A = _row_covariance(len(r), lm)
                    out += -0.5 * D * np.linalg.slogdet(A)[1] - 0.5 * np.trace(S @ r.T @ np.linalg.inv(A) @ r)
                return out

            lam = math.exp(_slice(rng, log_lambda, math.log(lam)))
        # ---- hyperparameters
        prec = eye + K * R
        cov = np.linalg.inv(prec)
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
        trace["session_scale"][sweep] = lam
        trace["offset_variance"][sweep] = omega if sess is not None else 0.0
        if on_sweep is not None:
            on_sweep(sweep, z)
    return {**trace, "labels": z.copy()}


def _row_covariance(m: int, lam: float) -> np.ndarray:
    """``I + lambda 1 1^T`` (m, m): the rows of a (component, session) group share their session's effect."""
    return np.eye(m) + lam * np.ones((m, m))


def _group_quadratic(r: np.ndarray, lam: float) -> np.ndarray:
    """``R^T A^{-1} R`` for the residual rows ``r`` (m, D) of a group, ``A = I + lambda 1 1^T``."""
    return r.T @ np.linalg.inv(_row_covariance(len(r), lam)) @ r


def _row_given_group(x: np.ndarray, others: np.ndarray, mu: np.ndarray, L: np.ndarray, lam: float) -> float:
    """``log p(x | other rows of its group)`` of the matrix normal with row covariance ``I + lambda 1 1^T``.

    Gaussian conditioning of one row on the others: mean ``mu + a^T B^{-1} (others - mu)``, row
    variance ``(1 + lambda) - a^T B^{-1} a`` with ``a = lambda 1``, ``B = I + lambda 1 1^T``; the
    column covariance is ``(L L^T)^{-1}``.
    """
    D = x.size
    m = len(others)
    if m:
        B = _row_covariance(m, lam)
        a = np.full(m, lam)
        coef = np.linalg.solve(B, a)
        mean = mu + coef @ (others - mu)
        var = 1.0 + lam - a @ coef
    else:
        mean, var = mu, 1.0 + lam
    y = L.T @ (x - mean)
    return float(
        _chol_logdet(L) / 2 - 0.5 * D * math.log(2 * math.pi) - 0.5 * D * math.log(var) - 0.5 * (y @ y) / var
    )
