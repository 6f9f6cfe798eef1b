"""Compiled (numba) kernels of the Pitman-Yor Gaussian-mixture Gibbs sampler of :mod:`tactile_torch.mixture`.

Everything here works on *whitened* data (see :class:`tactile_torch.mixture.PitmanYorGMM`), in
float64, and trusts its caller. The model and every parameterisation are documented in
``PitmanYorGMM``; these modules only say how the numbers are laid out. One module per section:

==================  ===========================================================================
``linalg``          small dense linear algebra on D x D matrices; the numba types
``densities``       log densities and draws (Wishart, normal, EPPF, hyperpriors)
``conditionals``    one component's (S, mu) given its points; the base measure
``state``           :class:`ChainState` (the whole chain in one structure), slot bookkeeping, log joint
``allocation``      Neal's (2000) algorithm 8 and the component updates
``hyper``           hyperparameter updates (Gibbs, slice sampling)
``split_merge``     Jain & Neal's (2007) split-merge moves
``chain``           :class:`Settings` and :func:`run_sweeps`, the driver (releases the GIL)
==================  ===========================================================================

The per-point update costs O((K + m) D^2): component likelihoods come from the cached factors
(one triangular mat-vec each), and the weights ``log(n_j - d)`` and ``log|S_j|/2`` are cached per
component and refreshed only when a count or a parameter changes. The random numbers come from the
``numpy.random.Generator`` passed in (numba draws from its bit generator), so a seeded run is
reproducible and shares no global state; chains with their own generators run in parallel threads.
"""

from __future__ import annotations

from .chain import SETTINGS, TRACE_NAMES, Settings, init_components, run_sweeps
from .split_merge import MERGE_ACCEPTED, MERGE_PROPOSED, SPLIT_ACCEPTED, SPLIT_PROPOSED
from .state import STATE, ChainState, copy_state, log_joint, new_state

__all__ = [
    "MERGE_ACCEPTED",
    "MERGE_PROPOSED",
    "SETTINGS",
    "SPLIT_ACCEPTED",
    "SPLIT_PROPOSED",
    "STATE",
    "TRACE_NAMES",
    "ChainState",
    "Settings",
    "copy_state",
    "init_components",
    "log_joint",
    "new_state",
    "run_sweeps",
]
