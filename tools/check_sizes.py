"""Size limits of the code (``make lint``): no file over 500 lines and no function over 80 lines unless a
``# size-ok: <why>`` comment says why (for a file: in its first 40 lines; for a function: on the line
above its ``def`` or decorators, or on the ``def`` line itself).

Usage: python tools/check_sizes.py DIR_OR_FILE... ; exit 1 and one line per offender when any limit is
broken without a reason.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 80
MARK = "# size-ok:"


def _has_reason(line: str) -> bool:
    i = line.find(MARK)
    return i >= 0 and line[i + len(MARK) :].strip() != ""


def check_file(path: Path) -> list[str]:
    text = path.read_text()
    lines = text.splitlines()
    problems = []
    if len(lines) > MAX_FILE_LINES and not any(_has_reason(x) for x in lines[:40]):
        problems.append(f"{path}: {len(lines)} lines > {MAX_FILE_LINES} (split it, or say why: '{MARK} ...')")
    for node in ast.walk(ast.parse(text, str(path))):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        assert node.end_lineno is not None
        first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
        n = node.end_lineno - node.lineno + 1
        near = lines[max(first - 2, 0) : node.lineno]
        if n > MAX_FUNCTION_LINES and not any(_has_reason(x) for x in near):
            problems.append(
                f"{path}:{node.lineno}: function {node.name} has {n} lines > {MAX_FUNCTION_LINES} "
                f"(split it, or say why above its def: '{MARK} ...')"
            )
    return problems


def main(args: list[str]) -> int:
    files = sorted(f for a in args for f in (Path(a).rglob("*.py") if Path(a).is_dir() else [Path(a)]))
    problems = [p for f in files for p in check_file(f)]
    for p in problems:
        print(p)
    print(f"check_sizes: {len(files)} files, {len(problems)} over the limits without a reason")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
