"""Sphinx configuration of irlsim's documentation: the Markdown pages (README, docs/*.md) through
myst-parser, and an API reference built from the docstrings by autodoc.

Build: ``make docs`` (``sphinx-build -W --keep-going -E -b html docs build/docs``; warnings are errors).

The API pages (``docs/api/<package>.md``, git-ignored) are written here at every build from
``API_MODULES``: one page per entry, with every submodule of a package. A new public package is one line
in that list.
"""

from __future__ import annotations

import importlib
import pkgutil
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))

project = "irlsim"
author = "the irlsim authors"
copyright = "2026, the irlsim authors"
release = importlib.import_module("irlsim").__version__

extensions = ["myst_parser", "sphinx.ext.autodoc"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]
html_theme = "alabaster"
html_title = f"irlsim {release}"
html_theme_options = {"page_width": "1200px", "sidebar_width": "240px"}

# Markdown: GitHub-style heading anchors (README and docs link to "#the-papers-scale" and the like),
# dollar maths off (the pages write prices and shell variables with $).
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]
# The pages are written for GitHub first: a heading may jump a level (#### under ##) after sections moved.
suppress_warnings = ["myst.header"]

# autodoc: members in source order, with base classes; signatures keep the annotations as written.
autodoc_default_options = {"member-order": "bysource", "show-inheritance": True}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
# SUMO, Ray and Gymnasium are imported inside functions (docs/design/layers.md), so importing the modules
# for autodoc starts none of them; torch is a runtime dependency and is imported for real.

#: the public API, one page each; packages list every submodule
API_MODULES = [
    "irlsim.road",
    "irlsim.sim",
    "irlsim.planner",
    "irlsim.rollout",
    "irlsim.data",
    "irlsim.models",
    "irlsim.irl",
    "irlsim.train",
    "irlsim.drive",
    "irlsim.envs",
    "irlsim.config",
    "irlsim.errors",
]


def _submodules(name: str) -> list[str]:
    module = importlib.import_module(name)
    if not hasattr(module, "__path__"):
        return []
    return sorted(f"{name}.{m.name}" for m in pkgutil.iter_modules(module.__path__))


def _page(name: str) -> str:
    subs = _submodules(name)
    # autodoc writes reStructuredText, so its directives sit in eval-rst blocks (MyST would read it as Markdown)
    lines = [f"# `{name}`", "", "```{eval-rst}", f".. automodule:: {name}"]
    lines += ([] if subs else ["   :members:"]) + ["```", ""]
    for sub in subs:
        lines += [f"## `{sub}`", "", "```{eval-rst}", f".. automodule:: {sub}", "   :members:", "```", ""]
    return "\n".join(lines)


def _write_if_changed(path: Path, text: str) -> None:
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def _write_api_pages() -> None:
    api = DOCS / "api"
    api.mkdir(exist_ok=True)
    for old in api.glob("*.md"):
        if old.stem not in API_MODULES and old.name != "index.md":
            old.unlink()
    for name in API_MODULES:
        _write_if_changed(api / f"{name}.md", _page(name))
    toc = "\n".join(API_MODULES)
    index = (
        "# API reference\n\nBuilt from the docstrings. Shapes are written as `[cycles, policies, 15]`; "
        "units are SI.\n\n```{toctree}\n:maxdepth: 1\n\n" + toc + "\n```\n"
    )
    _write_if_changed(api / "index.md", index)


_write_api_pages()


# The docstrings are written to read well as plain text. Two habits of that style mean something else in
# reStructuredText, so each docstring is adjusted before it is parsed (the source stays as it is):
# - a table drawn with pipes (lines starting and ending with "|") becomes a literal block, as it reads;
# - an indented block under a paragraph (aligned columns, formulas, "key  meaning" lists) becomes a
#   literal block too, as it reads (rST would see a block quote or a definition list, or an error);
# - |x| (an absolute value or norm) is not a substitution: outside inline literals (``...``) and literal
#   blocks (after a paragraph ending with "::") a pipe is escaped.
_LITERAL = re.compile(r"(``.*?``)")
_STRUCTURE = re.compile(r"^([-*+] |\d+[.)] |\(\w+\) |\.\. |:\w[^:]*: )")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _is_table_row(line: str) -> bool:
    stripped = line.strip()
    return len(stripped) > 1 and stripped.startswith("|") and stripped.endswith("|")


def _escape_pipes(line: str) -> str:
    parts = _LITERAL.split(line)
    return "".join(p if p.startswith("``") else p.replace("|", r"\|") for p in parts)


def _plain_text_to_rst(lines: list[str]) -> list[str]:
    out: list[str] = []
    literal_indent: int | None = None  # inside a literal block: the indentation of its "::" paragraph
    i = 0
    while i < len(lines):
        line = lines[i]
        if literal_indent is not None and (not line.strip() or _indent(line) > literal_indent):
            out.append(line)
            i += 1
            continue
        literal_indent = None
        j = i
        while j < len(lines) and _is_table_row(lines[j]):
            j += 1
        if j - i >= 2:
            out += ["", "::", ""] + ["    " + row for row in lines[i:j]] + [""]
            i = j
            continue
        parent = next((p for p in reversed(out) if p.strip()), "")
        if line.strip() and _indent(line) > _indent(parent) == 0 and not _STRUCTURE.match(parent):
            if not parent.rstrip().endswith("::"):
                out += ["", "::", ""]
            out.append(line)
            literal_indent = 0
            i += 1
            continue
        out.append(_escape_pipes(line))
        if line.rstrip().endswith("::"):
            literal_indent = _indent(line)
        i += 1
    return out


_RST_TABLE = re.compile(r"^=+( +=+)+\s*$")


def _process_docstring(app, what, name, obj, options, lines) -> None:
    if any(_RST_TABLE.match(line) for line in lines):  # written as reStructuredText already
        return
    lines[:] = _plain_text_to_rst(lines)


def setup(app) -> None:
    app.connect("autodoc-process-docstring", _process_docstring)
