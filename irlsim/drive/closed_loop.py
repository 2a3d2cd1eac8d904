"""Closed-loop driving with a learned (or the expert's) reward in SUMO: ``drive_episode``.

Every planning cycle (0.2 s): the planner samples its reward-agnostic policy set from the ego's state, the
model predicts theta from that set (PTACNN(+S) from its online history of the last H cycles' contexts and
thetas, kept by :class:`~irlsim.train.predictor.RewardPredictor` and reset per episode), and the ego
executes the policy of highest value V = -theta^T f for one cycle. As in the paper, learned models drive
without a model-based collision check; ``safety=True`` adds the planner's label filter (drop policies
predicted to collide, leave the road or take an exit). ``'expert'`` drives the demonstrator itself
(hand-tuned theta plus its model-based selection), the reference row of the closed-loop table.
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
from irlsim.errors import IrlsimError
from irlsim.road import HALF_ROAD, LANE_WIDTH, Road
from irlsim.sim.types import Observation

EXPERT = "expert"
#: the expert's hand-tuned theta alone: argmax V every cycle, without the expert's model-based selection
#: (the best a single linear reward of these features is known to do; LIRL's reference)
EXPERT_THETA = "expert-theta"


class FixedTheta:
    """A reward 'predictor' that always returns the expert's theta (``expert-theta``)."""

    name = EXPERT_THETA

    def predict(self, features: Any, control_points: Any, actions: Any) -> tuple[np.ndarray, dict[str, Any]]:
        from irlsim.planner.expert import THETA_EXPERT

        return THETA_EXPERT.copy(), {}

    def reset(self) -> None:
        pass


@dataclass
class DriveModel:
    """What drives: the expert (``predictor`` None) or a trained model's online reward predictor."""

    name: str
    checkpoint: Path | None = None
    predictor: Any = None  # irlsim.train.predictor.RewardPredictor

    @property
    def is_expert(self) -> bool:
        return self.predictor is None


def model_names() -> tuple[str, ...]:
    from irlsim.models.registry import MODEL_NAMES

    return (EXPERT, EXPERT_THETA, *MODEL_NAMES)


def load_drive_model(
    spec: str | Path, runs: str | Path | None = None, n_policies: int | None = None, threads: int = 1
) -> DriveModel:
    """Resolve ``spec``: 'expert', 'expert-theta', a model name (found in ``runs`` by
    :func:`irlsim.train.layout.find_checkpoint`: ``<runs>/stage1/<name>/``, ``<runs>/stage2/<name>/`` or
    ``<runs>/<name>/``) or a checkpoint path.

    ``n_policies``: the planner's policies per cycle; a checkpoint trained on another count is refused
    (the networks are built for the training set's N, and the features would not match anyway).
    """
    from irlsim.models.registry import MODEL_NAMES

    spec = str(spec)
    if spec == EXPERT:
        return DriveModel(EXPERT)
    if spec == EXPERT_THETA:
        return DriveModel(EXPERT_THETA, predictor=FixedTheta())
    if spec in MODEL_NAMES:
        from irlsim.train.layout import find_checkpoint, model_stage, stage_dir

        if runs is None:
            raise IrlsimError(f"model '{spec}' needs --runs (the runs folder 'irlsim train --out' wrote)")
        found = find_checkpoint(runs, spec)
        if found is None:
            stage = model_stage(spec)
            raise IrlsimError(
                f"checkpoint {stage_dir(runs, stage) / spec / 'checkpoint.pt'} not found: run 'irlsim train "
                f"--stage {stage} --out {runs}' first (or point --runs at the folder holding it)"
            )
        path = found
    else:
        path = Path(spec)
        if not (path.suffix == ".pt" or "/" in spec):
            raise IrlsimError(
                f"unknown model '{spec}': choose from {', '.join(model_names())} or give a checkpoint path"
            )
        if not path.is_file():
            raise IrlsimError(f"checkpoint {path} not found: run 'irlsim train' first (or fix the path)")
    from irlsim.train.predictor import RewardPredictor

    predictor = RewardPredictor(path, threads=threads)
    ck = predictor.loaded.checkpoint
    trained_n = int((ck.get("base") or ck).get("n_policies", 0))
    if n_policies is not None and trained_n and trained_n != n_policies:
        raise IrlsimError(
            f"{predictor.name} ({path}) was trained on {trained_n} policies per cycle, but the planner "
            f"samples {n_policies}: pass the collect --config the model was trained on"
        )
    return DriveModel(predictor.name, path, predictor)


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
    """cycles written as cycle_/radar_/temporal_XXXX.png"""
    top_k: int = 10
    """policies with the highest policy attention drawn in blue"""
    max_policies: int = 300
    """policies drawn per cycle (a subset, as in the paper's Fig. 1), chosen and top-k always included"""
    fps: int = 5
    """frames per second of the GIF"""


