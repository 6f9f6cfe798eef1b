"""The trade-off study as one job, what ``tactile-torch tradeoff`` runs: its options with their defaults,
and the run that writes every output into a directory at once.

:class:`TradeoffOptions` holds the choices a user makes about a study (the command's options, the
keywords of :func:`~tactile_torch.tradeoff.run_tradeoff`), with their defaults and their checks, so
that the command line and the library read one set of defaults. :func:`run_tradeoff_job` runs the
study (:func:`~tactile_torch.tradeoff.run_tradeoff`), the breaking points of the recommended model
(:func:`~tactile_torch.tradeoff.breaking.add_breaking_points`) and writes the outputs
(:func:`~tactile_torch.tradeoff.write_outputs`) into a staging directory that replaces ``out_dir``
only when everything succeeded.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

DEFAULT_FOLDS = 5
"""Folds when ``n_folds`` is not given (fewer when the data allow fewer)."""


@dataclass(frozen=True)
class TradeoffOptions:
    """The options of a trade-off study, with their defaults (checked when made).

    Attributes
    ----------
    quick : bool
        Fewer candidates and at most 60 samples per class.
    n_folds : int or None
        Cross-validation folds, >= 2; ``None``: :data:`DEFAULT_FOLDS`, or fewer when the data allow
        fewer (a number given is kept or refused, never lowered).
    window : int or None
        Vibration: the reference window in samples (default: 800).
    windows : tuple of int or None
        Vibration: the window sizes to try (default: 200, 400, 800, 1600).
    frame_rate_hz : float or None
        Explorations: frames per second, > 0 (default: the file's, or 10).
    threshold : float or {"auto", "otsu", "display"}
    erosion : int or "relative"
    contact : {"raises", "lowers", "auto"}
        Pressure maps: does contact raise or lower the reading.
    max_per_class : int or "auto"
        Samples kept per class, >= 2 (``"auto"``: 60 with ``quick``, else 300).
    classifiers, features : tuple of str or None
        Subsets of the classifiers and feature-set name prefixes (default: all).
    target : float or None
        The accuracy a deployment needs, in (0, 1] (default: the one-standard-error rule).
    deploy : str or None
        A candidate to refit on all the data and write besides the recommended one.
    random_state : int
    tune : bool
        Tune each candidate inside each training fold (else the catalogue's defaults).
    breaking : bool
        Also sweep the breaking points of the recommended and the study's model.
    exhaustive : bool
        Evaluate every candidate on every fold (default: candidates that cannot be recommended stop
        early, :mod:`tactile_torch.tradeoff.stopping`), and sweep the breaking points at every level with
        5 folds (default: the quick levels with 2 folds, as ``quick``).
    """

    quick: bool = False
    n_folds: int | None = None
    window: int | None = None
    windows: tuple[int, ...] | None = None
    frame_rate_hz: float | None = None
    threshold: float | str = "auto"
    erosion: int | str = "relative"
    contact: str = "raises"
    max_per_class: int | str = "auto"
    classifiers: tuple[str, ...] | None = None
    features: tuple[str, ...] | None = None
    target: float | None = None
    deploy: str | None = None
    random_state: int = 0
    tune: bool = True
    breaking: bool = True
    exhaustive: bool = False

    def __post_init__(self) -> None:
        if self.n_folds is not None and (
            isinstance(self.n_folds, bool) or not isinstance(self.n_folds, int) or self.n_folds < 2
        ):
            raise ValueError(f"n_folds must be a whole number >= 2, got {self.n_folds}")
        if self.max_per_class != "auto" and (
            isinstance(self.max_per_class, bool)
            or not isinstance(self.max_per_class, int)
            or self.max_per_class < 2
        ):
            raise ValueError(
                f"max_per_class must be 'auto' or a whole number >= 2, got {self.max_per_class!r}"
            )
        if self.frame_rate_hz is not None and not (
            math.isfinite(self.frame_rate_hz) and self.frame_rate_hz > 0
        ):
            raise ValueError(f"frame_rate_hz must be a number of frames/s > 0, got {self.frame_rate_hz:g}")
        if self.target is not None and not (math.isfinite(self.target) and 0 < self.target <= 1):
            raise ValueError(f"target must be an accuracy in (0, 1], got {self.target:g}")

    def changed(self) -> list[str]:
        """Return the names of the options not at their defaults, in declaration order."""
        default = TradeoffOptions()
        return [f.name for f in dataclasses.fields(self) if getattr(self, f.name) != getattr(default, f.name)]

    def run_keywords(self) -> dict:
        """Return the keywords of :func:`~tactile_torch.tradeoff.run_tradeoff` these options give."""
        return {
            "quick": self.quick,
            "n_folds": DEFAULT_FOLDS if self.n_folds is None else self.n_folds,
            "exact_folds": self.n_folds is not None,
            "window": self.window,
            "windows": None if self.windows is None else list(self.windows),
            "frame_rate_hz": self.frame_rate_hz,
            "threshold": self.threshold,
            "erosion": self.erosion,
            "contact": self.contact,
            "max_per_class": self.max_per_class,
            "classifiers": None if self.classifiers is None else list(self.classifiers),
            "features": None if self.features is None else list(self.features),
            "target": self.target,
            "deploy": ["recommended", *([self.deploy] if self.deploy else [])],
            "random_state": self.random_state,
            "tune": self.tune,
            "exhaustive": self.exhaustive,
            "estimate_breaking": self.breaking,
        }


def run_tradeoff_job(
    data,
    options: TradeoffOptions,
    out_dir: str | Path,
    *,
    command: str = "",
    allow_pickle: bool = False,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    log: Callable[[str], None] = print,
):
    """Run the study and write its outputs into ``out_dir``; return the result and the paths written.

    Parameters
    ----------
    data : path(s) or TradeoffData
        See :func:`~tactile_torch.tradeoff.load_tradeoff_data`.
    options : TradeoffOptions
    out_dir : path
        Replaced as a whole when the candidates were measured (:func:`~tactile_torch.tradeoff.output.staged_output`):
        a run that fails before (or is killed) leaves the previous ``out_dir`` as it was. A late stage
        that fails (deployment, breaking points, a chart: a bug) does not discard the others' outputs:
        they are written, and ``result.incomplete`` (``tradeoff.json``'s ``incomplete``) names it.
    command : str
        The command line that reproduces the run, written into the outputs.
    allow_pickle, backend, n_jobs, scheduler, progress, log
        As in :func:`~tactile_torch.tradeoff.run_tradeoff`.

    Returns
    -------
    result : TradeoffResult
    paths : dict of str to Path
        What :func:`~tactile_torch.tradeoff.write_outputs` wrote, by role, at their final place in
        ``out_dir``.
    """
    from . import run_tradeoff, write_outputs  # the package's names: what callers (and tests) replace
    from .breaking import add_breaking_points
    from .output import staged_output

    with staged_output(out_dir) as staging:
        result = run_tradeoff(
            data,
            out_dir=staging,
            allow_pickle=allow_pickle,
            backend=backend,
            n_jobs=n_jobs,
            scheduler=scheduler,
            progress=progress,
            log=log,
            **options.run_keywords(),
        )
        if options.breaking and result.recommended is not None:  # docs/robustness.md
            log("[tradeoff] breaking points of the recommended and the study's model")
            try:
                # the full sweeps (every level, 5 folds, 10 draws per SNR) retrain a network hundreds of
                # times: they run with --exhaustive; by default the quick levels (docs/tradeoff.md)
                add_breaking_points(
                    result,
                    staging,
                    quick=options.quick or not options.exhaustive,
                    random_state=options.random_state,
                    progress=progress,
                )
            except Exception as err:  # a late stage: what the earlier ones computed is written all the same
                result.mark_incomplete("breaking points", err)
        paths = write_outputs(result, staging, command=command)
    out = Path(out_dir)
    return result, {role: out / p.relative_to(staging) for role, p in paths.items()}
