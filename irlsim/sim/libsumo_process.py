"""SUMO asked a question in a process of its own (libsumo), so that the command's own simulation, if it
has one, is untouched: the vehicle types a recording names (:mod:`irlsim.sim.vehicle_types`), geographic
points on a network (:mod:`irlsim.sim.geo`)."""

from __future__ import annotations

import os
import subprocess
import sys

from irlsim.errors import IrlsimError
from irlsim.road.network import sumo_home


def run_libsumo(
    script: str, args: list[str], timeout: float, task: str
) -> tuple[subprocess.CompletedProcess[str], list[str]]:
    """Run the Python ``script`` (which starts libsumo) with ``args`` in a process of its own; its result
    and SUMO's error lines (the text after ``Error:``). Over ``timeout`` seconds: one line, "SUMO took over
    ... s to <task>"."""
    env = {**os.environ, "SUMO_HOME": sumo_home()}
    cmd = [sys.executable, "-c", script, *args]
    try:
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        raise IrlsimError(f"SUMO took over {timeout:g} s to {task}") from None
    errors = [ln[len("Error:") :].strip() for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    return res, errors
