"""irlsim/Planning-v0 (and its alias irlsim/Oval-v0): Gymnasium's checker, seeding, vectorisation, the
expert's episode, rewards (real SUMO)."""

from __future__ import annotations

import json
from functools import partial

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")


import irlsim.envs  # noqa: E402
from irlsim.envs import continuous_to_index, normalised_value  # noqa: E402
from irlsim.errors import IrlsimError  # noqa: E402

from .conftest import TINY_POLICIES  # noqa: E402

#: a quick env: 200 policies, 3 vehicles, at most 12 cycles (2.4 s) an episode
TINY = {"planner.n_policies": TINY_POLICIES, "scenario.n_vehicles": 3}


def make(**kw):
    kw.setdefault("overrides", TINY)
    kw.setdefault("max_cycles", 12)
    return gym.make("irlsim/Planning-v0", **kw)


def test_pure_helpers():
    assert normalised_value(np.array([1.0, 3.0, 2.0]), 1) == 1.0
    assert normalised_value(np.array([1.0, 3.0, 2.0]), 0) == 0.0
    assert normalised_value(np.array([1.0, 3.0, 2.0]), 2) == 0.5
    assert normalised_value(np.array([2.0, 2.0]), 0) == 1.0
    actions = np.zeros((3, 2, 2), np.float32)
    actions[:, 0, 0] = [-3.0, 0.0, 1.5]
    cps = np.zeros((3, 2, 3), np.float32)
    cps[:, -1, 0] = [0.0, 3.2, 0.0]
    assert continuous_to_index(np.array([1.4, 0.1]), actions, cps) == 2
    assert continuous_to_index(np.array([0.2, 3.0]), actions, cps) == 1
    assert continuous_to_index(np.array([-4.0, 0.0]), actions, cps) == 0


def test_check_env_and_render():
    from gymnasium.utils.env_checker import check_env

    env = make(render_mode="rgb_array")
    try:
        check_env(env.unwrapped, skip_render_check=False)
        obs, info = env.reset(seed=3)
        assert env.observation_space.contains(obs)
        frame = env.render()
        assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
        assert frame.std() > 0  # a picture, not a blank canvas
    finally:
        env.close()


def test_continuous_variant_checks_and_steps():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("irlsim/PlanningContinuous-v0", overrides=TINY, max_cycles=5)
    try:
        check_env(env.unwrapped, skip_render_check=True)
        env.reset(seed=1)
        _, r, *_, info = env.step(np.array([0.0, 0.0], np.float32))
        assert 0.0 <= r <= 1.0 and 0 <= info["policy_index"] < TINY_POLICIES
    finally:
        env.close()


def _rollout(env, seed, n=8):
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(0)
    out = [obs["ego"].copy()]
    rewards = []
    for _ in range(n):
        obs, r, term, trunc, info = env.step(int(rng.integers(0, TINY_POLICIES)))
        out.append(obs["ego"].copy())
        rewards.append(r)
        if term or trunc:
            break
    return np.stack(out), np.array(rewards), obs["features"].copy()


def test_reset_seed_reproduces_the_episode_and_info():
    env = make()
    try:
        a = _rollout(env, 11)
        b = _rollout(env, 11)
        c = _rollout(env, 12)
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
        assert not np.array_equal(a[0], c[0])
        assert ((a[1] >= 0) & (a[1] <= 1)).all()
        # the argmax of the cycle's values earns 1; the info carries the scorecard's per-step facts
        env.reset(seed=4)
        _, r, term, trunc, info = env.step(int(np.argmax(env.unwrapped.values)))
        assert r == 1.0
        for k in ("collisions", "exits", "progress_m", "ttc_min", "ttc_ok", "comfort_ok", "intrusion_m"):
            assert k in info, k
        assert info["steps"] == 2 and info["progress_m"] > 0
    finally:
        env.close()


def test_the_old_ids_are_the_same_environments():
    from irlsim.envs import ALIASES, CONTINUOUS_ENV_ID, ENV_ID, OvalEnv, PlanningEnv

    assert ALIASES == {"irlsim/Oval-v0": ENV_ID, "irlsim/OvalContinuous-v0": CONTINUOUS_ENV_ID}
    assert OvalEnv is PlanningEnv
    for old, new in ALIASES.items():
        a, b = gym.spec(old), gym.spec(new)
        assert (a.entry_point, a.kwargs) == (b.entry_point, b.kwargs)
    new_env, old_env = make(), gym.make("irlsim/Oval-v0", overrides=TINY, max_cycles=12)
    try:  # the same episode, byte for byte, under either id
        for x, y in zip(_rollout(new_env, 5), _rollout(old_env, 5), strict=True):
            np.testing.assert_array_equal(x, y)
    finally:
        old_env.close()
        new_env.close()


