"""The episode executor (irlsim.executor): the local spawn workers and Ray tasks give the same bytes, a
worker killed in the middle of an episode is retried, a worker that hangs (SIGSTOP) is killed after
--episode-timeout and retried, an episode that keeps failing is named and collected again by the same
command. Real processes, real SUMO, real Parquet, a real Ray: one simulated
two-node cluster (ray.cluster_utils.Cluster, 1 CPU per node) shared by this module's Ray tests.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

import irlsim.executor
from irlsim.cli import main
from irlsim.data.layout import episode_paths
from irlsim.executor import RAY_CANCEL_WAIT_S, Job, describe_failures, run_jobs
from tests.conftest import TINY_COLLECT
from tests.drive.conftest import tiny_runs  # noqa: F401 - the fixture, shared with the drive tests
from tests.pipelines.executor_jobs import always_fails, die_once, double, pid_and_double, stops_itself

ROOT = Path(__file__).resolve().parents[2]
#: the session's tiny dataset (one in-process worker) is the reference; these runs use two workers
TWO_WORKERS = [*TINY_COLLECT, "--set", "workers=2"]


def _collect_args(out: Path, *extra: str) -> list[str]:
    return ["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TWO_WORKERS, *extra]


def _sha256(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*.parquet"))
    }


# ------------------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def ray_cluster():
    """One simulated two-node Ray cluster for the module (head + one worker node, 1 CPU each)."""
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address, include_dashboard=False, log_to_driver=False)
    try:
        yield cluster
    finally:
        ray.shutdown()
        cluster.shutdown()


# ----------------------------------------------------------------------------- the executor by itself


@pytest.mark.parametrize("executor", ["inline", "local", "ray"])
def test_results_retries_and_failures(executor, tmp_path, request):
    """Each job's result once; a raising job is tried twice and named with a one-line reason; the others
    finish; a worker that dies (not possible in this process) is replaced and its job retried."""
    if executor == "ray":
        request.getfixturevalue("ray_cluster")
    kind, workers = ("local", 1) if executor == "inline" else (executor, 2)
    seen: list[str] = []
    retried: list[str] = []
    jobs = [Job(f"ok/{i}", i) for i in range(5)]
    out = run_jobs(
        double,
        jobs,
        executor=kind,
        workers=workers,
        on_result=lambda job, value: seen.append(job.key),
        on_retry=lambda job, reason: retried.append(job.key),
    )
    assert out.results == {f"ok/{i}": 2 * i for i in range(5)} and not out.failed
    assert sorted(seen) == sorted(out.results) and not retried

    failing = run_jobs(
        always_fails,
        [Job("bad/7", 7), Job("ok/1", 1)],
        executor=kind,
        workers=workers,
        on_retry=lambda job, reason: retried.append(job.key),
    )
    assert failing.failed == {"bad/7": "RuntimeError: episode 7 cannot be driven"}
    assert failing.results == {"ok/1": 2}
    assert retried == ["bad/7"]
    if executor == "inline":
        return
    died = run_jobs(
        die_once,
        [
            Job("a", (str(tmp_path / "a"), 1)),
            Job("b", (str(tmp_path / "b"), 2)),
            Job("c", (str(tmp_path / "c"), 3)),
        ],
        executor=kind,
        workers=workers,
    )
    assert died.results == {"a": 2, "b": 4, "c": 6} and not died.failed
    assert set(died.retried) == {"a", "b", "c"}
    assert all("died" in reason for reason in died.retried.values()), died.retried


#: a time limit far above a start-up and stops_itself's return, far below a test's patience
HANG_TIMEOUT = 5.0
#: [s] SIGTERM's grace here: a stopped worker never uses it (SIGKILL ends it), so the test waits less
KILL_GRACE_S = 0.5


def test_one_worker_runs_the_jobs_in_a_worker_process_when_they_have_a_time_limit():
    """One worker runs the jobs in this process, unless they have a time limit: a job here could not be
    killed, so one worker process runs them (its kill and retry: the test below, with two)."""
    jobs = [Job(f"ok/{i}", i) for i in (1, 2, 3)]
    limited = run_jobs(pid_and_double, jobs, executor="local", workers=1, timeout=HANG_TIMEOUT)
    inline = run_jobs(pid_and_double, jobs, executor="local", workers=1)
    for out in (limited, inline):
        assert {key: v for key, (_, v) in out.results.items()} == {"ok/1": 2, "ok/2": 4, "ok/3": 6}
    (worker,) = {pid for pid, _ in limited.results.values()}
    assert worker != os.getpid() and {pid for pid, _ in inline.results.values()} == {os.getpid()}


# local workers: in make test-slow, for the suite's time (collect's hung-worker test below runs the same
# local kill, retry and naming through the CLI in make test)
@pytest.mark.parametrize("executor", [pytest.param("local", marks=pytest.mark.slow), "ray"])
def test_a_hung_worker_is_killed_retried_then_named(executor, request, monkeypatch):
    """A job whose worker stops (SIGSTOP) on every attempt: after the time limit its process is killed
    (Ray: its task cancelled), the job is tried once more in a fresh worker, then named with a one-line
    reason; the other jobs finish and the run ends in bounded time."""
    if executor == "ray":
        request.getfixturevalue("ray_cluster")
        # Ray starts its worker processes on first use: started before the clock, so that on a busy
        # machine (the suite's other process beside this one) a start-up is not counted as a hang
        warm = run_jobs(double, [Job(f"warm/{i}", i) for i in (1, 2)], executor="ray", workers=2)
        assert warm.results == {"warm/1": 2, "warm/2": 4}, warm.failed
    kind, workers = executor, 2
    monkeypatch.setattr(irlsim.executor, "KILL_GRACE_S", KILL_GRACE_S)
    me = os.getpid()
    retried: list[str] = []
    t0 = time.monotonic()
    out = run_jobs(
        stops_itself,
        [Job("hung/7", (me, 7)), *(Job(f"ok/{i}", (me, i)) for i in (1, 2, 3))],
        executor=kind,
        workers=workers,
        timeout=HANG_TIMEOUT,
        on_retry=lambda job, reason: retried.append(job.key),
    )
    elapsed = time.monotonic() - t0
    assert out.results == {"ok/1": 2, "ok/2": 4, "ok/3": 6}, out.failed
    assert list(out.failed) == ["hung/7"] and "hung/7" in retried  # an ok job may be retried when slow
    reasons = [out.retried["hung/7"], out.failed["hung/7"]]
    assert all(r.startswith("no result within 5 s: ") for r in reasons), reasons
    # two attempts of the limit, each with its kill (SIGTERM's grace, or Ray's kill of a stopped worker)
    per_attempt = HANG_TIMEOUT + (KILL_GRACE_S if kind == "local" else 10)
    assert elapsed < 2 * per_attempt + 30, elapsed
    assert RAY_CANCEL_WAIT_S >= 10  # Ray kills a stopped worker a few seconds after its cancel
    if kind == "local":
        pids = [int(m[1]) for r in reasons if (m := re.search(r"worker process (\d+) killed$", r))]
        assert len(pids) == 2 and pids[0] != pids[1]  # the retry ran in a fresh worker
        assert not [p for p in pids if Path(f"/proc/{p}").exists()], "a hung worker is still there"


# ------------------------------------------------------------------------------- collect, same bytes


def _live_children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(stat.parent.name))
    return out


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def test_local_workers_killed_worker_is_retried_to_the_same_bytes(tiny_dataset, tmp_path):
    """Two spawned workers; one is SIGKILLed in the middle of an episode: the episode is collected again
    by a fresh worker, the command ends 0 (no hang) and every file is the bytes of one in-process worker."""
    out = tmp_path / "killed"
    proc = subprocess.Popen(
        [sys.executable, "-m", "irlsim.cli", *_collect_args(out)],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        deadline = time.time() + 120
        while time.time() < deadline and not list(out.glob("*/*.cycles.parquet")):
            time.sleep(0.02)
        workers = [p for p in _live_children(proc.pid) if "spawn_main" in _cmdline(p)]
        assert workers and proc.poll() is None, "collect ended before a worker could be killed"
        os.kill(workers[0], signal.SIGKILL)
        _, err = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err[-2000:]
    assert "died (SIGKILL)): trying it once more" in err
    assert _sha256(out) == _sha256(tiny_dataset)
    assert not list(out.rglob(".*.tmp"))
    assert json.loads((out / "manifest.json").read_text())["complete"] is True


def _stop_a_worker_and_its_retry(pid: int, stopped: list[int], done: threading.Event) -> None:
    """SIGSTOP one of the two spawn workers of ``pid`` once both are up, then the first worker started
    after that: the replacement of the stopped one once the time limit killed it, which takes its episode
    first (the retry). Both attempts of one episode hang; every other episode runs."""
    first: set[int] = set()
    while not done.is_set() and len(stopped) < 2:
        workers = [p for p in _live_children(pid) if "spawn_main" in _cmdline(p)]
        new = [p for p in workers if p not in first]
        if (len(workers) >= 2 and not stopped) or (stopped and new):
            os.kill(new[0], signal.SIGSTOP)
            stopped.append(new[0])
            first.update(workers)
        time.sleep(0.005)


def _run_with_hung_episode(argv: list[str]) -> tuple[subprocess.CompletedProcess, list[int]]:
    """Run ``irlsim ARGV`` (two local workers) while one episode's worker and its retry's are stopped."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "irlsim.cli", *argv],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    stopped: list[int] = []
    done = threading.Event()
    watcher = threading.Thread(target=_stop_a_worker_and_its_retry, args=(proc.pid, stopped, done))
    watcher.start()
    try:
        out, err = proc.communicate(timeout=180)  # 2 x (10 s + 2 s) and the start-ups: never a hang
    finally:
        done.set()
        watcher.join()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            for pid in stopped:
                os.kill(pid, signal.SIGKILL)
    assert len(stopped) == 2, f"stopped {stopped}; stderr: {err[-2000:]}"
    assert not [p for p in stopped if Path(f"/proc/{p}").exists()], "a stopped worker was left behind"
    return subprocess.CompletedProcess(argv, proc.returncode, out, err), stopped


