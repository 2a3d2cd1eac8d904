"""The test suite's time against its budget (``make test`` runs it after pytest): reported, never failed on.

``make test`` writes pytest's JUnit report to ``build/test-report.xml``; this prints the suite's wall time,
the number of tests, the CPU it ran on and the budget that applies (DEVELOPERS.md, "Time budget of the
suite"), and the slowest tests: the ones to make cheaper or to move to ``make test-slow`` when the suite
grows past its budget. A timed test would fail on a loaded machine; a report cannot.

Usage: python tools/test_budget.py [REPORT.xml] [--top N]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

#: [s] the whole ``make test`` on 2 cores: 8 minutes on an AVX2-only x86-64 (AMD EPYC of the Zen 2 family),
#: the slower CPU family it runs on, and the same suite's time on an x86-64 with AVX-512 (an Intel Xeon),
#: which runs it 1.4 times as fast (measured on one commit: 312 s against 440 s)
BUDGET_S = {"avx512": 340.0, "avx2": 480.0}


def cpu_name() -> str:
    """The CPU's model name (Linux /proc/cpuinfo; elsewhere the platform's processor string)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def has_avx512() -> bool:
    try:
        return " avx512f " in f" {Path('/proc/cpuinfo').read_text().replace(chr(10), ' ')} "
    except OSError:
        return False


def read_report(path: Path) -> tuple[float, int, list[tuple[float, str]]]:
    """(suite seconds, tests run, [(seconds, test id)] slowest first) of a JUnit XML report."""
    root = ET.parse(path).getroot()
    suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
    total = sum(float(s.get("time", 0.0)) for s in suites)
    cases = []
    for case in root.iter("testcase"):
        if case.find("skipped") is not None:
            continue
        cases.append((float(case.get("time", 0.0)), f"{case.get('classname')}::{case.get('name')}"))
    cases.sort(reverse=True)
    return total, len(cases), cases


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("report", nargs="?", default="build/test-report.xml", type=Path)
    p.add_argument("--top", type=int, default=10, help="how many of the slowest tests to list")
    args = p.parse_args(argv)
    if not args.report.is_file():
        print(f"test budget: no report at {args.report}: run 'make test' first", file=sys.stderr)
        return 2
    try:
        total, n, cases = read_report(args.report)
    except ET.ParseError as e:
        print(
            f"test budget: {args.report} is not a JUnit XML report ({e}): run 'make test' again",
            file=sys.stderr,
        )
        return 2
    kind = "avx512" if has_avx512() else "avx2"
    budget = BUDGET_S[kind]
    verdict = "within" if total <= budget else "OVER"
    cores = os.cpu_count()
    print(
        f"test budget: {n} tests in {total:.0f} s on {cores} cores of {cpu_name()} ({kind.upper()}): "
        f"{verdict} the {budget:.0f} s budget of such a machine"
    )
    for seconds, name in cases[: args.top]:
        print(f"  {seconds:6.1f} s  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
