"""The experiments behind ``make run``: each module adds one section to the report.

A study module exposes ``TITLE`` and ``run(section, ctx)``; :data:`STUDIES` lists them in report
order. :func:`run_report` generates the bundled (seeded, synthetic) data, runs every study and
writes ``report.md`` with its tables and charts. Studies share generated data through
:attr:`RunContext.cache` so that nothing is generated twice.
"""

from __future__ import annotations

import importlib
import numbers
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._exports import lazy_exports
from ._reproduce import report_command
from ._seeds import study_seed
from .report import Report

# Report order. Each entry is a module of this package with TITLE and run(section, ctx).
STUDIES: list[str] = [
    "environment",
    "image_features",  # method 1: tactile-image pipeline (tactile_torch.image)
    "image_classification",  # method 1: HM-SVM vs LDA/kNN, fusion ablation, noise (tactile_torch.svm)
    "vibration_features",  # method 2: windows and 21 features (tactile_torch.signal)
    "vibration_classification",  # method 2: RBF SVM, feature ranking (tactile_torch.svm)
    "clustering",  # method 2: Pitman-Yor mixture (tactile_torch.mixture)
    "tradeoff",  # speed against accuracy, the simplest adequate model (tactile_torch.tradeoff)
    "learned_models",  # neural, learned front end and int8 against the classical models (tactile_torch.neural)
    "breaking_points",  # both methods: where each model breaks (tactile_torch.robustness)
    "claims",  # both methods: do the conclusions hold on other generators and real data?
]


@dataclass
class RunContext:
    """What every study gets: the seed, the size of the run and a cache of shared intermediate data."""

    random_state: int = 0
    quick: bool = False
    full: bool = False  # --full: the study-size experiments that do not fit make run's time budget
    out_dir: Path = Path("runs/latest")
    cache: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.quick and self.full:
            raise ValueError(
                "quick and full are exclusive (quick shrinks the run, full enlarges it): pass one"
            )

    @property
    def mode(self) -> str:
        """``"quick"``, ``"full"`` or ``"default"``: the size of this run, as the studies' records name it."""
        return "quick" if self.quick else "full" if self.full else "default"

    def cached(self, key: str, make: Callable[[], Any]) -> Any:
        """Return ``cache[key]``, computing it with ``make()`` the first time."""
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]

    def seed(self, study: str, purpose: str) -> int:
        """Return the seed of the draw ``purpose`` of ``study`` under this run's seed (:func:`._seeds.study_seed`)."""
        return study_seed(self.random_state, study, purpose)

    def command(self, *only: str) -> str:
        """Return the command that reruns the studies ``only`` with this run's options (:func:`._reproduce.report_command`)."""
        return report_command(
            out_dir=self.out_dir, random_state=self.random_state, quick=self.quick, full=self.full, only=only
        )


def run_report(
    out_dir: str | Path,
    *,
    random_state: int = 0,
    quick: bool = False,
    full: bool = False,
    only: list[str] | None = None,
    log: Callable[[str], None] = print,
) -> Path:
    """Run the studies (all, or those named in ``only``) and write the report; return its path.

    ``random_state`` is the root seed (``--seed``, a non-negative int): every random draw of every study
    takes its own seed from it through :meth:`RunContext.seed`, so one root seed gives one report.
    """
    if isinstance(random_state, bool) or not isinstance(random_state, numbers.Integral) or random_state < 0:
        raise ValueError(f"random_state must be a non-negative int, got {random_state!r}")
    unknown = sorted(set(only or []) - set(STUDIES))
    if unknown:
        raise ValueError(f"only must name studies among {STUDIES}, got unknown {unknown}")
    out_dir = Path(out_dir)
    ctx = RunContext(random_state=int(random_state), quick=quick, full=full, out_dir=out_dir)
    report = Report(out_dir)
    cmd = ctx.command(*(only or ()))
    report.preamble.append(f"Written by `{cmd}` (`make run` runs it with the defaults).")
    for name in STUDIES:
        if only and name not in only:
            continue
        module = importlib.import_module(f"{__name__}.{name}")
        section = report.section(module.TITLE)
        start = time.perf_counter()
        log(f"[report] {module.TITLE} ...")
        module.run(section, ctx)
        seconds = time.perf_counter() - start
        section.text(f"_Section computed in {seconds:.1f} s._")
        log(f"[report] {module.TITLE}: {seconds:.1f} s")
    return report.write()


__getattr__, __dir__, __all__ = lazy_exports(__name__, {}, defined=("STUDIES", "RunContext", "run_report"))
