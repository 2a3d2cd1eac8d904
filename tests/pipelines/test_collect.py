"""`irlsim collect` end to end with real SUMO and real Parquet: demonstrations, resume after a kill,
determinism, and bad input."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.demos import W_YAW
from irlsim.data.schema import SCHEMA_VERSION
from tests.conftest import TINY_COLLECT

ROOT = Path(__file__).resolve().parents[2]


def _parquet_files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*.parquet"))}


def test_demonstration_is_argmin_and_far_better_than_random(tiny_dataset):
    from irlsim.data.reader import open_dataset

    ds = open_dataset(tiny_dataset)
    for split in ("train", "validation", "test"):
        t = ds.split_tensors(split)
        has = t.demo_index >= 0
        assert has.sum() > 0, split
        d = np.asarray(t.distances[has])
        np.testing.assert_array_equal(np.asarray(t.demo_index[has]), np.argmin(d, axis=1))
        np.testing.assert_allclose(np.asarray(t.demo_distance[has]), d.min(axis=1), rtol=1e-6)
        demo_mean, random_mean = float(d.min(axis=1).mean()), float(d.mean())
        assert demo_mean < 0.25 * random_mean, (split, demo_mean, random_mean)
        # the expert drives its executed policy for the cycle's first steps and re-plans consistently,
        # so that policy is among the closest to the odometry; a wrong or shuffled executed_index (a
        # random policy: rank ~N/2, distance ~random_mean) fails both
        ex = np.asarray(t.executed_index[has])
        d_ex = d[np.arange(len(d)), ex]
        rank = (d < d_ex[:, None]).sum(axis=1)  # policies strictly closer than the executed one
        assert np.median(rank) < 0.25 * d.shape[1], (split, np.median(rank))
        assert d_ex.mean() < 0.5 * random_mean, (split, d_ex.mean(), random_mean)


def test_splits_use_disjoint_seeds_and_keep_cycle_order(tiny_dataset):
    from irlsim.data.reader import open_dataset

    man = json.loads((tiny_dataset / "manifest.json").read_text())
    seeds = [s for split in man["seeds"].values() for s in split]
    assert len(seeds) == len(set(seeds)) == 4
    ds = open_dataset(tiny_dataset)
    for split in ("validation", "test"):
        c = ds.read_cycles(split)
        assert (np.diff(c["cycle"].to_numpy()) == 1).all()
        assert (np.diff(c["t"].to_numpy()) > 0).all()


def _assert_incomplete(out: Path, capsys) -> None:
    """An interrupted collection is not a (small) dataset: the reader and 'data info' refuse it."""
    from irlsim.data.reader import open_dataset
    from irlsim.errors import IrlsimError

    assert json.loads((out / "manifest.json").read_text())["complete"] is False
    with pytest.raises(IrlsimError, match="incomplete"):
        open_dataset(out)
    capsys.readouterr()
    assert main(["data", "info", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"irlsim: error: dataset {out} is incomplete (collection was interrupted): "
        "re-run the same 'irlsim collect' command to finish it"
    ]


def _start_collect(out: Path, *extra: str, stderr: Any = subprocess.DEVNULL) -> subprocess.Popen:
    """'irlsim collect' of the tiny config in a subprocess that leads its own process group (as a shell
    job would), so the test can signal the whole group like a terminal or a job control would."""
    cmd = [sys.executable, "-m", "irlsim.cli", *_tiny(out, *extra)]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    # SIGINT at its default in the child, as in a terminal: a test run started in the background by a
    # non-interactive shell (`cmd &`) inherits SIGINT ignored, and Python keeps an inherited SIG_IGN
    return subprocess.Popen(
        cmd,
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=stderr,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def _wait_for_first_episode(out: Path, proc: subprocess.Popen) -> None:
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None and not list(out.glob("*/*.cycles.parquet")):
        time.sleep(0.02)
    assert proc.poll() is None, "collect ended before its first episode was written"


def _live_group_members(pgid: int) -> list[int]:
    """Pids of the process group that are alive (zombies left to a non-reaping init do not count)."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # gone meanwhile
        if int(fields[2]) == pgid and fields[0] != "Z":
            pids.append(int(stat.parent.name))
    return pids


def _wait_group_gone(pgid: int, timeout: float = 30.0) -> list[int]:
    deadline = time.time() + timeout
    while (alive := _live_group_members(pgid)) and time.time() < deadline:
        time.sleep(0.02)
    return alive


