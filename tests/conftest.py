"""Shared fixtures: the oval's Road (built once per session) and a headless libsumo Simulation.

libsumo holds one simulation per process: tests share the session ``sim`` (``reset(seed)`` reloads it in
a few ms); a test that makes its own Simulation closes the shared one, which restarts on its next reset.
"""

from __future__ import annotations

import os

import pytest

#: numpy's BLAS on one thread in the test processes, as the irlsim command runs it
#: (pipelines.commands.BLAS_THREADS: its own setdefault comes too late in a process that has imported
#: numpy, as a test process has). The suite runs in two processes on two cores: BLAS threads of both
#: waiting on descheduled siblings made the planner's products about 4 times as slow on a busy machine.
#: Read when numpy loads, which no test process has done before this file (the first it imports).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
#: torch's OpenMP threads (evaluate's --threads 2) sleep when idle instead of spinning for the CPU the other
#: test process needs (no effect on any result; read when torch loads): on the loaded host an evaluation
#: of the tiny demo's data beside one busy process took 12.5-17.0 s spinning, 3.7-5.7 s passive
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip @pytest.mark.slow tests unless selected with -m (``make test-slow`` / ``pytest -m slow``)."""
    if "slow" in (config.option.markexpr or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with 'pytest -m slow' or 'make test-slow'")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def road():
    from irlsim.road import load_road

    return load_road()


@pytest.fixture(scope="session")
def sim(road):
    from irlsim.sim.config import EpisodeConfig
    from irlsim.sim.simulation import Simulation

    s = Simulation(road, EpisodeConfig(laps=10, max_time=2000.0))
    yield s
    s.close()


#: a tiny collection config shared by the collect, chain and drive tests (real SUMO, real Parquet)
TINY_COLLECT = [
    "--set",
    "train_episodes=2",
    "--set",
    "validation_episodes=1",
    "--set",
    "test_episodes=1",
    "--set",
    "max_cycles=40",
    "--set",
    "planner.n_policies=120",
    "--set",
    "scenario.n_vehicles=4",
    "--set",
    "workers=1",
]


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """A real dataset collected by the expert in SUMO: 2 train, 1 validation, 1 test episode of 40 cycles."""
    from irlsim.cli import main

    out = tmp_path_factory.mktemp("data") / "tiny"
    assert main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT]) == 0
    return out


@pytest.fixture(scope="session")
def second_tiny(tmp_path_factory):
    """A second real tiny collection: seed 1 (other episode seeds), one train and one validation episode,
    no test split (a DAgger round's folder, a second dataset to aggregate)."""
    from irlsim.cli import main

    out = tmp_path_factory.mktemp("data") / "tiny_seed1"
    sets = ["--set", "seed=1", "--set", "train_episodes=1", "--set", "test_episodes=0"]
    assert (
        main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT, *sets])
        == 0
    )
    return out


MULTI_TOML = """
seed = 0
workers = 1
max_cycles = 40

[scenario]
n_vehicles = 4
laps = 1
max_time = 120.0

[planner]
n_policies = 120

[[scenarios]]
name = "oval"
train_episodes = 1
test_episodes = 1

[[scenarios]]
name = "ramp"
train_episodes = 1
validation_episodes = 1
test_episodes = 1
"""


@pytest.fixture(scope="session")
def multi(tmp_path_factory):
    """(config path, dataset folder) of a real two-scenario collection (collect config ``[[scenarios]]``):
    oval 1 train + 1 test episode, ramp 1 train, 1 validation, 1 test episode, 40 cycles each."""
    from irlsim.cli import main

    root = tmp_path_factory.mktemp("multi")
    cfg = root / "multi.toml"
    cfg.write_text(MULTI_TOML)
    out = root / "data"
    assert main(["collect", "--config", str(cfg), "--out", str(out)]) == 0
    return cfg, out


@pytest.fixture(scope="session")
def ramp_runs(multi, tmp_path_factory):
    """LIRL and PACNN trained (tiny, real) on the ramp episodes of the two-scenario dataset only."""
    from irlsim.cli import main

    _, data = multi
    runs = tmp_path_factory.mktemp("ramp_runs")
    args = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(data)]
    args += ["--out", str(runs), "--set", "models=['LIRL','PACNN']", "--set", "epochs=1"]
    assert main([*args, "--scenario-select", "ramp"]) == 0
    return runs


def train_synthetic_runs(dataset, runs):
    """The layout 'irlsim train --out RUNS' writes, from an in-memory dataset: RUNS/stage1/{LIRL,PACNN}/
    and RUNS/stage2/PTACNN/, one epoch each (smoke configs)."""
    import dataclasses

    from irlsim.train import Stage1Config, Stage2Config, train_stage1, train_stage2
    from irlsim.train.layout import stage_dir

    cfg1 = dataclasses.replace(Stage1Config.smoke(), models=("LIRL", "PACNN"), epochs=1)
    train_stage1(dataset, cfg1, stage_dir(runs, 1))
    cfg2 = dataclasses.replace(Stage2Config.smoke(), models=("PTACNN",), epochs=1)
    train_stage2(dataset, cfg2, stage_dir(runs, 2), stage_dir(runs, 1))
    return runs


def one_line(e) -> str:
    """The message of a raised IrlsimError (pytest.ExceptionInfo), asserted to be one non-empty line."""
    msg = str(e.value)
    assert msg and "\n" not in msg
    return msg


def refused(capsys, argv: list[str]) -> str:
    """The one line an ``irlsim`` command (``argv``) refused with: exit status 2, one line on stderr."""
    from irlsim.cli import main

    capsys.readouterr()
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    return err[0]
