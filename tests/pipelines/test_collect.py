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

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.demos import W_YAW
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
        # the executed policy is close to its own odometry: the demonstration is at most as far
        ex = np.asarray(t.executed_index[has])
        assert np.all(d[np.arange(len(d)), ex] >= d.min(axis=1))


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


def test_killed_collect_resumes_to_the_same_bytes(tiny_dataset, tmp_path, capsys):
    """SIGKILL in the middle, re-run: only complete files at any time, the same dataset in the end.

    The uninterrupted reference is the session's tiny dataset (same config, same seeds), so this also
    checks determinism across runs.
    """
    out = tmp_path / "killed"
    cmd = [
        sys.executable,
        "-m",
        "irlsim.cli",
        "collect",
        "--config",
        "configs/collect/tiny.toml",
        "--out",
        str(out),
        *TINY_COLLECT,
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not list(out.glob("train/*.cycles.parquet")):
        time.sleep(0.05)
    time.sleep(0.3)  # now in the middle of the next episode
    proc.send_signal(signal.SIGKILL)
    proc.wait()
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
        ("schema_version", 0, "holds a dataset of schema version 0, this irlsim writes 1"),
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
        (["--seed", "-1"], "--seed must be >= 0"),
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
