"""``PlanningEnv``: a road (any scenario, default the oval) as a :class:`gymnasium.Env` whose action is
one of the planner's sampled policies, on the one episode runner.

Every step is one planning cycle (0.2 s of simulated time, 2 SUMO steps): the planner samples its
``n_policies`` policies from the ego's state (reward-agnostic, as for collection and driving), the agent
picks one, and :class:`~irlsim.rollout.runner.EpisodeRunner` executes it for one cycle. The runner is the
same one ``irlsim sim``, ``irlsim collect`` and ``irlsim drive`` drive their episodes with.

Spaces (N = ``planner.n_policies``, K = ``planner.n_control_points``; all float32 unless said):

    action      Discrete(N): the index of a policy of the current cycle's set (sorted by progress).
                Continuous variant (``continuous=True``, ``irlsim/PlanningContinuous-v0``): Box(2,)
                (target acceleration [m/s^2] in [a_min, a_max], lateral target [m] in [-8, 8]), turned
                into the policy with the nearest (acceleration at its first control point, lateral offset
                to the ego at the horizon), distances scaled by 1 m/s^2 and the lane width (3.2 m)
    observation Dict:
      features        [N, 15]    the 15 path-integral feature costs (irlsim.FEATURE_NAMES), >= 0
      control_points  [N, K, 3]  (lateral offset to the ego [m], yaw to the ego [rad], progress [m])
      actions         [N, K, 2]  (longitudinal acceleration [m/s^2], lateral velocity [m/s])
      labels          [N, 3]     int8 predicted collision, off-road, exit (the planner's model-based labels)
      ego             [6]        (v [m/s], a [m/s^2], d [m], d_dot [m/s], d_ddot [m/s^2], lane 0..2 / -1)
      mission         [4]        (distance to the target checkpoint [m], required lane's centre minus d [m],
                                  required lane 0..2, distance to the next active stop line [m], 1e4 if none)
      At the end of an episode there is no next policy set: the policy arrays are zeros.

Reward: theta from ``reward`` (``"expert-theta"``: the expert's hand-tuned theta; a model name with
``runs``, a model's run folder or a ``checkpoint.pt`` of any of the seven models, PTACNN(+S) with its
online history of the episode's cycles; or a callable ``f(policy_set, observation) -> theta [15]``),
predicted once per cycle on the cycle's policy set. The reward of a step is the value of the executed
policy under that theta, min-max normalised over the cycle's policies::

    r = (V_a - min_i V_i) / (max_i V_i - min_i V_i)   in [0, 1],   V_i = -theta^T f_i   (r = 1 if all equal)

so executing the learned planner's own choice (the argmax) earns 1 whatever the scale of theta.

Episode end: ``terminated`` on a collision, an exit or the laps done; ``truncated`` on the scenario's
time-out or ``max_cycles``. ``info``: the scorecard's per-step facts of the cycle (new ``collisions``,
``exits``, ``checkpoints_passed``, ``checkpoints_in_lane``, ``stop_lines_passed``, ``stop_lines_compliant``,
``offroad_steps``, ``progress_m``, ``steps``, ``laps``, ``t``, ``end_reason``; ``ttc_min`` [s], ``ttc_ok``,
``overspeed`` [m/s], ``intrusion_m``, ``comfort_ok`` from :class:`~irlsim.drive.recorder.ScorecardObserver`),
``policy_index``, ``value``, ``value_max`` and ``seed``.

``reset(seed=s)`` starts the SUMO episode with seed s (traffic and ego start): the same seed and actions
give the same episode. Without a seed, the episode seed is drawn from the env's ``np_random``.
``render_mode="rgb_array"``: ``render()`` returns the cycle picture (policies coloured by value, the
executed one, the vehicles; :mod:`irlsim.viz.frames`) as a [H, W, 3] uint8 array.
One libsumo simulation per process: vectorise with ``gymnasium.vector.AsyncVectorEnv`` (one per worker).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from irlsim import FEATURE_NAMES, N_FEATURES
from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import RECORDING
from irlsim.drive.recorder import ScorecardObserver
from irlsim.errors import IrlsimError
from irlsim.planner.expert import ExpertDriver
from irlsim.planner.planner import Planner
from irlsim.reward import EXPERT, LearnedReward, check_features, load_reward
from irlsim.road import LANE_WIDTH, load_road
from irlsim.road.scenario import Scenario, Scenarios
from irlsim.rollout.runner import EpisodeRunner
from irlsim.sim.simulation import MAX_SEED, Simulation
from irlsim.utils import seed_everything
from irlsim.viz.figure import new_figure
from irlsim.viz.frames import cycle_axes, cycle_figure_size, draw_cycle
from irlsim.viz.scene import cycle_window, make_frame

NO_STOP_LINE = 1e4  # [m] mission[3] when no stop line is active
LAT_RANGE = 8.0  # [m] of the continuous action's lateral target
ACC_SCALE = 1.0  # [m/s^2] distance scale of the continuous action's acceleration


def normalised_value(value: np.ndarray, index: int) -> float:
    """(V_index - min V) / (max V - min V) in [0, 1]; 1 when all values are equal."""
    value = np.asarray(value, dtype=np.float64)
    lo, hi = float(value.min()), float(value.max())
    if not hi > lo:
        return 1.0
    return float((value[index] - lo) / (hi - lo))


def discrete_index(action: Any, n_policies: int) -> int:
    """A ``Discrete(n_policies)`` action as the policy index: an integer (Python or numpy, or an integral
    0-d array) in 0..n_policies-1; anything else (a fraction, NaN, a bool, another shape) is refused in
    one line rather than truncated to some policy."""
    a = np.asarray(action) if not isinstance(action, (bool, np.bool_)) else None
    if a is None or a.shape != () or a.dtype.kind not in "iu":
        raise IrlsimError(
            f"action {action!r} is not a policy index: Discrete({n_policies}) takes an integer in "
            f"0..{n_policies - 1}"
        )
    index = int(a)
    if not 0 <= index < n_policies:
        raise IrlsimError(f"action {index} outside Discrete({n_policies})")
    return index


def continuous_action(action: Any) -> np.ndarray:
    """A continuous action as (target acceleration [m/s^2], lateral target [m]): two finite numbers, else
    one line (NaN would choose policy 0 by argmin; another shape read some other pair of numbers)."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (2,) or not np.isfinite(a).all():
        raise IrlsimError(
            f"action {action!r} is not two finite numbers: PlanningContinuous takes (target acceleration "
            "[m/s^2], lateral target [m]) of shape (2,)"
        )
    return a


