"""What verifying a dataset's cache costs a training: ``irlsim train --stage 1`` run twice in this process
with timers around the cache's hashing at its build (``write_cache_meta``) and its check on open
(``verify_cache``), against the epochs' time that the models' ``metrics.csv`` record.

    python tools/cache_check_cost.py DATA CONFIG RUNS [--set KEY=VALUE ...]

The first run starts without a cache (built and hashed), the second verifies it as a new process would.
DATA's ``.cache`` and RUNS are deleted first. Prints one line per run
(docs/results/speed-memory.md, "What verifying the caches costs").
"""

from __future__ import annotations

import csv
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from irlsim.cli import main as irlsim
from irlsim.data import cache, reader

SPENT = {"build": 0.0, "verify": 0.0}


def _timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            SPENT[name] += time.perf_counter() - start

    return wrapper


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    data, config, runs, *sets = argv
    reader.write_cache_meta = _timed("build", cache.write_cache_meta)  # type: ignore[assignment]
    reader.verify_cache = _timed("verify", cache.verify_cache)  # type: ignore[assignment]
    shutil.rmtree(Path(data) / cache.CACHE_DIR, ignore_errors=True)
    for run in ("no cache (built and hashed)", "cache verified"):
        SPENT.update(build=0.0, verify=0.0)
        cache._VERIFIED.clear()  # as a new process
        shutil.rmtree(runs, ignore_errors=True)
        if irlsim(["train", "--stage", "1", "--config", config, "--data", data, "--out", runs, *sets]) != 0:
            return 1
        epochs = [
            float(row["time/epoch_s"])
            for log in sorted(Path(runs, "stage1").glob("*/metrics.csv"))
            for row in csv.DictReader(log.open())
        ]
        checks = SPENT["build"] + SPENT["verify"]
        print(
            f"{run}: {len(epochs)} epochs, {sum(epochs) / len(epochs):.3f} s each; hash at build "
            f"{SPENT['build']:.3f} s, verify {SPENT['verify']:.3f} s: {1000 * checks / len(epochs):.1f} ms "
            f"per epoch ({100 * checks / sum(epochs):.2f} % of the epochs)",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
