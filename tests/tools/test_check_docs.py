"""tools/check_docs.py (run by ``make docs``): the real pages pass; a paragraph copied into a second page, a
dead link, a dead anchor and a dead backticked path are each one line, and the command exits 1."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TOOL = ROOT / "tools" / "check_docs.py"

PARAGRAPH = (
    "The expert drives every shipped road within every bound on ten unseen seeds, with no collision, "
    "no exit, no red light crossed and every checkpoint in a lane the route goes on from, at the speed "
    "of SUMO's driver."
)


def _tool():
    spec = importlib.util.spec_from_file_location("check_docs", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _site(root: Path, pages: dict[str, str]) -> Path:
    for name, text in pages.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    (root / "configs").mkdir(exist_ok=True)
    (root / "configs" / "real.toml").write_text("")
    return root


def test_the_real_docs_pass():
    assert _tool().check(ROOT) == []


def test_a_paragraph_in_two_pages_is_one_line(tmp_path):
    tool = _tool()
    base = {
        "README.md": "# Front\n\nSee [the guide](docs/guide.md).\n",
        "docs/guide.md": f"# Guide\n\n{PARAGRAPH}\n",
    }
    assert tool.check(_site(tmp_path / "a", base)) == []
    # the copy differs in wrapping, markup and case only; a list item counts like a paragraph
    rest = PARAGRAPH[len("The expert drives every shipped road ") :]
    copy = "**the** expert drives\n   every shipped road " + rest
    problems = tool.check(_site(tmp_path / "b", {**base, "docs/results.md": f"# R\n\n- {copy}\n- short\n"}))
    assert problems == [
        "docs/guide.md:3: paragraph also at docs/results.md:3 (keep it in one page and link to it)"
    ]
    # a short repeated line and a repeated code block are not findings
    short = "Every bound holds.\n\n    make demo  # " + PARAGRAPH + "\n"
    assert tool.check(_site(tmp_path / "c", {**base, "docs/a.md": short, "docs/b.md": short})) == []


def test_dead_links_anchors_and_paths_are_one_line_each(tmp_path):
    tool = _tool()
    page = (
        "# Guide\n\n## The sweep, measured\n\n"
        "[ok](other.md#second-part) [self](#the-sweep-measured) [img](img/x.png) [web](https://example.org/x)\n"
        "`configs/real.toml` `configs/*.toml` `irlsim/Oval-v0` `docs/api/irlsim.road.md` `runs/anything`\n"
        "[gone](missing.md) [no anchor](other.md#nowhere)\n"
        "`configs/missing.toml` `tests/none/*.py`\n"
        "```\n[in code](missing.md) `configs/in-code.toml`\n```\n"
    )
    root = _site(tmp_path, {"docs/guide.md": page, "docs/other.md": "# Other\n\n### Second part\n"})
    (root / "docs" / "img").mkdir()
    (root / "docs" / "img" / "x.png").write_bytes(b"")
    assert tool.check(root) == [
        "docs/guide.md:7: link to missing.md: no such file",
        "docs/guide.md:7: link to other.md#nowhere: docs/other.md has no heading '#nowhere'",
        "docs/guide.md:8: `configs/missing.toml` does not exist",
        "docs/guide.md:8: `tests/none/*.py` matches no file",
    ]
    run = subprocess.run([sys.executable, str(TOOL), str(root)], capture_output=True, text=True)
    assert run.returncode == 1 and len(run.stdout.splitlines()) == 4 and run.stderr == ""
    assert subprocess.run([sys.executable, str(TOOL), str(ROOT)], capture_output=True).returncode == 0