def check_theta(theta: np.ndarray, reward: str, features: tuple[str, ...] = FEATURE_NAMES) -> np.ndarray:
    """A cycle's theta from the reward, refused (one line) unless it holds one finite number per feature
    (``features``: the planner's): a NaN or infinite weight makes every policy's value NaN (or equal),
    which the normalised reward scored as the maximal 1.0."""
    theta = np.asarray(theta, dtype=np.float64)
    if theta.shape != (len(features),):
        raise IrlsimError(f"reward {reward} gave theta of shape {theta.shape}, not [{len(features)}]")
    bad = ~np.isfinite(theta)
    if bad.any():
        names = [features[i] for i in np.flatnonzero(bad)[:3]]
        raise IrlsimError(
            f"reward {reward} gave a non-finite theta ({', '.join(names)} = "
            f"{', '.join(str(theta[i]) for i in np.flatnonzero(bad)[:3])}): fix the reward callable, or "
            "retrain the model (check its checkpoint and the dataset for non-finite features)"
        )
    return theta


def callable_theta(out: Any, n: int = N_FEATURES) -> np.ndarray:
    """What a reward callable returned as theta [n] float64 (n: the planner's features); anything else
    (another shape, or not numbers: a string, None, a dict, complex or bool values, a tensor that needs
    grad) is one line."""
    try:
        arr = np.asarray(out)
    except Exception:  # noqa: BLE001  # what numpy cannot take (a tensor needing grad, ...): named below
        arr = np.asarray(None)
    if arr.dtype.kind not in "iuf":
        what = type(out).__name__ + ("" if arr.dtype == object else f" of {arr.dtype}")
        raise IrlsimError(f"the reward callable must return theta [{n}] (real numbers), got {what}")
    theta = arr.astype(np.float64).reshape(-1)
    if theta.shape != (n,):
        raise IrlsimError(
            f"the reward callable must return theta [{n}] (real numbers), got shape {arr.shape}"
        )
    return theta


