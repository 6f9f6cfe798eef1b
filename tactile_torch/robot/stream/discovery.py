"""New surfaces in a stream: turn per-window novelty flags into proposals of new surfaces (numpy only).

The study's motivation for a nonparametric mixture is that the number of surfaces "may increase over
time". An exported Pitman-Yor mixture (``tactile-torch cluster`` then ``export``) flags every window
that a *new* component explains better than every known one (output ``novel``, see
:class:`tactile_torch.mixture.GaussianMixtureClassifier`). One novel window is weak evidence (a
bump, a slip); :class:`SurfaceDiscovery` proposes a new surface only after ``n_consecutive`` novel
windows in a row, and keeps classifying: the windows of the run are named after the proposed
surface, the others after their known component. Runs separated by a known window count as
separate proposals. With the bundle's per-window novelty scores (output ``novelty``, minus the log
density under the mixture) and the thresholds it carries (metadata ``novelty_thresholds``, calibrated on windows
of known surfaces by :meth:`~tactile_torch.mixture.PitmanYorGMM.calibrate_novelty`), a window is
novel when the mean score of the last ``n_consecutive`` windows exceeds the threshold of that N:
the decision :meth:`~tactile_torch.mixture.PitmanYorGMM.novel_after` makes. Importing this module
never imports torch (it runs on the robot).

Examples
--------
>>> d = SurfaceDiscovery(n_consecutive=3, known_names=["glass", "cork"])
>>> [d.update(label, novel).name for label, novel in [(0, False), (1, True), (1, True), (1, True), (0, False)]]
['glass', 'cork', 'cork', 'new surface 1', 'glass']
>>> d.proposals
[{'name': 'new surface 1', 'first_window': 1, 'windows': 3}]
"""

from __future__ import annotations

import json
import math
import sys
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TextIO

from ...validation import check_count
from ..contract import NOVEL_OUTPUT, NOVELTY_SCORE_OUTPUT, NOVELTY_THRESHOLDS_KEY, UNKNOWN


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
    thresholds : sequence of float, optional
        Thresholds of the mean novelty score over N = 1, 2, ... windows. When given, :meth:`update`
        takes each window's score and a window is novel when the mean score of the last
        ``n_consecutive`` windows exceeds ``thresholds[n_consecutive - 1]`` (the last threshold
        beyond the list); a proposal is made on the first such window of a run.

    Attributes
    ----------
    proposals : list of dict
        One per proposed surface: ``name``, ``first_window`` (index of the run's first window),
        ``windows`` (its length so far).
    windows : int
        Windows seen.
    """

    def __init__(
        self,
        n_consecutive: int = 5,
        known_names: Sequence[str] | None = None,
        thresholds: Sequence[float] | None = None,
    ) -> None:
        self.n_consecutive = check_count(n_consecutive, "n_consecutive", 1)
        self.known_names = list(known_names) if known_names is not None else None
        self.threshold = None
        if thresholds is not None:
            values = [float(t) for t in thresholds]
            if not values or not all(math.isfinite(t) for t in values):
                raise ValueError(
                    f"thresholds must be a non-empty list of finite numbers, got {thresholds!r:.80}"
                )
            self.threshold = values[min(n_consecutive, len(values)) - 1]
        self._scores: deque[float] = deque(maxlen=n_consecutive)
        self.proposals: list[dict] = []
        self.windows = 0
        self._run = 0

    def _known(self, label: int) -> str:
        if self.known_names is not None and 0 <= label < len(self.known_names):
            return str(self.known_names[label])
        return f"component {label}"

    def update(self, label: int, novel: bool, score: float | None = None) -> WindowVerdict:
        """Take the next window's most likely known component, novelty flag and score; return its verdict.

        ``score`` (the window's novelty score) is required when ``thresholds`` were given; the flag
        is then not used.
        """
        if self.threshold is not None:
            if score is None:
                raise ValueError("SurfaceDiscovery with thresholds needs each window's novelty score")
            self._scores.append(float(score))
            full = len(self._scores) == self.n_consecutive
            novel = full and sum(self._scores) / self.n_consecutive > self.threshold
            return self._verdict(label, novel, 1, self.n_consecutive)
        return self._verdict(label, novel, self.n_consecutive, 1)

    def _verdict(self, label: int, novel: bool, needed: int, span: int) -> WindowVerdict:
        """Verdict of a window given its decision; a proposal after ``needed`` novel decisions in a row, covering ``span`` windows before the run."""
        index = self.windows
        self.windows += 1
        if not novel:
            self._run = 0
            return WindowVerdict(self._known(int(label)), False, False, 0)
        self._run += 1
        proposed = self._run == needed
        if proposed:
            self.proposals.append(
                {
                    "name": f"new surface {len(self.proposals) + 1}",
                    "first_window": index - self._run - span + 2,
                    "windows": 0,
                }
            )
        if self._run >= needed:
            self.proposals[-1]["windows"] = self._run + span - 1
            return WindowVerdict(self.proposals[-1]["name"], True, proposed, self._run + span - 1)
        return WindowVerdict(self._known(int(label)), True, False, self._run)


def stream_consumer(pipeline, n_consecutive: int, out: TextIO = sys.stdout) -> Callable[[object], None]:
    """Return a consumer of ``tactile-torch stream``'s window results that proposes new surfaces.

    ``pipeline`` is the :class:`~tactile_torch.robot.runtime.OnnxPipeline` of an exported clustering; each
    result's window is run through it for its ``novel`` output (a second, ~1 ms inference: the
    stream's classifier does not keep that output) and fed to a :class:`SurfaceDiscovery`. Windows
    the stream leaves without a known label are skipped (neither counted nor breaking a run): those
    with non-finite scores (label ``None``) and the unknown ones (label ``-1``: beyond the sensor's
    range, constant on every axis as from a stuck or saturated sensor, or out of distribution), whose
    novelty says nothing about a surface. Novel windows and proposals are printed to ``out``. Raises
    ``ValueError`` when the bundle has no ``novel`` output.
    """
    outputs = [o.name for o in pipeline.session.get_outputs()]
    if NOVEL_OUTPUT not in outputs:
        raise ValueError(
            f"surface discovery (n_consecutive=) needs a clustering bundle with a '{NOVEL_OUTPUT}' output "
            "(tactile-torch cluster, then "
            f"export), got outputs {outputs}"
        )
    scored = NOVELTY_SCORE_OUTPUT in outputs and NOVELTY_THRESHOLDS_KEY in pipeline.metadata
    thresholds = json.loads(pipeline.metadata[NOVELTY_THRESHOLDS_KEY]) if scored else None
    discovery = SurfaceDiscovery(n_consecutive, pipeline.class_names, thresholds)

    def consume(result) -> None:
        if result.label is None or result.label == UNKNOWN:  # not a surface's window: nothing to say
            return
        outputs = pipeline.run(result.window.data)
        score = float(outputs[NOVELTY_SCORE_OUTPUT][0]) if scored else None
        verdict = discovery.update(result.label, bool(outputs[NOVEL_OUTPUT][0]), score)
        if verdict.proposed:
            print(
                f"new surface proposed: {verdict.name} (over the last {verdict.run} windows)",
                file=out,
                flush=True,
            )
        if verdict.novel:
            print(f"  novel window -> {verdict.name}", file=out, flush=True)

    return consume


__all__ = ["SurfaceDiscovery", "WindowVerdict", "stream_consumer"]
