"""Every Python example of README.md and docs/ runs as written.

Each ```python block runs as a script in a fresh namespace (``__name__ == "__main__"``), in an empty temporary
working directory (so a block that reads a file must write it first, or continue a block of the same page that
does), with an empty standard input and matplotlib's file-only backend. The blocks run in this process, one
after the other: importing torch and the compiled kernels once, not once per block, keeps the test fast.

Markers, HTML comments on the lines just above a block (invisible on GitHub), change how it runs:

- ``<!-- example: continue -->``: the block continues the page's previous block, in the same namespace and
  directory (the two are run as one script); the prose should say so too ("continuing the example above").
- ``<!-- example: skip: <reason> -->``: the block is not run, and the test is reported skipped with the
  reason (hardware the test machine has not got, such as a serial sensor).
- ``<!-- example: shorten: <text> => <replacement> -->``: the block runs with ``<text>`` replaced by
  ``<replacement>`` (a long run in a shortened form: fewer sweeps, a shorter recording); the text must occur
  in the block.

A block that is not marked ``continue`` starts a new namespace. Several markers may be stacked.
"""

from __future__ import annotations

import io
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

_MARKER = re.compile(r"^<!--\s*example:\s*(.*?)\s*-->$")


@dataclass
class Example:
    """A runnable unit: one block, or a chain of blocks joined by ``continue`` markers."""

    page: str
    parts: list[tuple[int, str]]  # (first line of the code, 1-based; the code) of each block
    skip: str | None = None

    @property
    def line(self) -> int:
        return self.parts[0][0]

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"

    @property
    def code(self) -> str:
        return "".join(code for _, code in self.parts)

    def script(self) -> str:
        """The blocks at their lines of the page (blank lines between), so that a traceback names them."""
        text = ""
        for line, code in self.parts:
            text += "\n" * (line - 1 - text.count("\n")) + code
        return text


def _markers(lines: list[str], fence: int) -> list[str]:
    """The ``example:`` directives in the HTML comments just above line ``fence`` (0-based)."""
    found = []
    index = fence - 1
    while index >= 0 and not lines[index].strip():
        index -= 1
    while index >= 0:
        match = _MARKER.match(lines[index].strip())
        if match is None:
            break
        found.append(match.group(1))
        index -= 1
    return found[::-1]


def collect_examples(text: str, page: str) -> list[Example]:
    """The examples of one Markdown page, in page order; raises ``ValueError`` on a malformed marker."""
    lines = text.splitlines()
    examples: list[Example] = []
    index = 0
    while index < len(lines):
        opening = lines[index].strip()
        if not opening.startswith("```"):
            index += 1
            continue
        end = index + 1
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        if end == len(lines):
            raise ValueError(f"{page}:{index + 1}: code block never closed")
        if opening[3:].strip().split(" ")[0] != "python":
            index = end + 1
            continue
        code = "\n".join(lines[index + 1 : end]) + "\n"
        skip = None
        follows = False
        for directive in _markers(lines, index):
            kind, _, argument = directive.partition(":")
            kind, argument = kind.strip(), argument.strip()
            if kind == "continue" and not argument:
                follows = True
            elif kind == "skip" and argument:
                skip = argument
            elif kind == "shorten" and "=>" in argument:
                old, new = (part.strip() for part in argument.split("=>", 1))
                if old not in code:
                    raise ValueError(f"{page}:{index + 1}: shorten marker's text {old!r} is not in the block")
                code = code.replace(old, new)
            else:
                raise ValueError(
                    f"{page}:{index + 1}: unknown example marker {directive!r}; expected 'continue', "
                    "'skip: <reason>' or 'shorten: <text> => <replacement>'"
                )
        if follows:
            if not examples:
                raise ValueError(f"{page}:{index + 1}: 'continue' marker on the page's first example")
            examples[-1].parts.append((index + 2, code))
            examples[-1].skip = examples[-1].skip or skip
        else:
            examples.append(Example(page, [(index + 2, code)], skip))
        index = end + 1
    return examples


def _all_examples() -> list[Example]:
    examples = []
    for page in PAGES:
        examples += collect_examples(page.read_text(encoding="utf-8"), page.relative_to(ROOT).as_posix())
    return examples


EXAMPLES = _all_examples()


def test_examples_are_found():
    pages = {example.page for example in EXAMPLES}
    assert {"README.md", "docs/svm.md", "docs/mixture.md", "docs/robustness.md"} <= pages


@pytest.mark.parametrize("example", EXAMPLES, ids=[example.id for example in EXAMPLES])
def test_example_runs(example, tmp_path, monkeypatch):
    if example.skip:
        pytest.skip(f"{example.id}: {example.skip}")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    namespace = {"__name__": "__main__", "__file__": str(tmp_path / "example.py")}
    try:
        exec(compile(example.script(), str(ROOT / example.page), "exec"), namespace)
    finally:
        plt.close("all")


def test_the_collector_applies_the_markers():
    page = (
        "text\n\n```python\na = 1\n```\n\n<!-- example: continue -->\n```python\nprint(a)\n```\n\n"
        "<!-- example: skip: needs a serial sensor -->\n```python\nimport serial\n```\n"
        "<!-- example: shorten: n_iter=2000 => n_iter=20 -->\n```python\nfit(n_iter=2000)\n```\n"
        "```bash\nnot python\n```\n"
    )
    examples = collect_examples(page, "page.md")
    assert [(e.line, e.code, e.skip) for e in examples] == [
        (4, "a = 1\nprint(a)\n", None),
        (14, "import serial\n", "needs a serial sensor"),
        (18, "fit(n_iter=20)\n", None),
    ]


@pytest.mark.parametrize(
    ("page", "message"),
    [
        ("<!-- example: continue -->\n```python\na = 1\n```\n", "first example"),
        ("<!-- example: skipp: x -->\n```python\na = 1\n```\n", "unknown example marker"),
        ("<!-- example: shorten: b => c -->\n```python\na = 1\n```\n", "is not in the block"),
        ("```python\na = 1\n", "never closed"),
    ],
)
def test_the_collector_rejects_malformed_markers(page, message):
    with pytest.raises(ValueError, match=message):
        collect_examples(page, "page.md")


def test_a_failing_example_names_its_page_line(tmp_path):
    (example,) = collect_examples(
        "# t\n\n```python\na = 1\n```\n\n<!-- example: continue -->\n```python\nb\n```\n", "p.md"
    )
    assert example.script() == "\n\n\na = 1\n\n\n\n\nb\n"
    with pytest.raises(NameError) as caught:
        exec(compile(example.script(), "p.md", "exec"), {})
    assert caught.traceback[-1].lineno + 1 == 9  # the line of `b` in the page