def _kill_group(pgid: int) -> None:
    try:
        os.killpg(pgid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def test_killed_collect_resumes_to_the_same_bytes(tiny_dataset, tmp_path, capsys):
    """SIGKILL in the middle, re-run: only complete files at any time, the same dataset in the end.

    The uninterrupted reference is the session's tiny dataset (same config, same seeds), so this also
    checks determinism across runs.
    """
    out = tmp_path / "killed"
    proc = _start_collect(out)
    try:
        _wait_for_first_episode(out, proc)
        time.sleep(0.3)  # now in the middle of the next episode
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        _kill_group(proc.pid)
    done = list(out.glob("*/*.cycles.parquet"))
    assert 1 <= len(done) < 4, "kill came too late or too early to test resuming"
    for p in out.rglob("*.parquet"):  # every visible Parquet file is complete and readable
        pq.read_table(p)
    _assert_incomplete(out, capsys)
    assert main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT]) == 0
    assert not list(out.rglob("*.tmp"))
    assert _parquet_files(out) == _parquet_files(tiny_dataset)
    m1 = json.loads((out / "manifest.json").read_text())
    m2 = json.loads((tiny_dataset / "manifest.json").read_text())
    assert m1 == m2 and m1["complete"] is True


def test_killed_two_worker_collect_resumes_with_one_worker_to_the_same_bytes(tiny_dataset, tmp_path, capsys):
    """SIGKILL of the whole process group (parent and both workers) after the first episode file, then
    a resume with workers=1: the bytes of the uninterrupted one-worker run, manifest included."""
    out = tmp_path / "killed2"
    proc = _start_collect(out, "--set", "workers=2")
    try:
        _wait_for_first_episode(out, proc)
        assert len(_live_group_members(proc.pid)) >= 3, "expected the parent and two workers"
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        assert _wait_group_gone(proc.pid) == []
    finally:
        _kill_group(proc.pid)
    assert 1 <= len(list(out.glob("*/*.cycles.parquet"))) < 4, "kill came too late to test resuming"
    _assert_incomplete(out, capsys)
    assert main(_tiny(out)) == 0
    assert not list(out.rglob("*.tmp"))
    assert _parquet_files(out) == _parquet_files(tiny_dataset)
    assert (out / "manifest.json").read_bytes() == (tiny_dataset / "manifest.json").read_bytes()


#: two workers and enough episodes (~0.5 s each) that the run is still busy when the test signals it
MANY_EPISODES = ("--set", "workers=2", "--set", "train_episodes=8")
MANY_TOTAL = 10  # with the tiny config's validation and test episode


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux only")
def test_workers_die_with_their_parent(tmp_path):
    """SIGKILL of the parent alone: its workers must not live on to finish their episodes into a
    folder a new run may already have locked."""
    out = tmp_path / "orphans"
    proc = _start_collect(out, *MANY_EPISODES)
    try:
        _wait_for_first_episode(out, proc)
        assert len(_live_group_members(proc.pid)) >= 3, "expected the parent and two workers"
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        finished = sorted(out.glob("*/*.cycles.parquet"))
        assert len(finished) < MANY_TOTAL, "the workers had nothing left to do: the test proves nothing"
        alive = _wait_group_gone(proc.pid)
        assert alive == [], f"workers {alive} outlived their parent"
        assert sorted(out.glob("*/*.cycles.parquet")) == finished  # nothing written after the parent died
    finally:
        _kill_group(proc.pid)


def test_ctrl_c_gives_the_parents_one_line_only(tmp_path):
    """SIGINT to the whole process group, as Ctrl-C in a terminal sends it: the workers ignore it, the
    parent stops them and prints its one line, and no traceback appears. The workers get it a moment
    before the parent, as they may on a busy machine (else the parent often stops them first)."""
    out = tmp_path / "ctrl_c"
    err_path = tmp_path / "stderr.txt"
    with err_path.open("w") as err_file:
        proc = _start_collect(out, *MANY_EPISODES, stderr=err_file)
        try:
            _wait_for_first_episode(out, proc)
            for pid in _live_group_members(proc.pid):
                if pid != proc.pid:
                    os.kill(pid, signal.SIGINT)
            time.sleep(0.3)
            assert len(list(out.glob("*/*.cycles.parquet"))) < MANY_TOTAL, "collect ended before the Ctrl-C"
            os.killpg(proc.pid, signal.SIGINT)
            rc = proc.wait(timeout=60)
            assert _wait_group_gone(proc.pid) == []
        finally:
            _kill_group(proc.pid)
    err = err_path.read_text()
    assert rc == 130, err
    assert "Traceback" not in err and "Error" not in err, err
    said = [line for line in err.splitlines() if line.startswith("irlsim:")]
    assert said == ["irlsim: interrupted; finished files are kept, re-run the command to resume"], err


