"""Compare the files of two output trees (e.g. two ``irlsim demo --preset tiny`` runs) by sha256.

    python tools/sha_compare.py BEFORE AFTER [--alias OLD NEW ...]

BEFORE and AFTER are folders (each holding e.g. ``data/`` and ``runs/``). Every file below them is
hashed, except caches, locks and logs (``.cache/``, ``.lock``, ``*.log``,
TensorBoard's ``events.out.tfevents.*``). A file whose bytes differ is
compared again as text with each tree's own root path replaced by ``<ROOT>`` (summaries and drive.json
record the folders they were given), and each ``--alias OLD NEW`` pair read as the same path (e.g. the
two checkouts whose ``configs/`` the runs read). A JSON or CSV file that still differs is compared once
more without the values that are wall-clock measurements (keys or columns named in ``VOLATILE``:
timings and rates, which change between two runs of the same command); a Markdown table likewise
without its timing columns. Prints one line per file that is not byte-identical, and a summary; exits 1
when a file differs beyond those, or is missing on one side.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
from pathlib import Path
from typing import Any

SKIP_PARTS = {".cache"}
SKIP_NAMES = {".lock"}
SKIP_SUFFIXES = {".log"}
#: TensorBoard event logs: their names hold the time, host and process id of the run that wrote them
SKIP_PREFIXES = ("events.out.tfevents.",)
#: the last part of a key (after '/') or a column name whose values are wall-clock measurements
VOLATILE = ("wall_s", "setup_s", "epoch_s", "_ms", "_ms_mean", "_ms_p90", "per_s", "cycles_per_s")
#: Markdown column headers that hold timings
MD_TIMING = ("ms", "wall")


def files(root: Path) -> dict[str, Path]:
    out = {}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if (
            not p.is_file()
            or SKIP_PARTS & set(rel.parts)
            or p.name in SKIP_NAMES
            or p.suffix in SKIP_SUFFIXES
            or p.name.startswith(SKIP_PREFIXES)
        ):
            continue
        out[rel.as_posix()] = p
    return out


def volatile(key: str) -> bool:
    last = key.split("/")[-1]
    return any(last == v or last.endswith(v) for v in VOLATILE)


def strip_volatile(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: strip_volatile(v) for k, v in obj.items() if not volatile(str(k))}
    if isinstance(obj, list):
        return [strip_volatile(v) for v in obj]
    return obj


def csv_rows(text: str) -> list[list[str]]:
    rows = list(csv.reader(io.StringIO(text)))
    keep = [i for i, name in enumerate(rows[0] if rows else []) if not volatile(name)]
    return [[r[i] for i in keep if i < len(r)] for r in rows]


def md_equal_but_timings(x: str, y: str) -> bool:
    """Equal once the table columns whose header (the row above a ``|---`` row) names a time are dropped."""
    lx, ly = x.splitlines(), y.splitlines()
    if len(lx) != len(ly):
        return False
    drop: set[int] = set()
    for i, (u, v) in enumerate(zip(lx, ly, strict=True)):
        if i + 1 < len(lx) and lx[i + 1].startswith("|---") and u == v:
            drop = {k for k, c in enumerate(u.split("|")) if any(t in c for t in MD_TIMING)}
        if u == v:
            continue
        cu, cv = u.split("|"), v.split("|")
        if not u.startswith("|") or len(cu) != len(cv):
            return False
        if any(cu[k] != cv[k] for k in range(len(cu)) if k not in drop):
            return False
    return True


def normalise(data: bytes, root: Path, aliases: list[str]) -> str:
    text = data.decode()
    for path in sorted({str(root.resolve()), str(root), *aliases}, key=len, reverse=True):
        text = text.replace(path, "<ROOT>" if path in (str(root.resolve()), str(root)) else "<ALIAS>")
    return text


def verdict(rel: str, x: bytes, y: bytes, before: Path, after: Path, aliases: list[tuple[str, str]]) -> str:
    """'' when equal; else a label: 'paths', 'timings' (both acceptable) or 'DIFFERS'."""
    if x == y:
        return ""
    try:
        tx = normalise(x, before, [a for a, _ in aliases])
        ty = normalise(y, after, [b for _, b in aliases])
    except UnicodeDecodeError:
        return "DIFFERS"
    if tx == ty:
        return "paths"
    if rel.endswith(".json") and strip_volatile(json.loads(tx)) == strip_volatile(json.loads(ty)):
        return "timings"
    if rel.endswith(".csv") and csv_rows(tx) == csv_rows(ty):
        return "timings"
    if rel.endswith(".md") and md_equal_but_timings(tx, ty):
        return "timings"
    return "DIFFERS"


def compare(before: Path, after: Path, aliases: list[tuple[str, str]]) -> int:
    a, b = files(before), files(after)
    bad = same = 0
    for rel in sorted(set(a) | set(b)):
        if rel not in a or rel not in b:
            print(f"MISSING  {rel} (only in {'after' if rel in b else 'before'})")
            bad += 1
            continue
        label = verdict(rel, a[rel].read_bytes(), b[rel].read_bytes(), before, after, aliases)
        if not label:
            same += 1
        else:
            print(f"{label:<8} {rel}")
            bad += label == "DIFFERS"
    print(f"{same} of {len(set(a) | set(b))} files byte-identical; {bad} differ beyond paths and timings")
    return 1 if bad else 0


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    p.add_argument("--alias", nargs=2, action="append", default=[], metavar=("OLD", "NEW"))
    args = p.parse_args()
    sys.exit(compare(args.before, args.after, [tuple(x) for x in args.alias]))
