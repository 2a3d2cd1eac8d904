"""Values checked at the edge: a non-finite theta or a malformed action in the Gymnasium environment, a
network too large for the memory, too many threads and an empty split are one line before any work
(nothing written). Real SUMO for the environment, real Parquet and the real CLI for training."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim import N_FEATURES
from irlsim.cli import main
from irlsim.errors import IrlsimError
from tests.conftest import TINY_COLLECT, one_line

gym = pytest.importorskip("gymnasium")

import irlsim.envs  # noqa: E402,F401
from irlsim.train.preflight import check_split_sizes  # noqa: E402

TINY_ENV = {"planner.n_policies": 120, "scenario.n_vehicles": 2}


def _env(env_id: str = "irlsim/Planning-v0", **kw):
    return gym.make(env_id, overrides=TINY_ENV, max_cycles=6, **kw)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_theta_is_one_line_not_the_maximal_reward(bad):
    def reward(ps, obs):
        theta = np.ones(N_FEATURES)
        theta[3] = bad
        return theta

    env = _env(reward=reward)
    try:
        with pytest.raises(IrlsimError) as e:
            env.reset(seed=3)
        assert "non-finite theta" in one_line(e) and "jerk_lat" in str(e.value)
    finally:
        env.close()


def test_actions_are_checked_not_truncated():
    env = _env()
    try:
        env.reset(seed=3)
        for bad in (1.7, np.nan, "3", np.array([1, 2]), True):
            with pytest.raises(IrlsimError) as e:
                env.step(bad)
            assert "not a policy index" in one_line(e)
        env.step(np.int64(5))  # an integer of any kind is a policy index
        env.step(np.array(4))
    finally:
        env.close()
    cont = _env("irlsim/PlanningContinuous-v0")
    try:
        cont.reset(seed=3)
        for bad in ([np.nan, 0.0], [0.0, np.inf], [0.0], [[0.0, 0.0]], [0.0, 0.0, 0.0], "ab"):
            with pytest.raises(IrlsimError) as e:
                cont.step(bad)
            assert "not two finite numbers" in one_line(e)
        cont.step(np.array([0.0, 0.0], np.float32))
    finally:
        cont.close()


def _train(tmp_path, data, *sets: str) -> int:
    args = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(data)]
    for s in ('models=["LIRL","PACNN+S"]', *sets):
        args += ["--set", s]
    return main([*args, "--out", str(tmp_path / "runs")])


@pytest.mark.parametrize(
    "setting, needle",
    [
        ("model.hidden_channels=100000000", "training PACNN+S ([model] hidden_channels=100000000 makes it"),
        # the field that makes it large is named, not the first of the sizes
        ("model.head_hidden=300000000", "[model] head_hidden=300000000 makes it this large"),
        ("threads=100000", "threads must be in 1..1024"),
    ],
)
def test_sizes_beyond_the_machine_are_one_line_before_any_work(
    tiny_dataset, tmp_path, capsys, setting, needle
):
    assert _train(tmp_path, tiny_dataset, setting) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not (tmp_path / "runs").exists()


def test_the_memory_estimate_counts_no_more_cycles_than_a_split_has(tiny_dataset, tmp_path, capsys):
    """batch_size far beyond the data: the estimate uses the largest split's cycles (a batch never holds
    more), so training runs instead of being refused for memory it would never take."""
    from irlsim.train.preflight import largest_split_cycles

    counts = {"counts": {"train": {"cycles": 240}, "validation": {"cycles": 60}, "test": {}}}
    assert largest_split_cycles(counts) == 240 and largest_split_cycles({}) == 0
    assert _train(tmp_path, tiny_dataset, "batch_size=100000000", "eval_batch=100000000") == 0, (
        capsys.readouterr().err
    )


@pytest.fixture(scope="module")
def no_validation(tmp_path_factory):
    """A real tiny collection without validation episodes (a DAgger round's data on its own)."""
    out = tmp_path_factory.mktemp("data") / "no_val"
    sets = ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]
    assert (
        main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT, *sets])
        == 0
    )
    return out


def test_an_empty_validation_split_is_named_before_any_work(no_validation, tmp_path, capsys):
    assert _train(tmp_path, no_validation) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has an empty validation split" in err[0] and "--data" in err[0], err
    assert not (tmp_path / "runs").exists()


def test_the_split_check_works_on_counts_before_collecting():
    check_split_sizes({"train": 3, "validation": 1}, "round 1")
    for counts, split in (({"train": 3, "validation": 0}, "validation"), ({"validation": 2}, "train")):
        with pytest.raises(IrlsimError) as e:
            check_split_sizes(counts, "DAgger round 2 (planned)")
        assert f"DAgger round 2 (planned) has an empty {split} split" in one_line(e)
