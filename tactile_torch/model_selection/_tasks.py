"""Where the engine's tasks run: in this process, on joblib's workers, or on a Dask cluster."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

BACKENDS = ("sequential", "loky", "threading", "multiprocessing", "dask")
"""Names :class:`Backend` takes (joblib's, plus ``"sequential"``: a plain loop in this process)."""
DASK_EXTRA = "pip install 'tactile-torch[dask]'"


class Backend:
    """Runs lists of independent tasks through ``joblib.Parallel``; a context manager.

    Every task is a pure function of its arguments (its seed included), so the results do not depend on
    the backend, on ``n_jobs`` or on the order in which workers finish; they are returned in task order.

    Parameters
    ----------
    name : str or None
        One of :data:`BACKENDS`. ``None``: ``"sequential"`` when ``n_jobs`` is ``None`` or 1, else
        ``"loky"`` (worker processes).
    n_jobs : int or None
        Workers (joblib's meaning: -1 every core); ``None``: 1 for ``"sequential"``, every core (or every
        worker of the cluster) otherwise.
    scheduler : str or None
        ``"dask"`` only: the address of a running ``dask.distributed`` scheduler
        (``"tcp://host:8786"``); ``None`` starts a local cluster of worker processes for the run.

    Raises
    ------
    ValueError
        For an unknown backend, ``n_jobs`` of 0, a ``scheduler`` without ``"dask"``, or ``"dask"``
        without the optional ``dask`` extra (one line naming it).
    """

    def __init__(self, name: str | None = None, n_jobs: int | None = None, scheduler: str | None = None):
        if n_jobs is not None and (isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0):
            raise ValueError(f"n_jobs must be a non-zero integer (-1: every core) or None, got {n_jobs!r}")
        if name is None:
            name = "sequential" if n_jobs in (None, 1) else "loky"
        if name not in BACKENDS:
            raise ValueError(f"backend must be one of {list(BACKENDS)}, got {name!r}")
        if scheduler is not None and name != "dask":
            raise ValueError(
                f"scheduler is the address of a Dask scheduler: it needs backend='dask', got {name!r}"
            )
        if name == "dask":
            try:
                import distributed  # noqa: F401
            except ImportError:
                raise ValueError(
                    f"backend 'dask' needs the optional extra dask (dask.distributed), not installed here: {DASK_EXTRA}"
                ) from None
        self.name, self.n_jobs, self.scheduler = name, n_jobs, scheduler
        self._client = None
        self._depth = 0

    @property
    def parallel(self) -> bool:
        """Whether tasks run outside this process's main thread (then each task's own threads are 1)."""
        return self.name != "sequential"

    def __enter__(self) -> Backend:
        if self.name == "dask" and self._depth == 0:
            from distributed import Client

            self._client = Client(self.scheduler) if self.scheduler else Client(processes=True)
        self._depth += 1
        return self

    def __exit__(self, *exc: object) -> None:
        self._depth -= 1
        if self._depth == 0 and self._client is not None:
            self._client.close()
            self._client = None

    def map(
        self, fn: Callable[..., Any], tasks: Sequence[tuple], *, desc: str = "", progress: bool = False
    ) -> list:
        """Return ``[fn(*task) for task in tasks]``, run on the backend, with a progress bar."""
        from tqdm.auto import tqdm

        bar = tqdm(
            total=len(tasks), desc=desc, disable=not progress or not tasks, leave=False, dynamic_ncols=True
        )
        try:
            if self.name == "sequential" or len(tasks) <= 1:
                out = []
                for task in tasks:
                    out.append(fn(*task))
                    bar.update()
                return out
            import joblib

            with self:
                n_jobs = self.n_jobs if self.n_jobs is not None else -1
                with joblib.parallel_config(backend=self.name, n_jobs=n_jobs):
                    run = joblib.Parallel(return_as="generator")
                    out = []
                    for result in run(joblib.delayed(fn)(*task) for task in tasks):
                        out.append(result)
                        bar.update()
                    return out
        finally:
            bar.close()


def as_backend(
    backend: Backend | str | None, n_jobs: int | None = None, scheduler: str | None = None
) -> Backend:
    """Return ``backend`` if it is a :class:`Backend`, else a new one from the three settings."""
    if isinstance(backend, Backend):
        return backend
    return Backend(backend, n_jobs, scheduler)


def progress_bar(items, desc: str, enabled: bool):
    """Return ``items`` wrapped in a tqdm progress bar named ``desc`` (``items`` itself when not ``enabled``).

    The one progress bar of the evaluation stages (folds, exports, int8, memory): it disappears when
    done (``leave=False``) and follows the terminal's width.
    """
    if not enabled:
        return items
    from tqdm.auto import tqdm

    return tqdm(items, desc=desc, leave=False, dynamic_ncols=True)
