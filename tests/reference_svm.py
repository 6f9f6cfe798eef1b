"""Reference for the SVM tests and benchmark: scikit-learn's ``SVC`` (libsvm) and NumPy/SciPy helpers
that compare a torch solution with it.

The helpers read only public attributes (``support_``, ``dual_coef_``, ``intercept_``) of both models
and recompute the kernel with SciPy, so a comparison never goes through the code it checks.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist
from sklearn.svm import SVC as LibSVC


def kernel(a: np.ndarray, b: np.ndarray, kind: str, gamma: float) -> np.ndarray:
    """Kernel matrix with SciPy: ``exp(-gamma * sqeuclidean)`` or the dot product."""
    if kind == "linear":
        return a @ b.T
    return np.exp(-gamma * cdist(a, b, "sqeuclidean"))


def dual_objective(
    X: np.ndarray, support: np.ndarray, dual_coef: np.ndarray, kind: str, gamma: float
) -> float:
    """libsvm's dual objective ``1/2 v^T K v - sum |v|`` from a binary model's support and ``y_i a_i``."""
    v = np.asarray(dual_coef, dtype=np.float64).ravel()
    sv = X[support]
    return float(0.5 * v @ kernel(sv, sv, kind, gamma) @ v - np.abs(v).sum())


def libsvm(
    X: np.ndarray,
    y: np.ndarray,
    *,
    C: float,
    kind: str,
    gamma: float,
    tol: float = 1e-3,
    cache_size: float = 200,
):
    """Fit scikit-learn's ``SVC`` (libsvm) with the given hyper-parameters."""
    return LibSVC(C=C, kernel=kind, gamma=gamma, tol=tol, cache_size=cache_size).fit(X, y)


def compare_binary(
    ours, ref, X_train: np.ndarray, X_test: np.ndarray, *, kind: str, gamma: float, tie: float = 1e-2
) -> dict:
    """Compare two fitted binary SVMs (ours and libsvm's) trained on ``X_train``.

    Returns the relative difference of the dual objectives, the share of ``X_test`` on which the
    predicted sides agree, the largest decision-value difference, and the support sets' symmetric
    difference, split into ties (samples whose margin ``|y f(x)| `` is within ``tie`` of 1 by
    libsvm's own decision function, where an approximate solver may legitimately include or leave
    them) and the rest.
    """
    obj_ours = dual_objective(X_train, ours.support_, ours.dual_coef_, kind, gamma)
    obj_ref = dual_objective(X_train, ref.support_, ref.dual_coef_, kind, gamma)
    d_ours = ours.decision_function(X_test)
    d_ref = ref.decision_function(X_test)
    sym = np.setxor1d(ours.support_, ref.support_)
    f_ref = np.abs(ref.decision_function(X_train[sym])) if sym.size else np.zeros(0)
    ties = int((np.abs(f_ref - 1.0) <= tie).sum())
    return {
        "objective_rel": abs(obj_ours - obj_ref) / max(abs(obj_ref), 1e-300),
        "agreement": float(np.mean((d_ours > 0) == (d_ref > 0))),
        "decision_max_diff": float(np.abs(d_ours - d_ref).max()),
        "n_sv_ours": int(ours.support_.size),
        "n_sv_ref": int(ref.support_.size),
        "support_ties": ties,
        "support_other": int(sym.size - ties),
    }