def test_a_hung_worker_is_killed_retried_then_named_and_recollected(tiny_dataset, tmp_path):
    """Two local workers; one episode's worker is stopped (SIGSTOP: alive, silent), and so is the fresh
    worker of its retry: each is killed after --episode-timeout, the command ends with exit 1 naming that
    episode (manifest "failed"), the other episodes are the bytes of a normal run, and the same command
    then collects the hung one to the bytes of an uninterrupted run."""
    out = tmp_path / "hung"
    argv = _collect_args(out, "--episode-timeout", "10")
    t0 = time.monotonic()
    proc, _ = _run_with_hung_episode(argv)
    elapsed = time.monotonic() - t0
    assert proc.returncode == 1, proc.stderr[-2000:]
    man = json.loads((out / "manifest.json").read_text())
    assert man["complete"] is False and len(man["failed"]) == 1, man
    ((key, reason),) = man["failed"].items()
    assert key in ("train/0", "train/1") and reason.startswith("no result within 10 s: worker process ")
    err = proc.stderr.strip().splitlines()
    assert f"collect: episode {key} failed (no result within 10 s: worker process " in proc.stderr
    assert err[-1].startswith(f"irlsim: error: collect: 1 of 4 episodes failed twice: {key} (no result ")
    assert err[-1].endswith(
        "re-run the same command to collect the failed ones (an episode that is only "
        "slow needs a larger --episode-timeout)"
    )
    assert "at most 10 s per episode" in proc.stdout
    assert elapsed < 120, elapsed
    split, episode = key.split("/")
    hung = {str(p.relative_to(out)) for p in episode_paths(out, split, int(episode))}
    reference = _sha256(tiny_dataset)
    assert _sha256(out) == {k: v for k, v in reference.items() if k not in hung}
    assert not list(out.rglob(".*.tmp"))

    rerun = subprocess.run(
        [sys.executable, "-m", "irlsim.cli", *argv], cwd=ROOT, capture_output=True, text=True, timeout=180
    )
    assert rerun.returncode == 0, rerun.stderr[-2000:]
    assert "4 episodes (3 already done)" in rerun.stdout
    assert _sha256(out) == reference
    man = json.loads((out / "manifest.json").read_text())
    assert man["complete"] is True and "failed" not in man


