"""The documentation holds together: every relative link in the README, the docs/ pages, the add-on's README and the
model cards names a file or folder that exists, and every docs/ page can be reached from the README's map."""

from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = sorted([REPO / "README.md", REPO / "blender_addon" / "README.md", *(REPO / "docs").rglob("*.md"),
                *(REPO / "dancenet_core" / "weights").glob("*.md")])
FENCE = re.compile(r"^ {0,3}(```|~~~).*?^ {0,3}\1", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"(`+).+?\1", re.DOTALL)
# [text](target "title") and ![alt](target); the text may hold one level of brackets, the target no spaces or
# parentheses (none of ours has them); <a href> and <img src> too.
INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HTML = re.compile(r"<(?:a|img)\s[^>]*?(?:href|src)=\"([^\"]+)\"", re.IGNORECASE)
REFERENCE = re.compile(r"^ {0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s|$)", re.MULTILINE)
EXTERNAL = re.compile(r"^(?:[a-z][a-z0-9+.-]*:|//)", re.IGNORECASE)  # http:, https:, mailto:, protocol-relative


def links(text: str) -> list[str]:
    """The link targets of a Markdown text, outside fenced code blocks and code spans."""
    prose = CODE_SPAN.sub("", FENCE.sub("", text))
    return [m.group(1) for pattern in (INLINE, HTML, REFERENCE) for m in pattern.finditer(prose)]


def relative_targets(page: Path) -> list[str]:
    """The targets of `page` that point into the repository (no scheme, not only an anchor), anchors dropped."""
    out = []
    for target in links(page.read_text(encoding="utf-8")):
        path = unquote(target.split("#", 1)[0].split("?", 1)[0])
        if path and not EXTERNAL.match(target):
            out.append(path)
    return out


def test_the_link_finder_finds_what_it_should_and_skips_code() -> None:
    text = ("See [install](docs/install.md#pip), ![a picture](docs/p.png \"title\"), [web](https://example.org),\n"
            "[top](#licence), <img src=\"docs/q.png\" width=300>, [nested [x]](a/b.md) and `[not](code.md)`.\n"
            "```sh\n[also not](fenced.md)\n```\n[ref]: docs/ref.md\n")
    assert links(text) == ["docs/install.md#pip", "docs/p.png", "https://example.org", "#licence", "a/b.md",
                           "docs/q.png", "docs/ref.md"]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_resolves(page: Path) -> None:
    dead = [t for t in relative_targets(page) if not (page.parent / t).exists()]
    assert dead == [], f"{page.relative_to(REPO)} links to missing files: {dead}"


def test_every_docs_page_is_linked_from_the_readme() -> None:
    linked = {(REPO / t).resolve() for t in relative_targets(REPO / "README.md")}
    unlinked = [str(p.relative_to(REPO)) for p in sorted((REPO / "docs").rglob("*.md")) if p.resolve() not in linked]
    assert unlinked == [], f"docs pages missing from the README's map: {unlinked}"


def test_a_dead_link_is_caught(tmp_path: Path) -> None:
    (tmp_path / "there.md").write_text("x")
    page = tmp_path / "page.md"
    page.write_text("[ok](there.md) [gone](missing.md#part) [web](https://example.org/missing.md)")
    assert [t for t in relative_targets(page) if not (page.parent / t).exists()] == ["missing.md"]