def test_demo_farther_than_max_distance_is_no_demo(tiny_dataset, tmp_path):
    """demo.max_distance at the median of the tiny run's demonstration distances: the same driving (the
    projection does not steer), so cycles whose closest policy is farther get demo_index -1."""
    from irlsim.data.reader import open_dataset

    ref = open_dataset(tiny_dataset).read_cycles("train")
    ref = ref[(ref["episode"] == 0) & ref["has_demo"]]
    limit = float(np.median(ref["demo_distance"]))
    out = tmp_path / "near"
    assert main(_tiny(out, *ONE_EPISODE, "--set", f"demo.max_distance={limit!r}")) == 0
    cycles = pq.read_table(out / "train" / "episode_00000.cycles.parquet").to_pandas()
    dist = pq.read_table(out / "train" / "episode_00000.policies.parquet", columns=["distance"])
    dist = dist.column("distance").to_numpy().reshape(len(cycles), -1)
    ref_dist = pq.read_table(tiny_dataset / "train" / "episode_00000.policies.parquet", columns=["distance"])
    np.testing.assert_array_equal(dist.reshape(-1), ref_dist.column("distance").to_numpy())
    window = np.isfinite(dist).all(axis=1)  # cycles whose odometry window is complete
    closest = np.where(window, np.nanmin(np.where(window[:, None], dist, 0.0), axis=1), np.nan)
    far = window & (closest > np.float32(limit))
    near = window & ~far
    assert far.sum() > 0 and near.sum() > 0
    demo_index = cycles["demo_index"].to_numpy()
    assert (demo_index[~near] == -1).all() and not cycles["has_demo"].to_numpy()[~near].any()
    assert np.isnan(cycles["demo_distance"].to_numpy()[~near]).all()
    np.testing.assert_array_equal(demo_index[near], np.argmin(dist[near], axis=1))
    np.testing.assert_array_equal(cycles["demo_distance"].to_numpy()[near], closest[near])


@pytest.mark.parametrize(
    "extra, difference",
    [
        (["--set", "max_cycles=41"], "(max_cycles = 40 there, 41 now)"),
        (["--set", "demo.w_yaw=2.5"], f"(demo.w_yaw = {W_YAW!r} there, 2.5 now)"),
    ],
)
def test_rerun_with_another_config_is_refused(tiny_dataset, capsys, extra, difference):
    before = (tiny_dataset / "manifest.json").read_bytes()
    capsys.readouterr()
    assert main(_tiny(tiny_dataset, *extra)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"irlsim: error: {tiny_dataset} was collected with another config {difference}: "
        f"choose another --out or delete {tiny_dataset}"
    ]
    assert (tiny_dataset / "manifest.json").read_bytes() == before


def test_workers_do_not_block_a_resume(tiny_dataset, tmp_path, capsys):
    """workers changes no byte of the data: it is not recorded, and a manifest that still records it
    (written before) resumes with any value."""
    out = _copy_dataset(tiny_dataset, tmp_path / "workers")
    manifest = json.loads((out / "manifest.json").read_text())
    assert "workers" not in manifest["config"]
    manifest["config"]["workers"] = 3
    (out / "manifest.json").write_text(json.dumps(manifest))
    assert main(_tiny(out, "--set", "workers=2")) == 0
    assert "4 episodes (4 already done)" in capsys.readouterr().out
    assert (out / "manifest.json").read_bytes() == (tiny_dataset / "manifest.json").read_bytes()


