"""The one builder of the report's "reproduce with" lines: every option the run actually used."""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from pathlib import Path


def report_command(
    *,
    out_dir: str | Path,
    random_state: int,
    quick: bool = False,
    full: bool = False,
    only: Sequence[str] | None = None,
) -> str:
    """Return the ``tactile-torch report`` command line that reruns a report with these options.

    Every option is written, defaults included (``--seed 0``, ``--out``), so that the line does not
    depend on the defaults of a later version; ``--quick`` and ``--full`` appear when set (both if both
    were). Arguments are shell-quoted.

    Parameters
    ----------
    out_dir : str or Path
        The output directory (``--out``).
    random_state : int
        The root seed (``--seed``).
    quick, full : bool
        The size of the run (``--quick``, ``--full``).
    only : sequence of str, optional
        The studies to run (``--only``, comma-separated); None or empty: every study.

    Examples
    --------
    >>> report_command(out_dir="runs/latest", random_state=3, full=True, only=["claims"])
    'tactile-torch report --only claims --seed 3 --out runs/latest --full'
    """
    words = ["tactile-torch", "report"]
    if only:
        words += ["--only", ",".join(only)]
    words += ["--seed", str(int(random_state)), "--out", str(out_dir)]
    words += ["--quick"] * bool(quick) + ["--full"] * bool(full)
    return shlex.join(words)
