"""The one seed derivation of the report: every random draw of every study takes its seed from here.

``tactile-torch report --seed S`` sets the root seed ``S``; each draw (a generated data set, the
cross-validation folds, an estimator, a noise stream, a network's initialisation) asks for
``study_seed(S, study, purpose)``, named by the study that owns the draw and what it is for. Two draws
with different names get independent seeds (numpy's ``SeedSequence`` over the root and the names,
through the evaluation engine's :func:`~tactile_torch.model_selection.seed_of`), a study's draws do not depend on
which other studies ran before it, and the same root seed gives the same report.
"""

from __future__ import annotations

from ..model_selection import seed_of

SEED_BITS = 31  # every consumer accepts it: numpy, torch, and scikit-learn's RandomState (< 2**32)


def study_seed(root: int, study: str, purpose: str) -> int:
    """Return the seed, an int in ``[0, 2**31)``, of the draw ``purpose`` of ``study`` under root seed ``root``.

    Parameters
    ----------
    root : int
        The report's seed (``--seed``), non-negative.
    study : str
        The study that owns the draw (its module name, e.g. ``"claims"``); data shared between studies is
        named by the study that generates it.
    purpose : str
        What the draw is for (``"hard image set"``, ``"cv folds"``, ...), unique within the study.

    Examples
    --------
    >>> study_seed(0, "claims", "hard image set") == study_seed(0, "claims", "hard image set")
    True
    >>> study_seed(0, "claims", "hard image set") != study_seed(1, "claims", "hard image set")
    True
    """
    return seed_of(root, study, purpose) >> (62 - SEED_BITS)
