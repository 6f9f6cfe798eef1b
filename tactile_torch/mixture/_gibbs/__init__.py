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

import hashlib
from pathlib import Path


def _drop_stale_kernels() -> None:
    """Delete numba's cached kernels of this package when any of its sources changed.

    numba keys a cached kernel on its own file only, but the entry kernels of ``chain`` have every
    helper of the sibling modules compiled into them: an edit of ``linalg.py`` alone would leave a
    stale ``run_sweeps`` in the cache. A fingerprint of all the package's sources, kept next to the
    cache, catches that (an upgrade or an edit); the next import recompiles, as ``make install`` does.
    """
    here = Path(__file__).parent
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(here.glob("*.py")))).hexdigest()
    cache = here / "__pycache__"
    stamp = cache / "kernels.sha256"
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        for f in (*cache.glob("*.nbi"), *cache.glob("*.nbc")):
            f.unlink()
        stamp.write_text(digest)
    except OSError:  # a read-only installation: numba then compiles in memory or in NUMBA_CACHE_DIR
        pass


_drop_stale_kernels()

from .chain import SETTINGS, TRACE_NAMES, Settings, init_components, run_sweeps  # noqa: E402
from .split_merge import MERGE_ACCEPTED, MERGE_PROPOSED, SPLIT_ACCEPTED, SPLIT_PROPOSED  # noqa: E402
from .state import STATE, ChainState, copy_state, log_joint, new_state  # noqa: E402

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