@pytest.mark.slow  # run_jobs' timeout is tested fast above and through collect's CLI
def test_drive_a_hung_worker_is_killed_retried_then_named(tmp_path):
    """drive with two local workers: the expert episode whose worker and retry's worker are stopped is
    killed after --episode-timeout each time, and the command ends with exit 1 naming it, no drive.json."""
    out = tmp_path / "drive"
    argv = "drive --model expert --episodes 2 --workers 2 --max-cycles 25 --frames 0".split()
    argv += ["--config", "configs/collect/tiny.toml", "--episode-timeout", "10", "--out", str(out)]
    proc, _ = _run_with_hung_episode(argv)
    assert proc.returncode == 1, proc.stderr[-2000:]
    err = proc.stderr.strip().splitlines()
    assert re.match(
        r"irlsim: error: drive: 1 of 2 episodes failed twice: expert/[01] \(no result within "
        r"10 s: worker process \d+ killed\); nothing written to ",
        err[-1],
    ), err
    assert err[-1].endswith("(an episode that is only slow needs a larger --episode-timeout)")
    assert sum("trying it once more" in line for line in err) == 1, err
    assert not (out / "drive.json").exists()


def test_ray_default_starts_a_local_ray_with_the_same_bytes(tiny_dataset, tmp_path):
    """The CLI as a user runs it: --executor ray without --address starts (and stops) its own local Ray."""
    out = tmp_path / "ray"
    proc = subprocess.run(
        [sys.executable, "-m", "irlsim.cli", *_collect_args(out, "--executor", "ray")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "as Ray tasks" in proc.stdout
    assert _sha256(out) == _sha256(tiny_dataset)


def _ray_task_pids(cluster: Any) -> list[int]:
    """Worker processes of ``cluster`` (children of its raylets; not a lingering worker of another test's
    Ray) running a task of the executor (Ray titles them 'ray::_ray_call')."""
    raylets = {
        p.process.pid for node in cluster.list_all_nodes() for p in node.all_processes.get("raylet", [])
    }
    return [
        pid
        for pid in (int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit())
        if _cmdline(pid).startswith("ray::_ray_call") and _parent(pid) in raylets
    ]


def _parent(pid: int) -> int:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return -1


def test_two_node_cluster_same_bytes_and_a_killed_task_is_retried(
    ray_cluster, tiny_dataset, tmp_path, capsys
):
    """Episodes as Ray tasks on two nodes; one task's worker is SIGKILLed mid-episode: retried, and the
    dataset is the bytes of the local pool's."""
    out = tmp_path / "cluster"
    rc: list[int] = []
    runner = threading.Thread(target=lambda: rc.append(main(_collect_args(out, "--executor", "ray"))))
    runner.start()
    try:
        deadline = time.time() + 120
        while time.time() < deadline and not (pids := _ray_task_pids(ray_cluster)):
            time.sleep(0.05)
        assert pids, "no Ray task seen running"
        os.kill(pids[0], signal.SIGKILL)
    finally:
        runner.join(timeout=300)
    assert rc == [0], capsys.readouterr().err[-2000:]
    assert "Ray worker process died): trying it once more" in capsys.readouterr().err
    assert _sha256(out) == _sha256(tiny_dataset)


@pytest.mark.parametrize("first", ["ray", "local"])
def test_failing_episode_is_named_then_recollected_by_the_same_command(
    first, ray_cluster, tiny_dataset, tmp_path, capsys
):
    """The test split's folder is a file, so its episode fails (a real OSError) on every attempt: the
    other episodes finish, the command exits 1 with one line naming it, the manifest records it; once
    the folder can be written, the same command (with the other executor) collects just that episode."""
    out = tmp_path / "failing"
    out.mkdir()
    (out / "test").write_text("not a folder")
    other = "local" if first == "ray" else "ray"
    capsys.readouterr()
    assert main(_collect_args(out, "--executor", first)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert any("test/0 failed (" in line and "trying it once more" in line for line in err), err
    assert err[-1].startswith("irlsim: error: collect: 1 of 4 episodes failed twice: test/0 (")
    assert "re-run the same command" in err[-1]
    man = json.loads((out / "manifest.json").read_text())
    assert man["complete"] is False and list(man["failed"]) == ["test/0"]
    assert man["splits"] == {"train": [0, 1], "validation": [0], "test": []}

    (out / "test").unlink()
    assert main(_collect_args(out, "--executor", other)) == 0
    assert "4 episodes (3 already done)" in capsys.readouterr().out
    assert _sha256(out) == _sha256(tiny_dataset)
    man = json.loads((out / "manifest.json").read_text())
    assert man["complete"] is True and "failed" not in man


# ------------------------------------------------------------------------------------------------ drive


def _drive_json(out: Path) -> dict[str, Any]:
    """drive.json without the wall-clock figures (inference and planning times, wall time, steps/s)."""

    def strip(d: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in d.items() if not any(t in k for t in ("_ms", "wall_s", "_per_s"))}

    doc = json.loads((out / "drive.json").read_text())
    return {
        **doc,
        "summary": [strip(s) for s in doc["summary"]],
        "episodes": [strip(e) for e in doc["episodes"]],
    }


@pytest.mark.parametrize(
    "other",
    ["two", pytest.param("ray", marks=pytest.mark.slow)],  # Ray's bytes: collect's tests above, fast
)
def test_drive_same_json_for_workers_and_executors(request, tiny_runs, tmp_path, other):  # noqa: F811
    """drive.json is the same for one worker, two local workers and two Ray workers (but its clocks)."""
    if other == "ray":
        request.getfixturevalue("ray_cluster")
    base = ["drive", "--runs", str(tiny_runs), "--model", "expert,PACNN+S", "--episodes", "2"]
    base += ["--max-cycles", "25", "--frames", "0", "--config", "configs/collect/tiny.toml"]
    extra = {"two": ["--workers", "2"], "ray": ["--workers", "2", "--executor", "ray"]}[other]
    results = {}
    for name, more in {"one": [], other: extra}.items():
        assert main([*base, "--out", str(tmp_path / name), *more]) == 0
        results[name] = _drive_json(tmp_path / name)
    assert [e["drive/seed"] for e in results["one"]["episodes"]] == [100, 101, 100, 101]
    assert results["one"]["episodes"][0]["drive/cycles"] == 25
    assert results[other] == results["one"]


def test_failures_with_one_reason_are_named_together_in_the_order_they_failed():
    same = "IrlsimError: SUMO stopped the episode: function call not allowed for rail model"
    died = "worker process 12 died (SIGKILL)"
    failed = {"train/0": same, "train/3": died, "validation/0": same, "test/0": same}
    assert describe_failures(failed) == (f"train/0, validation/0 and test/0 ({same}), train/3 ({died})")
    assert describe_failures({"a/1": "x"}) == "a/1 (x)"
    many = {f"train/{i}": f"reason {i % 2}" for i in range(7)}
    assert describe_failures(many, limit=3) == "train/0 and train/2 (reason 0), train/1 (reason 1) and 4 more"
