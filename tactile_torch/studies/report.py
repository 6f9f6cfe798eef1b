"""Markdown reports with tables and PNG charts, as written by ``make run`` (``tactile-torch report``).

A :class:`Report` is a list of sections; each section holds paragraphs, tables and figures in order.
``write()`` renders ``report.md`` (figures under ``figures/``) and ``report.json`` (every table as
data, so that numbers can be compared between runs).

Examples
--------
>>> rep = Report("runs/example")                       # doctest: +SKIP
>>> sec = rep.section("Vibration features")            # doctest: +SKIP
>>> sec.table([{"surface": "cork", "accuracy": 0.98}])  # doctest: +SKIP
>>> rep.write()                                        # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib

from ..robot.files.naming import slug

matplotlib.use("Agg")  # reports are written on headless machines
import matplotlib.pyplot as plt


def _slug(text: str) -> str:
    return slug(text) or "figure"  # the file and anchor of a figure or section; never empty


def _cell(value: Any, floatfmt: str) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else format(value, floatfmt)
    return str(value).replace("|", "\\|")


@dataclass
class Section:
    """One titled part of a report; add content in reading order."""

    title: str
    report: Report
    blocks: list[str] = field(default_factory=list)
    tables: list[dict[str, Any]] = field(default_factory=list)

    def text(self, markdown: str) -> None:
        """Append a paragraph of markdown."""
        self.blocks.append(markdown.strip())

    def command(self, cmd: str) -> None:
        """Append the command that reproduces what follows."""
        self.blocks.append(f"Reproduce with:\n\n```\n{cmd}\n```")

    def table(
        self,
        rows: list[dict[str, Any]],
        *,
        caption: str | None = None,
        columns: list[str] | None = None,
        floatfmt: str = ".4g",
    ) -> None:
        """Append a table given as a list of dicts (one per row; keys are column names)."""
        if not rows:
            raise ValueError("rows must hold at least one row, got an empty list")
        columns = columns or list(dict.fromkeys(k for row in rows for k in row))
        lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        lines += ["| " + " | ".join(_cell(row.get(c, ""), floatfmt) for c in columns) + " |" for row in rows]
        if caption:
            lines.insert(0, f"*{caption}*\n")
        self.blocks.append("\n".join(lines))
        self.tables.append({"caption": caption, "columns": columns, "rows": rows})

    def figure(self, fig: plt.Figure, name: str, caption: str) -> Path:
        """Save ``fig`` as ``figures/<name>.png``, close it and reference it in the report."""
        path = self.report.figure_dir / f"{_slug(name)}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        rel = path.relative_to(self.report.out_dir).as_posix()
        self.blocks.append(f"![{caption}]({rel})\n\n*{caption}*")
        return path


class Report:
    """A markdown report with tables and figures written under ``out_dir``."""

    def __init__(self, out_dir: str | Path, title: str = "tactile-torch report") -> None:
        self.out_dir = Path(out_dir)
        self.figure_dir = self.out_dir / "figures"
        self.title = title
        self.preamble: list[str] = []
        self.sections: list[Section] = []

    def section(self, title: str) -> Section:
        """Start and return a new section."""
        sec = Section(title, self)
        self.sections.append(sec)
        return sec

    def write(self) -> Path:
        """Write ``report.md`` and ``report.json``; return the path of ``report.md``."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        parts = [f"# {self.title}", *self.preamble]
        parts += ["## Contents", "\n".join(f"- [{s.title}](#{_slug(s.title)})" for s in self.sections)]
        for sec in self.sections:
            parts.append(f"## {sec.title}")
            parts.extend(sec.blocks)
        md = self.out_dir / "report.md"
        md.write_text("\n\n".join(parts) + "\n")
        data = {
            "title": self.title,
            "sections": [{"title": s.title, "tables": s.tables} for s in self.sections],
        }
        (self.out_dir / "report.json").write_text(json.dumps(data, indent=1, default=_json_default) + "\n")
        return md


def _json_default(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)