class FrameRecorder:
    """Collects :class:`~irlsim.viz.drive.CycleFrame` records during an episode (see :class:`PictureSpec`)."""

    def __init__(self, spec: PictureSpec, road: Road, model: str, ego_size: tuple[float, float]):
        self.spec, self.road, self.model, self.ego_size = spec, road, model, ego_size
        self.window: deque[Any] = deque(maxlen=max(spec.frames, 1))
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
        self, cycle: int, obs: Observation, ps: Any, chosen: int, theta: np.ndarray, info: dict[str, Any]
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
        from irlsim.viz.drive import save_animation, save_frame_pictures

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


def road_lines(
    road: Road, s0: float, behind: float = 40.0, ahead: float = 160.0
) -> tuple[tuple[str, np.ndarray], ...]:
    """Lane edges, dividers, stop lines and exit ramps within [s0 - behind, s0 + ahead] as world polylines."""
    s = np.arange(s0 - behind, s0 + ahead, 2.0)
    lines: list[tuple[str, np.ndarray]] = []
    for d in (-HALF_ROAD, -LANE_WIDTH / 2, LANE_WIDTH / 2, HALF_ROAD):
        x, y = road.to_xy(s, np.full_like(s, d))
        lines.append(("edge" if abs(d) == HALF_ROAD else "divider", np.stack([x, y], axis=1)))
    lap = road.lap_length
    for sl in road.stop_lines:
        rel_s = (sl.s - s0 + behind) % lap - behind
        if -behind <= rel_s <= ahead:
            x, y = road.to_xy(np.full(2, s0 + rel_s), np.array([-HALF_ROAD, HALF_ROAD]))
            lines.append(("stop", np.stack([x, y], axis=1)))
    for ex in road.exits:
        rel = (ex.ramp_s - s0 + behind) % lap - behind
        ok = (rel >= -behind) & (rel <= ahead)
        if ok.sum() >= 2:
            for off in (-LANE_WIDTH / 2, LANE_WIDTH / 2):
                x, y = road.to_xy(s0 + rel[ok], ex.ramp_d[ok] + off)
                lines.append(("ramp", np.stack([x, y], axis=1)))
    return tuple(lines)


def make_frame(
    road: Road,
    model: str,
    cycle: int,
    obs: Observation,
    ps: Any,
    chosen: int,
    theta: np.ndarray,
    info: dict[str, Any],
    ego_size: tuple[float, float],
    top_k: int = 10,
    max_policies: int = 300,
) -> Any:
    """A CycleFrame of one cycle: a subset of ``ps``'s policies (chosen, top-k attention, an even spread
    over the progress order), value ranks over all N policies, the vehicles and the road around the ego."""
    from irlsim.viz.drive import CycleFrame, drawn_subset, value_ranks

    att = info.get("attention")
    top = np.zeros(0, dtype=np.int64)
    if att is not None and top_k > 0:
        top = np.argsort(-np.asarray(att), kind="stable")[:top_k]
    idx = drawn_subset(ps.n_policies, max_policies, np.append(top, chosen))
    rank = value_ranks(ps.value(theta))
    ego = obs.ego
    vehicles = obs.vehicles.boxes()
    tw = info.get("temporal_weights")
    return CycleFrame(
        model=model,
        cycle=cycle,
        t=float(ego.t),
        x=ps.x[idx].astype(np.float32),
        y=ps.y[idx].astype(np.float32),
        value_rank=rank[idx],
        top_attention=np.isin(idx, top),
        chosen=int(np.searchsorted(idx, chosen)),
        theta=np.asarray(theta, dtype=np.float64),
        ego=(
            float(ego.x),
            float(ego.y),
            float(ego.yaw),
            float(ego.v),
            float(ego_size[0]),
            float(ego_size[1]),
        ),
        vehicles=vehicles.astype(np.float64),
        attention=None if att is None else np.asarray(att, dtype=np.float32)[idx],
        temporal_weights=None if tw is None else np.asarray(tw, dtype=np.float64),
        lines=road_lines(road, float(ego.s)),
        info={"lane": int(ego.lane), "target_checkpoint": int(obs.target_checkpoint)},
        view_yaw=float(road.heading(np.array(ego.s))),
    )


# ------------------------------------------------------------------------------------------ the episode