def continuous_to_index(action: np.ndarray, actions: np.ndarray, control_points: np.ndarray) -> int:
    """The policy nearest to (target acceleration, lateral target): see the module docstring."""
    a = np.asarray(action, dtype=np.float64).reshape(-1)
    acc = actions[:, 0, 0].astype(np.float64)
    lat = control_points[:, -1, 0].astype(np.float64)
    dist = ((acc - a[0]) / ACC_SCALE) ** 2 + ((lat - a[1]) / LANE_WIDTH) ** 2
    return int(np.argmin(dist))


def _resolve_reward(
    reward: Any, runs: Any, n_policies: int, features: tuple[str, ...] = FEATURE_NAMES
) -> tuple[str, Any]:
    """(name, theta_fn(policy_set, obs) -> theta, with reset()) from the ``reward`` argument, for a
    planner computing ``features``."""
    if callable(reward) and not isinstance(reward, (str, Path)):
        return getattr(reward, "__name__", "callable"), _CallableReward(reward, len(features))
    spec = str(reward)
    if spec == EXPERT:
        raise IrlsimError(
            "reward='expert' has no theta of its own beyond 'expert-theta' (the expert's selection is a "
            "rule, not a reward): use reward='expert-theta'"
        )
    path = Path(spec)
    if path.is_dir() and (path / "checkpoint.pt").is_file():
        spec = str(path / "checkpoint.pt")
    model = load_reward(spec, runs, n_policies=n_policies)
    check_features(model, features)
    return model.name, _LoadedReward(model)


class _LoadedReward:
    def __init__(self, reward: LearnedReward):
        self.reward = reward

    def __call__(self, ps: Any, obs: Any) -> np.ndarray:
        return np.asarray(self.reward.theta(ps), dtype=np.float64)

    def reset(self) -> None:
        self.reward.reset()


class _CallableReward:
    def __init__(self, fn: Callable[[Any, Any], Any], n: int = N_FEATURES):
        self.fn, self.n = fn, n

    def __call__(self, ps: Any, obs: Any) -> np.ndarray:
        return callable_theta(self.fn(ps, obs), self.n)

    def reset(self) -> None:
        reset = getattr(self.fn, "reset", None)
        if callable(reset):
            reset()


def _no_recording(cfg: CollectConfig, config: Any) -> None:
    """Refuse a config whose demonstrator is a recording: the environment's traffic is irlsim's own, and
    a replay would otherwise be silently replaced by it."""
    if cfg.demonstrator.kind == RECORDING:
        name = "given" if isinstance(config, CollectConfig) else config
        raise IrlsimError(
            f"config {name} has a recording as its demonstrator: this environment drives irlsim's own "
            "traffic, not a replay; drive a reward on the recording with irlsim drive --config, or give "
            "the environment a config without the recording [demonstrator]"
        )