@pytest.mark.parametrize(
    "key, value, needle",
    [
        ("schema_version", 0, f"holds a dataset of schema version 0, this irlsim writes {SCHEMA_VERSION}"),
        ("feature_names", ["acc_lon"], "holds a dataset of other features than this irlsim computes"),
    ],
)
def test_collect_refuses_a_dataset_of_another_version(tiny_dataset, tmp_path, capsys, key, value, needle):
    out = _copy_dataset(tiny_dataset, tmp_path / "old")
    manifest = json.loads((out / "manifest.json").read_text())
    manifest[key] = value
    (out / "manifest.json").write_text(json.dumps(manifest))
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"}
    capsys.readouterr()
    assert main(_tiny(out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"irlsim: error: {out} {needle}: choose another --out or delete {out}"]
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"} == before


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--set", "workers=0"], "workers must be >= 1"),
        (["--seed", "3000"], "seed must be in 0..2147 (episode seeds are seed * 1,000,000"),
        (["--set", "planner.n_polices=10"], "unknown key 'planner.n_polices'"),
        (["--set", "scenario.n_vehicles=99"], "n_vehicles must be in 0..15"),
        (["--set", "seed.x=1"], "cannot set 'seed.x': 'seed' is a value (0), not a table"),
        (["--set", "seed=3", "--set", "seed.x=1"], "'seed' is a value (3), not a table"),
        (["--set", "scenario=1"], "'scenario' must be a table"),
    ],
)
def test_bad_input_is_one_line(tmp_path, capsys, args, needle):
    out = tmp_path / "bad"
    rc = main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and needle in err[0], err
    assert not out.exists()


def test_broken_config_file(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("seed = [\n")
    rc = main(["collect", "--config", str(bad), "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "not valid TOML" in err[0]


def _tiny(out: Path, *extra: str) -> list[str]:
    return ["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT, *extra]


ONE_EPISODE = ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]


def test_episode_ending_mid_cycle_uses_only_driven_steps(tmp_path):
    """A time-out after 61 steps of 0.1 s ends the episode inside a 2-step cycle: the step never driven
    must not complete any demonstration window, so exactly the cycles with t + 5 s <= the end have one."""
    out = tmp_path / "short"
    args = _tiny(out, *ONE_EPISODE, "--set", "max_cycles=0", "--set", "scenario.max_time=6.1")
    assert main(args) == 0
    stats = json.loads((out / "train" / "episode_00000.stats.json").read_text())
    assert stats["end_reason"] == "timeout" and stats["sim/steps"] == 61
    cycles = pq.read_table(out / "train" / "episode_00000.cycles.parquet")
    t = cycles.column("t").to_numpy().astype(np.float64)
    assert len(t) == 31  # cycles start at steps 0, 2, ..., 60
    complete = t + 5.0 <= t[0] + 6.1 + 1e-3  # the windows the simulated odometry covers
    assert complete.sum() == 6
    has_demo = cycles.column("has_demo").to_numpy(zero_copy_only=False)
    np.testing.assert_array_equal(has_demo, complete)
    dist = pq.read_table(out / "train" / "episode_00000.policies.parquet", columns=["distance"])
    dist = dist.column("distance").to_numpy().reshape(len(t), -1)
    assert np.isnan(dist[~complete]).all() and np.isfinite(dist[complete]).all()


def _copy_dataset(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns(".cache", ".lock"))
    return dst


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _foreign(path: Path) -> None:
    pq.write_table(pa.table({"x": [1, 2, 3]}), path)  # a Parquet file, but not ours


@pytest.mark.parametrize(
    "damage, name",
    [
        (_truncate, "train/episode_00000.policies.parquet"),
        (_truncate, "test/episode_00000.cycles.parquet"),
        (_foreign, "validation/episode_00000.cycles.parquet"),
    ],
)
def test_resume_recollects_a_corrupt_episode(tiny_dataset, tmp_path, capsys, damage, name):
    out = _copy_dataset(tiny_dataset, tmp_path / "damaged")
    damage(out / name)
    capsys.readouterr()
    assert main(_tiny(out)) == 0
    err = capsys.readouterr().err.splitlines()
    said = [line for line in err if line.startswith("collect: ") and str(out / name) in line]
    assert len(said) == 1 and said[0].endswith(f"collecting {name.split('/')[0]} episode 0 again"), err
    assert _parquet_files(out) == _parquet_files(tiny_dataset)
    assert json.loads((out / "manifest.json").read_text()) == json.loads(
        (tiny_dataset / "manifest.json").read_text()
    )


def test_second_collect_is_refused_while_the_lock_is_held(tiny_dataset, tmp_path, capsys):
    """The test process holds <out>/.lock as a running collect would: a collect into the same folder
    is refused with one line naming the holder, and leaves the dataset untouched."""
    out = _copy_dataset(tiny_dataset, tmp_path / "locked")
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.write(fd, b"4242\n")
        before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
        capsys.readouterr()
        assert main(_tiny(out)) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [
            f"irlsim: error: another 'irlsim collect' is writing {out} (pid 4242): wait for it or stop it"
        ]
        assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    finally:
        os.close(fd)
    assert main(_tiny(out)) == 0  # released: the same command now runs (nothing left to do)
    assert _parquet_files(out) == _parquet_files(tiny_dataset)