class _Decider:
    """The driver of one model plus per-cycle timing: ``plan(obs)`` returns the trajectory; afterwards
    ``policy_set``, ``index``, ``theta``, ``info``, ``plan_ms`` and ``inference_ms`` describe the cycle."""

    def __init__(self, model: DriveModel, road: Road, cfg: CollectConfig, safety: bool):
        from irlsim.planner.expert import THETA_EXPERT, ExpertDriver, ThetaDriver
        from irlsim.planner.planner import Planner

        self.model = model
        self.info: dict[str, Any] = {}
        self.inference_ms = 0.0
        if model.is_expert:
            self.driver: Any = ExpertDriver(road, cfg.planner)
            self.planner = self.driver.planner
            self.theta_expert = THETA_EXPERT
        else:
            self.planner = Planner(road, cfg.planner)
            self.driver = ThetaDriver(self.planner, self._theta, safe=safety)

    def _theta(self, ps: Any, obs: Observation) -> np.ndarray:
        t0 = time.perf_counter()
        theta, info = self.model.predictor.predict(ps.features, ps.control_points, ps.actions)
        self.inference_ms = 1e3 * (time.perf_counter() - t0)
        self.info = info
        return theta

    def reset(self) -> None:
        if not self.model.is_expert:
            self.model.predictor.reset()

    def plan(self, obs: Observation) -> Any:
        t0 = time.perf_counter()
        traj = self.driver.plan(obs)
        total_ms = 1e3 * (time.perf_counter() - t0)
        self.plan_ms = float(self.planner.last_ms)
        if self.model.is_expert:  # its 'inference' is the model-based selection after planning
            self.inference_ms = max(total_ms - self.plan_ms, 0.0)
            self.theta, self.info = self.theta_expert, {}
        else:
            self.theta = self.driver.last_theta
        self.policy_set, self.index = self.driver.last_policy_set, self.driver.last_index
        return traj


def drive_episode(
    model: DriveModel | str | Path,
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
) -> dict[str, Any]:
    """Drive one SUMO episode (seed ``seed``) until ``laps`` laps, a collision, an exit or the time-out.

    ``model``: a :class:`DriveModel` (load it once with :func:`load_drive_model` to drive several
    episodes), or a spec string resolved against ``runs``. ``cfg``: the collect config the model was trained
    with (its planner and scenario; ``scenario.laps`` is replaced by ``laps``). ``max_cycles`` > 0 stops
    early (end reason 'max_cycles'). ``pictures``: write stills and an animation (see :class:`PictureSpec`).

    Returns the episode record: the ``drive/...`` keys of :mod:`irlsim.drive.metrics` (then the simulator's
    ``sim/...`` keys), plus ``drive/pictures`` (paths written) and ``_inference_ms`` (every cycle's
    inference time [ms], for pooled percentiles; not meant for JSON).
    """
    from irlsim.drive.metrics import episode_metrics
    from irlsim.sim.simulation import Simulation
    from irlsim.utils import progress, seed_everything

    if laps < 1:
        raise IrlsimError(f"--laps must be >= 1, got {laps}")
    if not isinstance(model, DriveModel):
        model = load_drive_model(model, runs, cfg.planner.n_policies)
    scenario = dataclasses.replace(cfg.scenario, laps=int(laps))
    seed_everything(seed)
    decider = _Decider(model, road, cfg, safety)
    recorder = (
        FrameRecorder(pictures, road, model.name, (scenario.ego_length, scenario.ego_width))
        if pictures is not None and pictures.frames > 0
        else None
    )
    inference_ms: list[float] = []
    plan_ms: list[float] = []
    cycles = 0
    t_start = time.perf_counter()
    bound = int(math.ceil(scenario.max_time / scenario.cycle))
    bar = progress(
        total=min(bound, max_cycles) if max_cycles else bound,
        desc=f"drive {model.name} seed {seed}",
        unit="cycle",
        leave=False,
        disable=not show_progress,
    )
    with Simulation(road, scenario) as sim:
        obs = sim.reset(seed)
        decider.reset()
        while not sim.done and (max_cycles <= 0 or cycles < max_cycles):
            traj = decider.plan(obs)
            inference_ms.append(decider.inference_ms)
            plan_ms.append(decider.plan_ms)
            if recorder is not None and recorder.wants(cycles, obs):
                recorder.add(cycles, obs, decider.policy_set, decider.index, decider.theta, decider.info)
            sim.execute(traj)
            obs = sim.observe()
            cycles += 1
            bar.update(1)
            if cycles % 25 == 0:
                bar.set_postfix(v=f"{3.6 * obs.ego.v:.0f} km/h", laps=obs.info.get("laps", 0), refresh=False)
        stats = dict(sim.stats)
        odometry = sim.odometry_arrays()
    bar.close()
    end = stats.get("end_reason") or ("max_cycles" if max_cycles and cycles >= max_cycles else None)
    rec = episode_metrics(
        stats,
        odometry,
        inference_ms,
        plan_ms,
        model=model.name,
        episode=episode,
        seed=seed,
        safety=safety,
        cycles=cycles,
        wall_s=time.perf_counter() - t_start,
        end_reason=end,
    )
    # the radar's unit ring is the expert's weight of each feature
    rec["drive/pictures"] = recorder.write(_expert_theta()) if recorder is not None else []
    rec["_inference_ms"] = inference_ms
    return rec


def _expert_theta() -> np.ndarray:
    from irlsim.planner.expert import THETA_EXPERT

    return THETA_EXPERT
