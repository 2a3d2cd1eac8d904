"""SUMO's error log (``--error-log``, read where libsumo says only 'Process Error') never outlives its
process: removed when the simulation closes (at the latest when it is collected at exit), and, for a
process that was killed, by the next process's first simulation. Real SUMO through libsumo, in processes
of their own."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from irlsim.sim.inputs import LOG_PREFIX, remove_stale_logs

#: a process that starts SUMO on the oval, prints its error log's path once SUMO wrote it, then ends
#: as asked: 'close' (the simulation closed), 'exit' (never closed, held in a cycle, a normal exit),
#: 'kill' (SIGKILL, as a hung worker is killed)
CHILD = """
import gc, os, signal, sys
from irlsim.road import load_road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
gc.disable()
sim = Simulation(load_road(), EpisodeConfig(n_vehicles=2))
sim.reset(0)
sim.me = sim  # a cycle: no collection frees it before exit
assert sim.errors.path.exists(), sim.errors.path
print(sim.errors.path, flush=True)
how = sys.argv[1]
if how == "close":
    sim.close()
elif how == "kill":
    os.kill(os.getpid(), signal.SIGKILL)
"""


def _child(how: str, tmp: Path) -> tuple[int, Path]:
    env = {**os.environ, "TMPDIR": str(tmp)}
    run = subprocess.run([sys.executable, "-c", CHILD, how], capture_output=True, text=True, env=env)
    assert run.stdout.strip(), run.stderr[-2000:]
    return run.returncode, Path(run.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(os.name != "posix", reason="a process's own temporary folder and SIGKILL: POSIX")
def test_a_log_is_removed_on_close_at_exit_and_after_a_kill(tmp_path):
    rc, closed = _child("close", tmp_path)
    assert rc == 0 and closed.parent == tmp_path and not closed.exists()
    rc, never_closed = _child("exit", tmp_path)
    assert rc == 0 and not never_closed.exists()  # removed at exit
    rc, killed = _child("kill", tmp_path)
    assert rc == -signal.SIGKILL and killed.exists()  # nothing in a killed process runs
    rc, _ = _child("close", tmp_path)
    assert rc == 0 and not killed.exists()  # the next process's first simulation removed it
    assert not list(tmp_path.glob(f"{LOG_PREFIX}*"))


@pytest.mark.skipif(os.name != "posix", reason="whether a process exists: os.kill(pid, 0), POSIX")
def test_only_the_logs_of_ended_processes_are_removed(tmp_path):
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True)
    names = {
        "ended": f"{LOG_PREFIX}{int(ended.stdout)}-a.log",
        "own": f"{LOG_PREFIX}{os.getpid()}-b.log",  # this process's simulations are its own to close
        "parent": f"{LOG_PREFIX}{os.getppid()}-c.log",  # a live process
        "unnamed": f"{LOG_PREFIX}x-d.log",  # not a name this module gives: not its to remove
        "other": "sumo-errors.log",
    }
    for name in names.values():
        (tmp_path / name).write_text("")
    assert remove_stale_logs(tmp_path) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(set(names.values()) - {names["ended"]})
