"""Check of the documentation (``make docs`` runs it before Sphinx): one home per passage, no dead references.

Findings, one line each (``PAGE:LINE: ...``), exit 1 when there is any:

- a paragraph (or list item, or table) of at least ``MIN_WORDS`` words that appears in two pages, or twice
  in one, after normalising whitespace and Markdown markup (links to their text, no backticks, emphasis,
  pipes or quote marks, lower case). No page is exempt, HISTORY.md included: a passage has one home and
  other pages link to it. Code blocks are not compared (the same command may be shown where it is used).
- a relative Markdown link (``[text](path)``, ``![alt](path)``) whose file does not exist, or whose
  ``#anchor`` names no heading of that page (GitHub-style slugs of headings down to level 4, as
  ``myst_heading_anchors`` in ``docs/conf.py``);
- a backticked repository path (``irlsim/...``, ``docs/...``, ``configs/...``, ``tools/...``,
  ``studies/...``, ``sumo_net/...``, ``tests/...``, ``examples/...``, ``pipelines/...``) that does not
  exist (a pytest node id: its file). Globs (``*``) must match something; a placeholder (``<name>``,
  ``NNNN``) checks the folder before it; paths the build writes (``GENERATED``), SUMO's own
  (``EXTERNAL``) and Gymnasium ids (``irlsim/Oval-v0``) are not the repository's.

The pages: README.md, DEVELOPERS.md and every ``docs/**/*.md`` except the generated API pages.

Usage: python tools/check_docs.py [ROOT]   (default: the repository this file is in)
"""

from __future__ import annotations

import re
import sys
from collections import defaultdict
from pathlib import Path

MIN_WORDS = 25
PREFIXES = (
    "irlsim/",
    "docs/",
    "configs/",
    "tools/",
    "studies/",
    "sumo_net/",
    "tests/",
    "examples/",
    "pipelines/",
)
#: paths that a build or a command writes (git-ignored), named in the docs on purpose
GENERATED = ("docs/api/", "sumo_net/oval/oval.net.xml")
#: paths that are not the repository's: the eclipse-sumo wheel's tools (``sumo_tools = "game/..."``)
EXTERNAL = ("tools/game/",)
ANCHOR_DEPTH = 4

_FENCE = re.compile(r"^\s*(```|~~~)")
_HEADING = re.compile(r"^(#{1,6}) +(.*?)\s*#*\s*$")
_LINK = re.compile(r"!?\[([^\]]*)\]\(([^)\s]*)\)")
_CODE = re.compile(r"`([^`\n]+)`")
_ITEM = re.compile(r"^\s*(?:[-*+]|\d+[.)])\s+")
_GYM_ID = re.compile(r"-v\d+$")  # `irlsim/Oval-v0` is a Gymnasium id, not a path
_SLUG_CLEAN = re.compile(r"[^\w\- ]")


def pages(root: Path) -> list[Path]:
    found = [root / "README.md", root / "DEVELOPERS.md", *sorted((root / "docs").rglob("*.md"))]
    return [p for p in found if p.is_file() and "api" not in p.relative_to(root).parts[1:2]]


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced blocks; fence and HTML-comment lines become blank."""
    out, fenced = [], False
    for n, line in enumerate(text.splitlines(), 1):
        if _FENCE.match(line):
            fenced = not fenced
            out.append((n, ""))
        else:
            out.append((n, "" if fenced or line.lstrip().startswith("<!--") else line))
    return out


def _blocks(text: str) -> list[tuple[int, str]]:
    """Paragraphs, list items and tables of a page: (first line, text); no indented code, no headings."""
    blocks: list[tuple[int, list[str]]] = []
    current: list[str] = []
    start = 0
    for n, line in _prose_lines(text) + [(0, "")]:
        if not line.strip() or _HEADING.match(line) or (line.startswith("    ") and not current):
            if current:
                blocks.append((start, current))
            current = []
            continue
        if _ITEM.match(line) and current:
            blocks.append((start, current))
            current = []
        if not current:
            start = n
        current.append(line)
    return [(n, " ".join(lines)) for n, lines in blocks]


def normalise(text: str) -> str:
    text = _LINK.sub(r"\1", text)
    text = _ITEM.sub("", text)
    text = re.sub(r"[`*_|>\"]", " ", text.replace("\\|", " "))
    return " ".join(text.lower().split())


def duplicates(root: Path) -> list[str]:
    seen: dict[str, list[str]] = defaultdict(list)
    for page in pages(root):
        for n, block in _blocks(page.read_text()):
            norm = normalise(block)
            if len(norm.split()) >= MIN_WORDS:
                seen[norm].append(f"{page.relative_to(root)}:{n}")
    return [
        f"{places[0]}: paragraph also at {', '.join(places[1:])} (keep it in one page and link to it)"
        for places in seen.values()
        if len(places) > 1
    ]


def slug(title: str) -> str:
    """The GitHub-style anchor of a heading (myst_parser.slugs.github_slugify on the heading's text)."""
    title = _LINK.sub(r"\1", title)
    return _SLUG_CLEAN.sub("", title.lower().replace(" ", "-"))


def anchors(page: Path) -> set[str]:
    found: set[str] = set()
    counts: dict[str, int] = defaultdict(int)
    for _, line in _prose_lines(page.read_text()):
        m = _HEADING.match(line)
        if m and len(m.group(1)) <= ANCHOR_DEPTH:
            s = slug(m.group(2))
            found.add(s if counts[s] == 0 else f"{s}-{counts[s]}")
            counts[s] += 1
    return found


def _link_problem(page: Path, target: str, root: Path) -> str | None:
    if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("/"):
        return None
    if not target:
        return "empty link target"
    path, _, anchor = target.partition("#")
    dest = (page.parent / path).resolve() if path else page
    if not dest.exists():
        return f"link to {target}: no such file"
    if anchor and dest.suffix == ".md" and anchor not in anchors(dest):
        return f"link to {target}: {dest.relative_to(root.resolve())} has no heading '#{anchor}'"
    return None


def _path_problem(token: str, root: Path) -> str | None:
    token = token.split()[0].split("::")[0].rstrip(".,;:)")  # a pytest node id names its file
    if not token.startswith(PREFIXES) or token.startswith(GENERATED + EXTERNAL) or _GYM_ID.search(token):
        return None
    for mark in ("<", "NNNN", "{", "["):
        if mark in token:
            token = token[: token.index(mark)].rsplit("/", 1)[0] + "/"
    if "*" in token:
        return None if any(root.glob(token)) else f"`{token}` matches no file"
    return None if (root / token).exists() else f"`{token}` does not exist"


def references(root: Path) -> list[str]:
    problems = []
    for page in pages(root):
        for n, line in _prose_lines(page.read_text()):
            name = f"{page.relative_to(root)}:{n}"
            for m in _LINK.finditer(line):
                problem = _link_problem(page, m.group(2), root)
                if problem:
                    problems.append(f"{name}: {problem}")
            for m in _CODE.finditer(_LINK.sub(r"\1", line)):
                problem = _path_problem(m.group(1), root)
                if problem:
                    problems.append(f"{name}: {problem}")
    return problems


def check(root: Path) -> list[str]:
    return duplicates(root) + references(root)


def main(argv: list[str]) -> int:
    root = Path(argv[0]) if argv else Path(__file__).resolve().parent.parent
    problems = check(root)
    for problem in problems:
        print(problem)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
