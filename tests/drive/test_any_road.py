"""A reward trained on one scenario drives any scenario: ``irlsim drive --scenario X --model`` and the
Gymnasium environment's ``scenario=`` with a learned reward, on a model trained (tiny, real) on the ramp
episodes of a two-scenario dataset (tests/conftest.py ``ramp_runs``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

#: the collect config the ramp models were trained with (120 policies), with 3 background vehicles
DRIVE_TOML = """
[scenario]
n_vehicles = 3

[planner]
n_policies = 120
"""


@pytest.mark.parametrize("road", ["motorway", "oval"])
def test_drive_a_reward_trained_on_the_ramp_on_another_road(multi, ramp_runs, road, tmp_path, capsys):
    """On the motorway with the two-scenario collect config itself (--scenario picks one road of it)."""
    from irlsim.cli import main
    from irlsim.train.layout import find_checkpoint

    cfg = tmp_path / "drive.toml"
    cfg.write_text(DRIVE_TOML)
    if road == "motorway":
        cfg = multi[0]
    ckpt = find_checkpoint(ramp_runs, "PACNN")
    out = tmp_path / "drive"
    args = ["drive", "--runs", str(ramp_runs), "--model", f"LIRL,{ckpt}", "--scenario", road]
    args += ["--config", str(cfg), "--episodes", "1", "--laps", "1", "--seed", "7", "--max-cycles", "12"]
    assert main([*args, "--frames", "2", "--out", str(out)]) == 0
    doc = json.loads((out / "drive.json").read_text())
    assert [s["drive/model"] for s in doc["summary"]] == ["LIRL", str(ckpt)]
    for ep in doc["episodes"]:
        assert ep["drive/cycles"] >= 1 and ep["drive/seed"] == 7
    assert doc["config"].get("scenario", "oval") == road


def test_environment_takes_a_scenario_and_a_learned_reward(ramp_runs):
    import gymnasium as gym

    import irlsim.envs  # noqa: F401  (registers irlsim/Planning-v0)

    overrides = {"planner.n_policies": 120, "scenario.n_vehicles": 3}
    env = gym.make(
        "irlsim/Planning-v0",
        reward="PACNN",
        runs=ramp_runs,
        scenario="motorway",
        overrides=overrides,
        max_cycles=6,
    )
    try:
        obs, _ = env.reset(seed=3)
        base = env.unwrapped
        assert base.reward_name == "PACNN" and base.scenario.name == "motorway"
        assert obs["features"].shape[0] == 120
        steps, done = 0, False
        while not done:
            obs, r, terminated, truncated, _ = env.step(int(np.argmax(base.values)))
            assert 0.0 <= r <= 1.0
            done, steps = terminated or truncated, steps + 1
        assert 1 <= steps <= 6
    finally:
        env.close()
