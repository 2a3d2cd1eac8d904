"""Closed-loop driving with a learned (or the expert's) reward in SUMO: ``drive_episode``.

Every planning cycle (0.2 s): the planner samples its reward-agnostic policy set from the ego's state, the
model predicts theta from that set (PTACNN(+S) from its online history of the last H cycles' contexts and
thetas, kept by :class:`~irlsim.reward.predictor.RewardPredictor` and reset per episode), and the ego
executes the policy of highest value V = -theta^T f for one cycle. As in the paper, learned models drive
without a model-based collision check; ``safety=True`` adds the planner's label filter (drop policies
predicted to collide, leave the road or take an exit). ``'expert'`` drives the demonstrator itself
(hand-tuned theta plus its model-based selection), the reference row of the closed-loop table;
``'demonstrator'`` the collect config's SUMO driver or recorded ego (:mod:`irlsim.drive.demonstrated`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import RECORDING
from irlsim.data.recorded import ego_sized
from irlsim.data.recording_as import RECORDED_SIZE
from irlsim.drive.demonstrated import (
    DemonstratorModel,
    demonstrator_episode,
    is_demonstrator,
    recorded_ego_episode,
)
from irlsim.drive.metrics import episode_metrics, missed_checkpoints
from irlsim.drive.recorder import ScorecardObserver
from irlsim.errors import IrlsimError
from irlsim.planner.expert import expert_theta
from irlsim.planner.policy_set import PolicySet
from irlsim.reward import LearnedReward, RewardDriver, load_reward
from irlsim.road import Road
from irlsim.rollout import Cycle, EpisodeRunner, Observer, ObserverBase
from irlsim.rollout.style import StyleObserver
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from irlsim.sim.types import Observation
from irlsim.utils import progress, seed_everything
from irlsim.viz.frames import save_animation, save_frame_pictures
from irlsim.viz.scene import CycleFrame, make_frame

# ------------------------------------------------------------------------------------------ pictures


@dataclass(frozen=True)
class PictureSpec:
    """Which cycles of an episode become pictures, and where they go.

    Frames are taken every ``stride`` cycles into a rolling window of the last ``frames`` ones. The
    window is frozen ``frames - lead`` frames after the *trigger*: the first cycle with an active stop line
    closer than ``trigger_distance`` ahead (approach, full stop and start again, the scenario's hardest
    manoeuvre). Without a trigger the window holds the episode's last frames (its end: a collision or an
    exit shows there). ``stills`` evenly spaced frames of the window are also written as PNGs.
    """

    out_dir: Path
    frames: int = 40
    """frames of the animation (bounded: a GIF of 40 frames is ~2 MB)"""
    stride: int = 2
    """[cycles] between frames (2 cycles = 0.4 s; 40 frames = 16 s of driving)"""
    lead: int = 10
    """frames kept before the trigger"""
    trigger_distance: float = 60.0
    """[m] distance to an active stop line that starts the segment"""
    stills: int = 3
    """cycles written as ``cycle_/radar_/temporal_XXXX.png``"""
    top_k: int = 10
    """policies with the highest policy attention drawn in blue"""
    max_policies: int = 300
    """policies drawn per cycle (a subset, as in the paper's Fig. 1), chosen and top-k always included"""
    fps: int = 5
    """frames per second of the GIF"""


class FrameRecorder:
    """Collects :class:`~irlsim.viz.scene.CycleFrame` records during an episode (see :class:`PictureSpec`)."""

    def __init__(self, spec: PictureSpec, road: Road, model: str, ego_size: tuple[float, float]):
        self.spec, self.road, self.model, self.ego_size = spec, road, model, ego_size
        self.window: deque[CycleFrame] = deque(maxlen=max(spec.frames, 1))
        self.trigger: int | None = None
        self.after = 0

    @property
    def frozen(self) -> bool:
        return self.trigger is not None and self.after >= self.spec.frames - min(
            self.spec.lead, self.spec.frames - 1
        )

    def wants(self, cycle: int, obs: Observation) -> bool:
        if self.frozen:
            return False
        if self.trigger is None and obs.stop_s - obs.ego.s < self.spec.trigger_distance:
            self.trigger = cycle
        return cycle % self.spec.stride == 0

    def add(
        self,
        cycle: int,
        obs: Observation,
        ps: PolicySet,
        chosen: int,
        theta: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        self.window.append(
            make_frame(
                self.road,
                self.model,
                cycle,
                obs,
                ps,
                chosen,
                theta,
                info,
                self.ego_size,
                self.spec.top_k,
                self.spec.max_policies,
            )
        )
        if self.trigger is not None:
            self.after += 1

    def write(self, reference: np.ndarray | None) -> list[str]:
        """Stills and ``episode.gif`` into ``spec.out_dir``; returns the paths written."""
        frames = list(self.window)
        if not frames:
            return []
        out = Path(self.spec.out_dir)
        n = min(self.spec.stills, len(frames))
        picks = sorted(set(np.linspace(0, len(frames) - 1, n).round().astype(int).tolist())) if n else []
        paths: list[Path] = []
        for i in picks:
            paths += save_frame_pictures(out, frames[i], reference)
        paths.append(save_animation(out / "episode.gif", frames, reference, fps=self.spec.fps))
        return [str(p) for p in paths]


# ------------------------------------------------------------------------------------------ the episode


def _expert_ring(decider: RewardDriver) -> np.ndarray:
    """The radar's unit ring: the expert's weights of the features the decider's planner computes."""
    return expert_theta(decider.planner.cfg.feature_names)


class _Timing(ObserverBase):
    """Observer: every cycle's planning and inference time [ms]; resets the model's online history."""

    def __init__(self, decider: RewardDriver):
        self.decider = decider
        self.inference_ms: list[float] = []
        self.plan_ms: list[float] = []

    def on_reset(self, sim: Simulation, obs: Observation) -> None:
        self.decider.reset()

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None:
        self.inference_ms.append(self.decider.inference_ms)
        self.plan_ms.append(self.decider.plan_ms)


class _Pictures(ObserverBase):
    """Observer: hands the cycles a :class:`FrameRecorder` wants to it."""

    def __init__(self, recorder: FrameRecorder, decider: RewardDriver):
        self.recorder, self.decider = recorder, decider

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None:
        if self.recorder.wants(cycle.index, cycle.obs):
            assert cycle.policy_set is not None
            d = self.decider
            self.recorder.add(cycle.index, cycle.obs, cycle.policy_set, cycle.chosen, d.theta, d.info)


class _Progress(ObserverBase):
    """Observer: a progress bar over the cycles with speed and laps."""

    def __init__(self, bar: Any):
        self.bar = bar

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None:
        self.bar.update(1)
        if (cycle.index + 1) % 25 == 0 and sim.ego is not None:
            self.bar.set_postfix(v=f"{3.6 * sim.ego.v:.0f} km/h", laps=cycle.facts["laps"], refresh=False)


def drive_episode(
    model: LearnedReward | DemonstratorModel | str | Path,
    road: Road,
    cfg: CollectConfig,
    seed: int,
    laps: int,
    *,
    runs: str | Path | None = None,
    episode: int = 0,
    safety: bool = False,
    pictures: PictureSpec | None = None,
    max_cycles: int = 0,
    show_progress: bool = True,
    expert_progress: tuple[Any, Any] | None = None,
    reactive: bool = False,
    choice: str = "argmax",
    lane_change_bias: float = 1.0,
    commit: bool = False,
    full_stop: bool = False,
    keep_distance: float = 0.0,
    in_lane: bool = False,
) -> dict[str, Any]:
    """Drive one SUMO episode (seed ``seed``) until ``laps`` laps, a collision, an exit or the time-out.

    ``model``: a :class:`~irlsim.reward.LearnedReward` (load it once with :func:`~irlsim.reward.load_reward`
    to drive several episodes), or a spec string resolved against ``runs``; ``'demonstrator'`` (or a
    :class:`~irlsim.drive.demonstrated.DemonstratorModel`): ``cfg``'s demonstrator drives, no pictures
    (:mod:`irlsim.drive.demonstrated`). ``cfg``: the collect config
    the model was trained with (its planner and scenario; ``scenario.laps`` is replaced by ``laps``).
    ``max_cycles`` > 0 stops early (end reason 'max_cycles'). ``pictures``: stills and an animation.
    ``expert_progress``: the expert's ``_progress`` on the same seed, for the scorecard (:func:`_scores`);
    ``reactive``: on a recording (``cfg.demonstrator``), SUMO drives the others (:func:`_simulation`);
    ``choice``, ``lane_change_bias``, ``commit``, ``full_stop``, ``keep_distance``, ``in_lane``:
    RewardDriver's.

    Returns the episode record: the ``drive/...`` keys of :mod:`irlsim.drive.metrics` (then the simulator's
    ``sim/...`` keys), the scorecard's ``score/...`` keys (:mod:`irlsim.drive.scorecard`), plus
    ``drive/pictures`` (paths written), ``_inference_ms`` (every cycle's inference time [ms], for pooled
    percentiles) and ``_progress`` ((t, s) per step); the last two are not meant for JSON.
    """
    how = (choice, lane_change_bias, commit, full_stop, keep_distance, in_lane)
    reward, decider, road, scenario, sim = _decider(
        model, cfg, road, laps, episode, reactive, runs, seed, safety, how
    )
    recorder = (
        FrameRecorder(pictures, road, reward.name, (scenario.ego_length, scenario.ego_width))
        if pictures is not None and pictures.frames > 0 and not is_demonstrator(reward)
        else None
    )
    t_start = time.perf_counter()
    bar = _bar(scenario, max_cycles, f"drive {reward.name} seed {seed}", show_progress)
    timing = _Timing(decider)
    observers: list[Observer] = [timing] + ([_Pictures(recorder, decider)] if recorder is not None else [])
    scorer = ScorecardObserver()  # records every simulation step for the scorecard
    style = StyleObserver()  # the driving style (irlsim.rollout.style)
    observers += [_Progress(bar), scorer, style]
    with sim:
        result = EpisodeRunner(sim, observers=observers, max_cycles=max(max_cycles, 0)).run(decider, seed)
        odometry = sim.odometry_arrays()
    bar.close()
    rec = episode_metrics(
        dict(result.stats),
        odometry,
        timing.inference_ms,
        timing.plan_ms,
        model=reward.name,
        episode=episode,
        seed=seed,
        safety=safety,
        cycles=result.cycles,
        wall_s=time.perf_counter() - t_start,
        end_reason=result.end_reason,
    )
    # the radar's unit ring is the expert's weight of each feature
    rec["drive/pictures"] = recorder.write(_expert_ring(decider)) if recorder is not None else []
    rec["drive/checkpoints_missed"] = missed_checkpoints(sim.episode.events if sim.episode else [])
    rec["drive/first_collision"] = sim.first_collision
    rec.update({**_scores(scorer, dict(result.stats), reward.is_expert, expert_progress), **style.summary()})
    rec["_inference_ms"] = timing.inference_ms
    return rec


def _bar(scenario: EpisodeConfig, max_cycles: int, desc: str, show: bool) -> Any:
    """The episode's progress bar over its planning cycles (the time-out's, or ``max_cycles``)."""
    bound = int(math.ceil(scenario.max_time / scenario.cycle))
    total = min(bound, max_cycles) if max_cycles else bound
    return progress(total=total, desc=desc, unit="cycle", leave=False, disable=not show)


def _decider(
    model: Any,
    cfg: CollectConfig,
    road: Road,
    laps: int,
    episode: int,
    reactive: bool,
    runs: str | Path | None,
    seed: int,
    safety: bool,
    how: tuple[Any, ...],
) -> tuple[LearnedReward | DemonstratorModel, Any, Road, EpisodeConfig, Simulation]:
    """The model (a spec loaded), what decides every cycle, and the episode's road, settings and
    simulation; the random generators seeded with ``seed`` before the decider is made. ``how``:
    RewardDriver's choice, lane-change bias and rules (the demonstrator has none of them)."""
    if is_demonstrator(model):
        scenario = _with_laps(cfg.scenario, laps)
        decider, road, scenario, sim = demonstrator_episode(cfg, road, scenario, episode, reactive)
        seed_everything(seed)
        return DemonstratorModel(), decider, road, scenario, sim
    road, scenario, sim = _simulation(cfg, road, laps, episode, reactive)
    if not isinstance(model, LearnedReward):
        model = load_reward(model, runs, n_policies=cfg.planner.n_policies)
    seed_everything(seed)
    planner = cfg.planner  # a recorded ego at its own size: planned at it (the episode's ego size)
    if cfg.demonstrator.kind == RECORDING and cfg.demonstrator.ego_size == RECORDED_SIZE:
        planner = ego_sized(planner, scenario)
    return model, RewardDriver(model, road, planner, safety, None, *how), road, scenario, sim


def _with_laps(scenario: EpisodeConfig, laps: int) -> EpisodeConfig:
    """The scenario with ``laps`` laps (``--laps``, checked)."""
    if laps < 1:
        raise IrlsimError(f"--laps must be >= 1, got {laps}")
    return dataclasses.replace(scenario, laps=int(laps))


def _simulation(
    cfg: CollectConfig, road: Road, laps: int, episode: int, reactive: bool
) -> tuple[Road, EpisodeConfig, Simulation]:
    """The episode's road, settings and simulation: the scenario's; on a recording (its egos resolved
    into ``cfg.demonstrator.ego``) ego number ``episode``'s route, start and time, the other vehicles
    replaying their recorded motion (non-reactive) or, ``reactive``, driven by SUMO from their first
    recorded pose on. A SUMO demonstrator's lane change duration holds for the other vehicles here too:
    the learned reward drives in its demonstrator's traffic."""
    scenario = _with_laps(cfg.scenario, laps)
    if cfg.demonstrator.kind != RECORDING:
        return (
            road,
            scenario,
            Simulation(road, scenario, lane_change_duration=cfg.demonstrator.lane_change_duration),
        )
    _, road, scenario, sim = recorded_ego_episode(cfg, road, scenario, episode, reactive)
    return road, scenario, sim


def _scores(
    scorer: ScorecardObserver, stats: dict[str, Any], is_expert: bool, expert_progress: Any
) -> dict[str, Any]:
    """The scorecard's ``score/...`` keys and ``_progress`` ((t, s) per step). Progress is measured against
    ``expert_progress`` (the expert's (t, s) on the same seed); None: the expert against its own run,
    other models get progress None."""
    curve = scorer.progress_curve()
    if expert_progress is None and is_expert:
        expert_progress = curve
    return {**scorer.scorecard(stats, expert_progress), "_progress": curve}
