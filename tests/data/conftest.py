"""Fixtures of the data tests: synthetic episodes (numpy-built PolicySets and a straight-driving ego), and
a second real tiny collection to aggregate with the expert's tiny dataset."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from irlsim import N_FEATURES
from irlsim.data.demos import DemoProjector
from irlsim.data.layout import write_manifest
from irlsim.data.writer import EpisodeWriter
from irlsim.planner.policy_set import PolicySet
from irlsim.road import load_road
from irlsim.road.network import sumo_binary

DT = 0.1  # [s]
T = 51  # states over 5 s
K = 10  # control points
V_EGO = 20.0  # [m/s]
LAP = 1000.0  # [m]
PLAN_EVERY = 2  # simulation steps per planning cycle


def make_policy_set(
    rng: np.random.Generator, n: int, t: float, s0: float, *, match: bool = True
) -> PolicySet:
    """N constant-speed, constant-offset policies from arc length s0 [m]; one matches the ego (20 m/s,
    d = 0) when ``match``. Sorted by progress ascending."""
    speeds = rng.uniform(10.0, 30.0, n)
    offsets = rng.uniform(-4.0, 4.0, n)
    if match:
        speeds[rng.integers(n)] = V_EGO
        offsets[np.argmin(np.abs(speeds - V_EGO))] = 0.0
    order = np.argsort(speeds * 5.0, kind="stable")
    speeds, offsets = speeds[order], offsets[order]
    tau = np.arange(T) * DT
    s = s0 + speeds[:, None] * tau[None, :]
    d = np.broadcast_to(offsets[:, None], (n, T)).copy()
    yaw = np.zeros((n, T))
    return PolicySet(
        t=t,
        x=s.copy(),
        y=d.copy(),
        yaw=yaw,
        v=np.broadcast_to(speeds[:, None], (n, T)).copy(),
        s=s,
        d=d,
        lane=np.ones((n, T), dtype=np.int8),
        progress=(speeds * 5.0).astype(np.float32),
        features=rng.random((n, N_FEATURES), dtype=np.float32) * 10,
        control_points=rng.normal(size=(n, K, 3)).astype(np.float32),
        actions=rng.normal(size=(n, K, 2)).astype(np.float32),
        labels=rng.random((n, 3)) < 0.2,
    )


def write_episode(
    dataset: Path,
    split: str,
    episode: int,
    *,
    n_policies: int = 24,
    n_steps: int = 120,
    seed: int = 0,
    cycles_per_row_group: int = 8,
) -> None:
    """Drive the ego straight at 20 m/s for n_steps, plan every PLAN_EVERY steps, write the episode."""
    rng = np.random.default_rng(seed)
    proj = DemoProjector(lap_length=LAP, horizon=5.0, dt=DT)
    with EpisodeWriter(dataset, split, episode, cycles_per_row_group=cycles_per_row_group) as writer:
        for step in range(n_steps):
            t = step * DT
            s = 100.0 + V_EGO * t
            proj.push_odometry(t, s, 0.0, 0.0)
            if step % PLAN_EVERY == 0:
                k = step // PLAN_EVERY
                ps = make_policy_set(rng, n_policies, t, s)
                proj.push_cycle(k, ps.t, ps.s, ps.d, ps.yaw)
                ego = {"x": s, "y": 0.0, "yaw": 0.0, "v": V_EGO, "s": s, "d": 0.0, "lane": 1}
                writer.add_cycle(
                    k, ps, ego, executed_index=int(rng.integers(n_policies)), target_checkpoint=2
                )
            writer.add_demos(proj.pop_ready())
        writer.add_demos(proj.finish())


def make_dataset(root: Path, splits: dict[str, list[int]] | None = None, **kwargs: object) -> Path:
    splits = splits or {"train": [0, 1], "validation": [2]}
    for split, eps in splits.items():
        for ep in eps:
            write_episode(root, split, ep, seed=ep, **kwargs)  # type: ignore[arg-type]
    write_manifest(root, {"config": {"n_policies": 24}, "seeds": {"collect": 0}, "splits": splits})
    return root


@pytest.fixture()
def dataset(tmp_path: Path) -> Path:
    return make_dataset(tmp_path / "ds")


@pytest.fixture()
def pair(tiny_dataset: Path, second_tiny: Path, tmp_path: Path) -> tuple[Path, Path]:
    """Fresh copies of both folders (no caches), so a test may change them."""
    ignore = shutil.ignore_patterns(".cache", ".lock")
    a, b = tmp_path / "expert", tmp_path / "round"
    shutil.copytree(tiny_dataset, a, ignore=ignore)
    shutil.copytree(second_tiny, b, ignore=ignore)
    return a, b


#: SUMO's step of the recording fixture: resampled to irlsim's 0.1 s
RECORDING_STEP = 0.5


@pytest.fixture(scope="module")
def fcd(tmp_path_factory) -> Path:
    """Five vehicles on the oval for 60 s, recorded by SUMO itself (--fcd-output)."""
    tmp = tmp_path_factory.mktemp("recording")
    road = load_road()
    cars = "".join(
        f'<vehicle id="veh{i}" type="car" route="loop" depart="{2 * i}" departLane="{i % 3}" '
        f'departPos="{30 * i}" departSpeed="max"/>'
        for i in range(5)
    )
    routes = tmp / "cars.rou.xml"
    routes.write_text(
        f'<routes><vType id="car" sigma="0" maxSpeed="{12 + 0.5}" lcStrategic="0" lcSpeedGain="0" '
        f'lcKeepRight="0"/><route id="loop" edges="{" ".join(road.edges * 2)}"/>{cars}</routes>'
    )
    return record_fcd(routes, tmp / "fcd.xml")


def record_fcd(routes: Path, out: Path, *options: str) -> Path:
    """SUMO alone (the wheel's binary) drives ``routes`` on the oval for 60 s at ``RECORDING_STEP``, seed
    1, its FCD output at ``out`` (SUMO gzips it when the name ends in .gz), with ``options`` added."""
    road = load_road()
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(routes), "--end", "60"]
    cmd += ["--step-length", str(RECORDING_STEP), "--fcd-output", str(out), "--no-step-log", "true"]
    cmd += ["--seed", "1", *options]
    subprocess.run(cmd, check=True, capture_output=True)
    return out
