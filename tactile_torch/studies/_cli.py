"""Command-line checks shared by the study programs (``python -m tactile_torch.studies.<name>``)."""

from __future__ import annotations

import argparse
from collections.abc import Iterable


def refuse_unknown(
    parser: argparse.ArgumentParser, option: str, given: Iterable[str] | None, known: Iterable[str]
) -> None:
    """Exit through ``parser.error`` (one line, status 2) when ``given`` holds a name not in ``known``."""
    known = list(known)
    unknown = [name for name in given or () if name not in known]
    if unknown:
        parser.error(
            f"{option}: unknown {', '.join(map(repr, unknown))}; expected some of {', '.join(known)}"
        )