class PlanningEnv(gym.Env):
    """A road, the oval unless ``scenario`` names another (see the module docstring for spaces, reward,
    episode end and seeding).

    ``config``: a collect TOML path or a :class:`~irlsim.data.collection.CollectConfig` (its scenario and
    planner; default: the built-in one); ``overrides``: dotted keys applied on top
    (``{"scenario.max_time": 30, "planner.n_policies": 200}``); ``laps``: laps to drive (default the
    config's); ``max_cycles`` > 0 truncates earlier; ``scenario``: the road (a shipped scenario such as
    ``"motorway"``, a scenario.toml path or a loaded :class:`irlsim.road.scenario.Scenario`; default the
    config's, the oval).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(
        self,
        reward: Any = "expert-theta",
        *,
        runs: str | Path | None = None,
        config: Any = None,
        overrides: dict[str, Any] | None = None,
        laps: int | None = None,
        max_cycles: int = 0,
        continuous: bool = False,
        render_mode: str | None = None,
        scenario: str | Path | Scenario | None = None,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise IrlsimError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if max_cycles < 0:
            raise IrlsimError(f"max_cycles must be >= 0, got {max_cycles}")
        # the road's file read once, for the config's [defaults] and the road; a Scenario is not read again
        scenarios = Scenarios(*([scenario] if isinstance(scenario, Scenario) else []))
        if isinstance(scenario, Scenario):
            scenario = scenario.path
        if isinstance(config, CollectConfig):
            cfg = config
            if overrides:
                raise IrlsimError("overrides apply to a config file: pass config as a path (or None)")
        else:  # the scenario's own [defaults] beneath the config (CollectConfig.with_defaults)
            named = {"scenario.name": str(scenario)} if scenario is not None else {}
            given = {**(overrides or {}), **named}  # a bad value names the argument it came from
            labels = {k: f"overrides[{k!r}]" for k in overrides or {}} | {"scenario.name": "scenario="}
            cfg = load_config(CollectConfig, config, given, labels, scenarios)
        _no_recording(cfg, config)
        sc = cfg.scenario
        if scenario is not None:
            sc = dataclasses.replace(sc, name=str(scenario))
        if laps is not None:
            if laps < 1:
                raise IrlsimError(f"laps must be >= 1, got {laps}")
            sc = dataclasses.replace(sc, laps=int(laps))
        self.cfg, self.scenario = cfg, sc
        self.render_mode = render_mode
        self.continuous = bool(continuous)
        self.road = load_road(scenario=scenarios(sc.name))
        self.planner = Planner(self.road, cfg.planner)
        n, k = cfg.planner.n_policies, cfg.planner.n_control_points
        features = cfg.planner.feature_names
        self.reward_name, self._theta_fn = _resolve_reward(reward, runs, n, features)
        self.sim = Simulation(self.road, sc)
        self.scorer = ScorecardObserver()
        self.runner = EpisodeRunner(
            self.sim, planner=self.planner, observers=[self.scorer], max_cycles=max_cycles
        )
        inf = np.float32(np.inf)
        self.observation_space = spaces.Dict(
            {
                "features": spaces.Box(0.0, inf, (n, len(features)), np.float32),
                "control_points": spaces.Box(-inf, inf, (n, k, 3), np.float32),
                "actions": spaces.Box(-inf, inf, (n, k, 2), np.float32),
                "labels": spaces.MultiBinary((n, 3)),
                "ego": spaces.Box(-inf, inf, (6,), np.float32),
                "mission": spaces.Box(-inf, inf, (4,), np.float32),
            }
        )
        if self.continuous:
            pc = cfg.planner
            self.action_space: spaces.Space = spaces.Box(
                np.array([pc.a_min, -LAT_RANGE], np.float32), np.array([pc.a_max, LAT_RANGE], np.float32)
            )
        else:
            self.action_space = spaces.Discrete(n)
        self.policy_set: Any = None
        self.obs: Any = None
        self.theta: np.ndarray | None = None
        self.values: np.ndarray | None = None
        self.episode_seed: int | None = None
        self._last: tuple[Any, Any, int, np.ndarray] | None = None  # for render: obs, ps, index, theta
        self._expert: Any = None

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        ep_seed = int(seed) if seed is not None else int(self.np_random.integers(0, MAX_SEED))
        seed_everything(ep_seed)
        self.episode_seed = ep_seed
        self._theta_fn.reset()
        if self._expert is not None:
            self._expert._heading_lane = None
        self.obs, self.policy_set = self.runner.reset(ep_seed)
        self._score_cycle()
        self._last = None
        return self._observation(), {"seed": ep_seed, "reward": self.reward_name}

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        if self.policy_set is None:
            raise RuntimeError("step() after the episode ended (or before reset()): call reset()")
        ps = self.policy_set
        if self.continuous:
            index = continuous_to_index(continuous_action(action), ps.actions, ps.control_points)
        else:
            index = discrete_index(action, ps.n_policies)
        assert self.values is not None and self.theta is not None
        reward = normalised_value(self.values, index)
        value, value_max = float(self.values[index]), float(self.values.max())
        self._last = (self.obs, ps, index, self.theta)
        res = self.runner.step(index)
        self.obs, self.policy_set = res.obs, res.policy_set
        info: dict[str, Any] = dict(res.facts)
        info.update(self.scorer.cycle_facts(int(res.facts.get("steps") or 1)))
        info.update(policy_index=index, value=value, value_max=value_max, seed=self.episode_seed)
        self._score_cycle()
        return self._observation(), reward, bool(res.terminated), bool(res.truncated), info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._last is not None:
            obs, ps, index, theta = self._last
        elif self.policy_set is not None:
            assert self.theta is not None and self.values is not None
            obs, ps, index, theta = self.obs, self.policy_set, int(np.argmax(self.values)), self.theta
        else:
            raise RuntimeError("render() before reset(): call reset() first")
        return cycle_picture(self.road, self.reward_name, obs, ps, index, theta, self.scenario)

    def close(self) -> None:
        self.sim.close()

    # ------------------------------------------------------------------ helpers
    def expert_action(self) -> int:
        """The index the expert (hand-tuned theta plus its model-based selection) picks in this cycle;
        stepping it every cycle drives the episode ``irlsim sim --driver expert`` drives."""
        if self.policy_set is None:
            raise RuntimeError("no cycle to choose in: call reset()")
        if self._expert is None:
            self._expert = ExpertDriver(self.road, self.cfg.planner)
            self._expert.planner = self.planner  # select() reads the planner's last internals
        return int(self._expert.select(self.policy_set, self.obs))

    def episode_scorecard(self, expert_progress: tuple[Any, Any] | None = None) -> dict[str, Any]:
        """The scorecard of the episode so far (``score/...`` keys of :mod:`irlsim.drive.scorecard`) and the
        simulator's ``sim/...`` counts; ``expert_progress``: the expert's (t, s) on the same seed (from its
        episode's :meth:`progress_curve`) for the progress term, else progress is None."""
        stats = self.sim.stats
        if not stats:
            raise RuntimeError("no episode: call reset() and step() first")
        rec = {k: v for k, v in stats.items() if k.startswith("sim/")}
        rec["end_reason"] = self.runner.result.end_reason if self.runner.result is not None else None
        rec.update(self.scorer.scorecard(stats, expert_progress))
        return rec

    def progress_curve(self) -> tuple[list[float], list[float]]:
        """(t, s) per simulation step of the episode so far: the progress reference of other agents."""
        return self.scorer.progress_curve()

    def _score_cycle(self) -> None:
        if self.policy_set is None:
            self.theta = self.values = None
            return
        features = self.planner.cfg.feature_names
        self.theta = check_theta(self._theta_fn(self.policy_set, self.obs), self.reward_name, features)
        self.values = self.policy_set.value(self.theta)

    def _observation(self) -> dict[str, np.ndarray]:
        assert isinstance(self.observation_space, spaces.Dict)
        sp = self.observation_space.spaces
        obs, ps = self.obs, self.policy_set
        out: dict[str, np.ndarray] = {}
        if ps is not None:
            out["features"] = np.ascontiguousarray(ps.features, dtype=np.float32)
            out["control_points"] = np.ascontiguousarray(ps.control_points, dtype=np.float32)
            out["actions"] = np.ascontiguousarray(ps.actions, dtype=np.float32)
            out["labels"] = np.ascontiguousarray(ps.labels, dtype=np.int8)
        else:
            for key in ("features", "control_points", "actions", "labels"):
                space = sp[key]
                out[key] = np.zeros(tuple(space.shape or ()), dtype=np.dtype(space.dtype or np.float32))
        e = obs.ego
        out["ego"] = np.array([e.v, e.a, e.d, e.d_dot, e.d_ddot, e.lane], dtype=np.float32)
        req = self.road.checkpoints[obs.target_checkpoint].lane
        stop = obs.stop_s - e.s if np.isfinite(obs.stop_s) else NO_STOP_LINE
        out["mission"] = np.array(
            [obs.target_s - e.s, float(self.road.lane_center(req)) - e.d, req, min(stop, NO_STOP_LINE)],
            dtype=np.float32,
        )
        return out


def cycle_picture(
    road: Any, name: str, obs: Any, ps: Any, index: int, theta: np.ndarray, scenario: Any
) -> np.ndarray:
    """The cycle picture of the drive stage as a [H, W, 3] uint8 array."""
    frame = make_frame(road, name, 0, obs, ps, index, theta, {}, (scenario.ego_length, scenario.ego_width))
    win = cycle_window(frame)
    fig = new_figure(cycle_figure_size(win, width=6.0))
    draw_cycle(cycle_axes(fig, win), frame, window=win)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
