"""irlsim.reward: load_reward / LearnedReward on tiny trained checkpoints and real planner policy sets."""

from __future__ import annotations

import os
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from irlsim.errors import IrlsimError
from irlsim.planner.choice import expected_choice
from irlsim.planner.expert import THETA_EXPERT, ThetaDriver
from irlsim.planner.planner import Planner
from irlsim.reward import LearnedReward, RewardDriver, load_reward
from tests.drive.conftest import TINY_POLICIES, tiny_config
from tests.planner.conftest import make_obs

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def policy_sets(road):
    """Two real policy sets of the 200-policy planner: cruising in lane 1, and slow in lane 0."""
    planner = Planner(road, tiny_config().planner)
    a = planner.plan(make_obs(road, 100.0, 0.0, 15.0))
    b = planner.plan(make_obs(road, 400.0, -3.2, 6.0))
    assert a.n_policies == b.n_policies == TINY_POLICIES
    return a, b


def test_values_and_choice_follow_theta(tiny_runs, policy_sets):
    reward = load_reward("PACNN+S", runs=tiny_runs, n_policies=TINY_POLICIES)
    assert isinstance(reward, LearnedReward) and reward.name == "PACNN+S" and not reward.is_expert
    ps, _ = policy_sets
    reward.reset()
    theta = reward.theta(ps)
    assert theta.shape == (15,) and theta.dtype == np.float64 and (theta >= 0).all()
    values = reward.values(ps)
    assert values.shape == (TINY_POLICIES,)
    np.testing.assert_allclose(values, -(ps.features.astype(np.float64) @ theta))
    assert reward.choose(ps) == int(np.argmax(values))
    assert reward.info["attention"].shape == (TINY_POLICIES,)
    # safety: the choice never falls on a labelled policy while an unlabelled one exists
    bad = ps.labels.any(axis=1)
    expected = int(np.argmax(values if bad.all() else np.where(bad, -np.inf, values)))
    assert reward.choose(ps, safety=True) == expected
    # the expected choice (irlsim.planner.choice) on the same values, behind the same filter
    assert reward.choose(ps, choice="expected", lane_change_bias=2.0) == expected_choice(
        values, ps.control_points, 2.0
    )
    allowed = None if bad.all() else ~bad
    k = reward.choose(ps, safety=True, choice="expected")
    assert k == expected_choice(values, ps.control_points, 1.0, allowed) and (allowed is None or allowed[k])
    # a braking mask (irlsim drive --full-stop) keeps the choice within it: the best of the rest
    best = int(np.argmax(values))
    mask = np.ones(TINY_POLICIES, dtype=bool)
    mask[best] = False
    assert reward.choose(ps, braking=mask) == int(np.argmax(np.where(mask, values, -np.inf)))


def test_a_checkpoint_path_is_the_same_model(tiny_runs, policy_sets):
    ps, _ = policy_sets
    by_name = load_reward("PACNN+S", runs=tiny_runs)
    by_path = load_reward(tiny_runs / "PACNN+S" / "checkpoint.pt")
    assert by_path.checkpoint == tiny_runs / "PACNN+S" / "checkpoint.pt"
    np.testing.assert_array_equal(by_name.theta(ps), by_path.theta(ps))
    assert by_path.trained is not None and by_path.trained["n_policies"] == TINY_POLICIES


def test_temporal_history_advances_once_per_set_and_resets(tiny_runs, policy_sets):
    a, b = policy_sets
    reward = load_reward("PTACNN+S", runs=tiny_runs, n_policies=TINY_POLICIES)
    reward.reset()
    reward.theta(a)
    after_a = reward.theta(b)
    # values / choose / theta again on the same set reuse the cycle's prediction: no history step
    np.testing.assert_array_equal(reward.theta(b), after_a)
    np.testing.assert_allclose(reward.values(b), b.value(after_a))
    assert reward.info["temporal_weights"].shape == (4,)
    reward.reset()
    fresh_b = reward.theta(b)  # history padded with b alone: another theta than after a
    assert not np.allclose(fresh_b, after_a)
    reward.reset()
    reward.theta(a)
    np.testing.assert_array_equal(reward.theta(b), after_a)  # reset: the same episode, the same thetas
    # predict() on a stored cycle's arrays is a cycle too: the same set afterwards is predicted anew
    reward.predict(a.features, a.control_points, a.actions)
    assert not np.array_equal(reward.theta(b), after_a)


def test_expert_and_expert_theta(policy_sets):
    ps, _ = policy_sets
    et = load_reward("expert-theta")
    np.testing.assert_array_equal(et.theta(ps), THETA_EXPERT)
    assert et.choose(ps) == int(np.argmax(ps.value(THETA_EXPERT))) and et.checkpoint is None
    expert = load_reward("expert")
    assert expert.is_expert
    np.testing.assert_array_equal(expert.values(ps), ps.value(THETA_EXPERT))
    with pytest.raises(IrlsimError, match="expert-theta"):
        expert.choose(ps)


def test_unknown_or_missing_models_are_one_line(tiny_runs, tmp_path):
    with pytest.raises(IrlsimError, match="unknown model 'nope'"):
        load_reward("nope")
    with pytest.raises(IrlsimError, match="needs --runs"):
        load_reward("PACNN+S")
    with pytest.raises(IrlsimError, match="trained on 200 policies per cycle"):
        load_reward("LIRL", runs=tiny_runs, n_policies=50)


def test_reward_driver_executes_the_rewards_choice(road, tiny_runs):
    """RewardDriver (drive, DAgger) picks what LearnedReward.choose picks on the same set."""
    cfg = tiny_config()
    reward = load_reward("PACNN+S", runs=tiny_runs, n_policies=TINY_POLICIES)
    driver = RewardDriver(reward, road, cfg.planner)
    assert isinstance(driver.driver, ThetaDriver)
    driver.reset()
    driver.plan(make_obs(road, 100.0, 0.0, 15.0))
    ps = driver.last_policy_set
    assert ps is not None and driver.last_index == reward.choose(ps)
    np.testing.assert_array_equal(driver.theta, reward.theta(ps))
    assert driver.inference_ms > 0.0 and driver.info is reward.info


def _quickstart_printed(stdout: str, model: str) -> None:
    lines = stdout.splitlines()
    assert lines[0].startswith(f"{model}: {TINY_POLICIES} policies")
    assert lines[1].startswith("theta: acc_lon ") and lines[1].count(",") == 14
    chosen = int(lines[3].split("#")[1].split()[0])
    assert lines[2].startswith(f"best values: #{chosen} ")  # the choice is the highest value


def test_quickstart_example_runs_on_a_tiny_model(tiny_runs, monkeypatch, capsys):
    """examples/reward_quickstart.py (shown in the README) on a real SUMO cycle, nothing trained: with its
    default model (PACNN+S) in a fresh interpreter, as a user runs it, and with a temporal model run as
    __main__ in this process (an interpreter's start-up was most of a second subprocess)."""
    example = str(ROOT / "examples" / "reward_quickstart.py")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, example, str(tiny_runs)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    _quickstart_printed(out.stdout, "PACNN+S")
    monkeypatch.chdir(ROOT)
    monkeypatch.setattr(sys, "argv", [example, str(tiny_runs), "--model", "PTACNN+S"])
    runpy.run_path(example, run_name="__main__")
    _quickstart_printed(capsys.readouterr().out, "PTACNN+S")
