"""Per-session standardisation of features: remove what a session (a re-mounted sensor, a new gain) shifts.

A sensor re-mounted between sessions changes the gain of every signal; the log-amplitude features
then move by the same amount for every surface of the session, and a mixture fitted to the pooled
features counts each (surface, session) as its own cluster. When the sessions are known and each
session covers the same mix of surfaces, standardising every feature within each session
(:func:`standardise_per_session`) removes that shift before clustering. It assumes the mix: a
session that holds one surface only is flattened onto the others (its own mean is removed), so do
not apply it to data whose sessions are surfaces (one recording per surface).
"""

from __future__ import annotations

import numpy as np


def standardise_per_session(X: object, sessions: object) -> np.ndarray:
    """Return ``X`` (n, D) with every feature standardised within each session: mean 0, sd 1 per session, shape (n, D).

    Parameters
    ----------
    X : array-like (n, D)
        Features (e.g. the clustering transform's principal components), finite.
    sessions : array-like (n,)
        Session of each row (any hashable labels).

    A feature constant within a session (sd 0) is only centred there. Raises ``ValueError`` when the
    shapes disagree or ``X`` is not finite.

    Examples
    --------
    >>> X = np.array([[1.0], [3.0], [11.0], [13.0]])
    >>> standardise_per_session(X, ["a", "a", "b", "b"]).ravel().tolist()
    [-1.0, 1.0, -1.0, 1.0]
    """
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2:
        raise ValueError(f"X must be a 2-D array (n, D), got shape {X.shape}")
    sessions = np.asarray(sessions).ravel()
    if sessions.shape[0] != X.shape[0]:
        raise ValueError(f"sessions must have one entry per row of X ({X.shape[0]}), got {sessions.shape[0]}")
    if not np.isfinite(X).all():
        raise ValueError("X must be finite (no NaN or inf) to be standardised per session")
    out = np.empty_like(X)
    for s in np.unique(sessions):
        rows = sessions == s
        block = X[rows] - X[rows].mean(axis=0)
        sd = block.std(axis=0)
        out[rows] = block / np.where(sd > 0, sd, 1.0)
    return out


__all__ = ["standardise_per_session"]
