"""Every reference in the README and the docs resolves inside the repository."""

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])
# [text](target) and ![alt](target); the text may span lines, the target may not
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
EXTERNAL = ("http://", "https://", "mailto:")
# What a reader of the repository does not have: notes outside it, and issue numbers.
OUTSIDE = re.compile(r"\.\./shared|shared/|DESIGN\.md|model-?notes|hardware\.md|\bissue \d+")


def links(text: str) -> list[str]:
    return LINK.findall(text)


def test_the_link_pattern_finds_links_and_images():
    text = "see [a](x.md) and ![b](img/y.png)\nand [c](https://e.org) and [d](z.md#part)"
    assert links(text) == ["x.md", "img/y.png", "https://e.org", "z.md#part"]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_points_at_a_file(page):
    text = page.read_text(encoding="utf-8")
    broken = []
    for target in links(text):
        if target.startswith(EXTERNAL) or target.startswith("#"):
            continue
        path = target.split("#", 1)[0]
        if not (page.parent / path).exists():
            broken.append(target)
    assert not broken, f"{page.relative_to(REPO)}: no such file for {broken}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_no_reference_points_outside_the_repository(page):
    name = str(page.relative_to(REPO))
    found = OUTSIDE.findall(page.read_text(encoding="utf-8"))
    assert not found, f"{name} refers to {found}"


def test_the_docs_have_their_sections():
    for folder in ("tutorials", "how-to", "reference", "explanation", "decisions"):
        assert list((REPO / "docs" / folder).glob("*.md")), folder
