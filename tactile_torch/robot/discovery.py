"""New surfaces in a stream: turn per-window novelty flags into proposals of new surfaces (numpy only).

The study's motivation for a nonparametric mixture is that the number of surfaces "may increase over
time". An exported Pitman-Yor mixture (``tactile-torch cluster`` then ``export``) flags every window
that a *new* component explains better than every known one (output ``novel``, see
:class:`tactile_torch.mixture.GaussianMixtureClassifier`). One novel window is weak evidence (a
bump, a slip); :class:`SurfaceDiscovery` proposes a new surface only after ``n_consecutive`` novel
windows in a row, and keeps classifying: the windows of the run are named after the proposed
surface, the others after their known component. Runs separated by a known window count as
separate proposals. Importing this module never imports torch (it runs on the robot).

Examples
--------
>>> d = SurfaceDiscovery(n_consecutive=3, known_names=["glass", "cork"])
>>> [d.update(label, novel).name for label, novel in [(0, False), (1, True), (1, True), (1, True), (0, False)]]
['glass', 'cork', 'cork', 'new surface 1', 'glass']
>>> d.proposals
[{'name': 'new surface 1', 'first_window': 1, 'windows': 3}]
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TextIO

from .checks import check_count
from .contract import NOVEL_OUTPUT


@dataclass(frozen=True)
class WindowVerdict:
    """What :meth:`SurfaceDiscovery.update` says about one window.

    Attributes
    ----------
    name : str
        The known component's name, or the proposed new surface's name once a run is long enough
        (until then a novel window keeps its most likely known component's name).
    novel : bool
        The window's novelty flag.
    proposed : bool
        True on the window that completes a run of ``n_consecutive`` novel windows (a new proposal).
    run : int
        Length of the current run of novel windows (0 for a known window).
    """

    name: str
    novel: bool
    proposed: bool
    run: int


class SurfaceDiscovery:
    """Propose a new surface after ``n_consecutive`` novel windows in a row; name every window.

    Parameters
    ----------
    n_consecutive : int, default 5
        Novel windows in a row needed to propose a new surface (>= 1).
    known_names : sequence of str, optional
        Names of the known components (index = label); default ``"component <label>"``.

    Attributes
    ----------
    proposals : list of dict
        One per proposed surface: ``name``, ``first_window`` (index of the run's first window),
        ``windows`` (its length so far).
    windows : int
        Windows seen.
    """

    def __init__(self, n_consecutive: int = 5, known_names: Sequence[str] | None = None) -> None:
        self.n_consecutive = check_count(n_consecutive, "n_consecutive", 1)
        self.known_names = list(known_names) if known_names is not None else None
        self.proposals: list[dict] = []
        self.windows = 0
        self._run = 0

    def _known(self, label: int) -> str:
        if self.known_names is not None and 0 <= label < len(self.known_names):
            return str(self.known_names[label])
        return f"component {label}"

    def update(self, label: int, novel: bool) -> WindowVerdict:
        """Take the next window's most likely known component and novelty flag; return its verdict."""
        index = self.windows
        self.windows += 1
        if not novel:
            self._run = 0
            return WindowVerdict(self._known(int(label)), False, False, 0)
        self._run += 1
        proposed = self._run == self.n_consecutive
        if proposed:
            self.proposals.append(
                {
                    "name": f"new surface {len(self.proposals) + 1}",
                    "first_window": index - self._run + 1,
                    "windows": 0,
                }
            )
        if self._run >= self.n_consecutive:
            self.proposals[-1]["windows"] = self._run
            return WindowVerdict(self.proposals[-1]["name"], True, proposed, self._run)
        return WindowVerdict(self._known(int(label)), True, False, self._run)


def stream_consumer(pipeline, n_consecutive: int, out: TextIO = sys.stdout) -> Callable[[object], None]:
    """Return a consumer of ``tactile-torch stream``'s window results that proposes new surfaces.

    ``pipeline`` is the :class:`~tactile_torch.robot.runtime.OnnxPipeline` of an exported clustering; each
    result's window is run through it for its ``novel`` output (a second, ~1 ms inference: the
    stream's classifier does not keep that output) and fed to a :class:`SurfaceDiscovery`. Novel
    windows and proposals are printed to ``out``. Raises ``ValueError`` when the bundle has no
    ``novel`` output.
    """
    outputs = [o.name for o in pipeline.session.get_outputs()]
    if NOVEL_OUTPUT not in outputs:
        raise ValueError(
            f"--discover needs a clustering bundle with a '{NOVEL_OUTPUT}' output (tactile-torch cluster, then "
            f"export), got outputs {outputs}"
        )
    discovery = SurfaceDiscovery(n_consecutive, pipeline.class_names)

    def consume(result) -> None:
        if result.label is None:  # non-finite scores: nothing to say
            return
        novel = bool(pipeline.run(result.window.data)[NOVEL_OUTPUT][0])
        verdict = discovery.update(result.label, novel)
        if verdict.proposed:
            print(
                f"new surface proposed: {verdict.name} ({verdict.run} novel windows in a row)",
                file=out,
                flush=True,
            )
        if verdict.novel:
            print(f"  novel window -> {verdict.name}", file=out, flush=True)

    return consume


__all__ = ["SurfaceDiscovery", "WindowVerdict", "stream_consumer"]