def test_truncation_terminated_and_bad_input():
    env = make(max_cycles=3)
    try:
        env.reset(seed=0)
        flags = [env.step(0)[2:4] for _ in range(3)]
        assert flags[-1] == (False, True) and all(f == (False, False) for f in flags[:-1])
        with pytest.raises(RuntimeError, match="reset"):
            env.step(0)
        env.reset(seed=0)
        with pytest.raises(IrlsimError, match="outside"):
            env.step(TINY_POLICIES)
    finally:
        env.close()
    with pytest.raises(IrlsimError, match="unknown model"):
        make(reward="NoSuchModel")
    with pytest.raises(IrlsimError, match="render_mode"):
        irlsim.envs.PlanningEnv(render_mode="human")
    # a recording's config: the environment's traffic is irlsim's own, so it is refused, not ignored
    with pytest.raises(IrlsimError, match="has a recording as its demonstrator: this environment drives"):
        irlsim.envs.PlanningEnv(config="examples/mydriver/drive.toml")


def test_learned_and_callable_rewards(tiny_runs):
    from irlsim.planner.expert import THETA_EXPERT

    env = make(reward="PTACNN+S", runs=tiny_runs, max_cycles=4)
    try:
        env.reset(seed=2)
        assert env.unwrapped.reward_name == "PTACNN+S"
        _, r, *_ = env.step(0)
        assert 0.0 <= r <= 1.0
    finally:
        env.close()
    # the same cycle under a callable returning the expert's theta scores like reward='expert-theta'
    # (one env at a time: libsumo holds one simulation per process)
    got = []
    for reward in (lambda ps, obs: THETA_EXPERT, "expert-theta"):
        env = make(reward=reward)
        try:
            env.reset(seed=5)
            got.append((env.unwrapped.values.copy(), env.step(7)[1]))
        finally:
            env.close()
    np.testing.assert_array_equal(got[0][0], got[1][0])
    assert got[0][1] == got[1][1]
    with pytest.raises(IrlsimError, match="theta"):
        make(reward=lambda ps, obs: np.zeros(3)).reset(seed=0)


def test_async_vector_env_two_processes():
    from gymnasium.vector import AsyncVectorEnv

    venv = AsyncVectorEnv([partial(make, max_cycles=3)] * 2, context="spawn")
    try:
        obs, _ = venv.reset(seed=[21, 22])
        assert obs["features"].shape == (2, TINY_POLICIES, 15)
        assert not np.array_equal(obs["ego"][0], obs["ego"][1])  # two simulations, two seeds
        for _ in range(3):
            obs, r, term, trunc, _ = venv.step(np.array([0, 1]))
            assert r.shape == (2,) and ((r >= 0) & (r <= 1)).all()
        assert trunc.all()
    finally:
        venv.close()


def test_expert_choice_through_the_env_is_irlsim_sim_expert(tmp_path):
    """Stepping the expert's choice gives the episode 'irlsim sim --driver expert' drives (same seed)."""
    from irlsim.cli import main
    from irlsim.sim.simulation import TIMING_KEYS

    seed, max_time = 7, 3.0
    assert (
        main(
            [
                "sim",
                "--driver",
                "expert",
                "--seed",
                str(seed),
                "--max-time",
                str(max_time),
                "--json",
                str(tmp_path / "sim.json"),
            ]
        )
        == 0
    )
    ref = json.loads((tmp_path / "sim.json").read_text())["episodes"][0]
    env = gym.make("irlsim/Planning-v0", overrides={"scenario.max_time": max_time})
    try:
        env.reset(seed=seed)
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(env.unwrapped.expert_action())
            done = term or trunc
        got = env.unwrapped.sim.stats
    finally:
        env.close()
    keys = [k for k in ref if k.startswith("sim/") and k not in TIMING_KEYS and k != "sim/plan_ms_mean"]
    assert ref["sim/steps"] > 20 and ref["sim/distance_m"] > 10
    assert {k: got[k] for k in keys} == {k: ref[k] for k in keys}
