"""The documentation stands alone: every relative link in README.md, CONTRIBUTING.md and docs/ resolves.

A link must name a file or directory of the repository that exists, and a ``#fragment`` into a Markdown
page must name one of its headings (GitHub's anchors). Nothing may point outside the repository (the
real data sets are found through ``TACTILE_TORCH_SHARED_DATA``, not by a relative path), and
``docs/index.md`` lists every page under ``docs/``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted(
    [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *(ROOT / "docs").rglob("*.md")],
    key=lambda path: path.relative_to(ROOT).as_posix(),
)

_FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
_CODE_SPAN = re.compile(r"(`+)(.+?)\1", re.DOTALL)
# [text](target) and ![alt](target); the text may hold one level of brackets; an optional "title".
_INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^()\s<>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
_REFERENCE_DEFINITION = re.compile(r"^ {0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+\"[^\"]*\")?\s*$", re.MULTILINE)
_HEADING = re.compile(r"^ {0,3}#{1,6}[ \t]+(.+?)[ \t#]*$", re.MULTILINE)
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_INTERNAL_REFERENCE = re.compile(r"\b(issue|ticket)s?\s+#?\d+\b|\bthe \w+ issue\b", re.IGNORECASE)


def _prose(text: str) -> str:
    """The text without fenced code blocks, and with inline code reduced to its content."""
    text = _FENCE.sub("", text)
    return _CODE_SPAN.sub(lambda match: match.group(2).replace("[", "(").replace("]", ")"), text)


def links(text: str) -> list[str]:
    """Targets of the inline links, images and reference definitions of a Markdown text."""
    prose = _prose(text)
    return _INLINE_LINK.findall(prose) + _REFERENCE_DEFINITION.findall(prose)


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: rendered text, lower case, punctuation dropped, spaces to '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link renders as its text
    text = text.replace("`", "").lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every anchor of a Markdown page (repeated headings get -1, -2, ... as on GitHub)."""
    seen: dict[str, int] = {}
    result = set()
    for heading in _HEADING.findall(_FENCE.sub("", page.read_text(encoding="utf-8"))):
        anchor = github_anchor(heading)
        count = seen.get(anchor, 0)
        seen[anchor] = count + 1
        result.add(anchor if count == 0 else f"{anchor}-{count}")
    return result


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    """One line per link of ``page`` that does not resolve inside the repository ``root``."""
    problems = []
    for target in links(page.read_text(encoding="utf-8")):
        if not target or _SCHEME.match(target):  # http:, https:, mailto: ... are not checked here
            continue
        path_part, _, fragment = target.partition("#")
        resolved = (page.parent / path_part).resolve() if path_part else page
        if not resolved.is_relative_to(root):
            problems.append(f"{target}: points outside the repository")
        elif not resolved.exists():
            problems.append(f"{target}: no such file")
        elif fragment and resolved.suffix == ".md" and fragment not in anchors(resolved):
            problems.append(f"{target}: no heading with anchor #{fragment} in {resolved.name}")
    return problems


def _page_id(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def test_the_pages_are_found():
    names = {_page_id(page) for page in PAGES}
    assert {"README.md", "docs/index.md", "docs/performance/image.md"} <= names


@pytest.mark.parametrize("page", PAGES, ids=_page_id)
def test_every_relative_link_resolves(page):
    problems = broken_links(page)
    assert not problems, f"{_page_id(page)}: broken links:\n" + "\n".join(problems)


@pytest.mark.parametrize("page", PAGES, ids=_page_id)
def test_no_path_to_the_shared_directory_and_no_internal_references(page):
    text = page.read_text(encoding="utf-8")
    assert "../shared" not in text, f"{_page_id(page)} mentions ../shared: the repository stands alone"
    found = [match.group(0) for match in _INTERNAL_REFERENCE.finditer(text)]
    assert not found, f"{_page_id(page)} refers to the project's issue tracker: {found}"


def test_the_index_lists_every_page():
    index = ROOT / "docs" / "index.md"
    listed = {(index.parent / target.partition("#")[0]).resolve() for target in links(index.read_text())}
    missing = [
        _page_id(page) for page in PAGES if page.parent != ROOT and page != index and page not in listed
    ]
    assert not missing, f"docs/index.md does not list: {missing}"


def test_the_checker_finds_what_is_broken(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "b.md").write_text("# Why not `kornia`\n\n## Speed: 2x (ours)\n")
    page = tmp_path / "docs" / "a.md"
    page.write_text(
        "[ok](b.md) [anchor](b.md#why-not-kornia) [punctuation](b.md#speed-2x-ours) [web](https://x.org/y)\n"
        "[missing](c.md) [bad anchor](b.md#speed) [outside](../../shared/data) ![image](fig.png)\n"
        "`[not a link](code.md)`\n\n```\n[not a link](fenced.md)\n```\n[ref]: gone.md\n"
    )
    assert broken_links(page, root=tmp_path) == [
        "c.md: no such file",
        "b.md#speed: no heading with anchor #speed in b.md",
        "../../shared/data: points outside the repository",
        "fig.png: no such file",
        "gone.md: no such file",
    ]
