"""Run a command and report its peak memory, split into what the kernel can reclaim and what it cannot.

    python tools/peak_memory.py [--every SECONDS] -- COMMAND [ARG ...]

``/usr/bin/time -v`` reports one number, the peak resident set; for a process that memory-maps its data
(the training reader's caches) most of that is file-backed: pages of the cache files that sit in the page
cache and are dropped under memory pressure (read again from disk), not memory the process holds. This
tool samples ``/proc/<pid>/status`` of the command and all its descendants every ``--every`` seconds and
prints the peaks of the sum over the tree of

    RssAnon   anonymous memory (arrays, tensors, the interpreter): what must fit in RAM
    RssFile   file-backed pages mapped by the processes (memory-mapped caches): reclaimable page cache
    RssShmem  shared memory

and of their total (VmRSS), plus the kernel's own peak of the largest process (``ru_maxrss``, what
``/usr/bin/time -v`` calls "Maximum resident set size"). Sampling can miss a peak shorter than the
interval; ru_maxrss cannot. Exits with the command's exit status.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from pathlib import Path

FIELDS = ("VmRSS", "RssAnon", "RssFile", "RssShmem")


def _parents() -> dict[int, int]:
    """pid -> parent pid of every process (from /proc/<pid>/stat)."""
    out = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        # the command name in parentheses may hold spaces: the fields after its ')' are state, ppid, ...
        out[int(stat.parent.name)] = int(text[text.rindex(")") + 2 :].split()[1])
    return out


def _tree(pid: int) -> list[int]:
    """pid and all its descendants."""
    parents = _parents()
    todo, seen = [pid], []
    while todo:
        p = todo.pop()
        seen.append(p)
        todo += [c for c, pp in parents.items() if pp == p]
    return seen


def _status(pid: int) -> dict[str, int]:
    """The FIELDS of one process [bytes]; {} once it is gone."""
    try:
        lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    except OSError:
        return {}
    out = {}
    for line in lines:
        key, _, value = line.partition(":")
        if key in FIELDS:
            out[key] = int(value.split()[0]) * 1024  # kB
    return out


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--every", type=float, default=0.05, help="sampling interval [s]")
    parser.add_argument("command", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    cmd = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not cmd:
        parser.error("no command given")
    start = time.monotonic()
    proc = subprocess.Popen(cmd)
    peak = dict.fromkeys(FIELDS, 0)
    while proc.poll() is None:
        total = dict.fromkeys(FIELDS, 0)
        for pid in _tree(proc.pid):
            for key, value in _status(pid).items():
                total[key] += value
        peak = {k: max(peak[k], total[k]) for k in FIELDS}
        time.sleep(args.every)
    wall = time.monotonic() - start
    maxrss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    gib = 1 << 30
    print(
        f"peak_memory: wall {wall:.1f} s, ru_maxrss {maxrss / gib:.2f} GiB; sampled peaks: "
        + ", ".join(f"{k} {v / gib:.2f} GiB" for k, v in peak.items()),
        file=sys.stderr,
        flush=True,
    )
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
