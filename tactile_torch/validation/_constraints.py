"""Hyper-parameter constraints that several estimators share, in scikit-learn's ``_parameter_constraints`` form.

Torch-free (a torch generator is recognised by its methods), so that the estimators that do not import
torch (:class:`~tactile_torch.mixture.PitmanYorGMM`) use the same entries as those that do.
"""

from __future__ import annotations

import numpy as np
from sklearn.utils._param_validation import HasMethods

RANDOM_STATE: list = ["random_state", np.random.Generator, HasMethods(["manual_seed", "initial_seed"])]
"""The ``random_state`` entry of every estimator: scikit-learn's ``"random_state"`` (``None``, an int
seed in ``[0, 2**32 - 1]`` or a ``numpy.random.RandomState``), a ``numpy.random.Generator``, or a
``torch.Generator``. :func:`tactile_torch.validation.numpy_rng` turns any of them into a NumPy generator."""
