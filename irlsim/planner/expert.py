"""The expert demonstrator and a generic theta driver.

``ExpertDriver`` = hand-tuned ``THETA_EXPERT`` + model-based selection in the spirit of the paper:

1. drop policies labelled off-road or exit, and those that cross an active stop line without a full
   stop (stop_line > 0) when others do not; drop those labelled predicted collision unless nothing
   else is left;
2. risk of each policy: the planner's ``risk`` (time-weighted intrusion into the safety zone of a
   predicted vehicle, 3 s ahead) plus the following check of ``lane_outlook`` (at 1..5 s the ego must
   be able to fall back behind the vehicle ahead in its lane, braking 3 m/s^2 with 0.8 s headway), so
   the expert brakes for slow vehicles early instead of late in every receding horizon;
3. cluster topologically by (lanes away from the required lane where the policy passes the target
   checkpoint, or at the horizon if it does not reach it; lane at the horizon; number of lane changes);
   inside each cluster keep its least risky policies;
4. score each cluster by the best (progress over the horizon + ``outlook``: what its final lane offers
   for 5 s more, limited by the predicted vehicle ahead in it) [m], minus ``lc_cost`` per lane change,
   minus a mission penalty ``lanes away * m(remaining distance)`` [m] (``mission_penalty``: a small
   ``mission_base`` while the checkpoint is further than ``mission_far``, so the expert overtakes slow
   vehicles, rising linearly to ``mission_cap`` at ``mission_near``, so it is in the required lane well
   before the checkpoint), minus ``risk_cost`` per unit of the cluster's least risk, plus
   ``keep_bonus`` for the lane the expert is already heading to (hysteresis);
5. inside the best cluster execute argmax V = -theta^T f among its least risky policies.

When every policy is off-road or takes an exit (never seen), it falls back to the strongest braking.

``ThetaDriver(planner, theta_fn)`` executes argmax V for any theta (the learned models use it), with an
optional model-based safety filter (the labels) and an optional commitment to the maneuver under way, a
lane change or a stop (the expert's hysteresis as a rule without a score). Both expose
``last_policy_set`` and ``last_index``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.planner.choice import CHOICES, expected_choice
from irlsim.planner.config import PlannerConfig
from irlsim.planner.following import lane_outlook
from irlsim.planner.planner import Planner
from irlsim.planner.policy_set import PolicySet
from irlsim.road import Road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.types import Observation, Trajectory

#: the expert's hand-tuned weights, one per feature (FEATURE_NAMES order); V = -theta^T f
THETA_EXPERT_DICT: dict[str, float] = {
    "acc_lon": 1.0,  # 1 m/s^2 held over the horizon costs ~3
    "jerk_lon": 0.3,
    "acc_lat": 0.5,
    "jerk_lat": 0.2,
    "velocity": 1.0,  # 5 m/s below target over the horizon costs ~77
    "creep": 5.0,
    "end_heading": 50.0,
    "centerline": 10.0,  # hovering 0.8 m off a lane centre over the horizon costs ~20
    "road_edge": 100.0,
    "mission_lane": 10.0,
    "progress": 0.05,
    "stop_line": 100.0,
    "lc_delay": 1.0,
    "lat_overshoot": 10.0,
    "proximity": 30.0,  # with the overlap term, argmax V alone avoids most collisions (docs/HISTORY.md)
}
THETA_EXPERT = np.array([THETA_EXPERT_DICT[n] for n in FEATURE_NAMES], dtype=np.float64)


def expert_theta(names: tuple[str, ...] | list[str] = FEATURE_NAMES) -> np.ndarray:
    """The expert's weights for the features ``names`` (a feature set's, in order): 0 on the lane pair,
    which the expert does not price, so that its driving is the same with either set."""
    return np.array([THETA_EXPERT_DICT.get(n, 0.0) for n in names], dtype=np.float64)


#: [s] the time headway of the expert's following check (``SelectionConfig.follow_headway``)
FOLLOW_HEADWAY = 0.8


@dataclass(frozen=True)
class SelectionConfig:
    """The expert's model-based selection (units: metres of progress over the horizon)."""

    lc_cost: float = 2.0
    """[m] cluster score cost per lane change"""
    keep_bonus: float = 3.0
    """[m] cluster score bonus for the lane the expert already heads to (no dithering)"""
    mission_base: float = 4.0
    """[m] mission penalty per lane away from the required lane while the checkpoint is beyond
    ``mission_far`` (a tie-breaker: free lanes being equal, drive in the required one)"""
    mission_far: float = 200.0
    """[m] remaining distance to the checkpoint below which the mission penalty starts to rise; until
    here the expert leaves the required lane to overtake (a pass takes ~100-150 m)"""
    mission_near: float = 110.0
    """[m] remaining distance at which the mission penalty reaches ``mission_cap``"""
    mission_cap: float = 400.0
    """[m] mission penalty per lane from ``mission_near`` on (dominates any progress difference)"""
    progress_tol: float = 1.0
    """[m] cluster scores within this of the best count as equal (the fewest lane changes wins)"""
    risk_cost: float = 100.0
    """[m] cluster score cost per unit of the cluster's least risk (1 = one step, 0.1 s, inside the
    safety zone now): a risk-free cluster beats a risky one unless the mission says otherwise"""
    follow_times: tuple[float, ...] = (1.0, 2.0, 3.0, 4.0, 5.0)
    """[s] following check: the times along the horizon at which the ego must be able to fall back
    behind the predicted vehicle ahead in its lane braking ``follow_decel``, keeping ``follow_headway``"""
    follow_decel: float = 3.0
    """[m/s^2] following check: the braking it may assume"""
    follow_headway: float = FOLLOW_HEADWAY
    """[s] following check: time headway kept (plus ``follow_gap``)"""
    follow_gap: float = 2.0
    """[m] following check: bumper gap kept"""
    follow_scale: float = 5.0
    """[m] following-check shortfall that counts as one unit of risk"""
    outlook_time: float = 5.0
    """[s] the cluster score adds the progress the final lane offers this long after the horizon"""


def mission_penalty(sel: SelectionConfig, remaining: float) -> float:
    """[m] cluster score penalty per lane away from the required lane at ``remaining`` metres to the
    checkpoint: ``mission_base`` beyond ``mission_far``, ``mission_cap`` within ``mission_near``, linear
    in between."""
    x = (sel.mission_far - remaining) / max(sel.mission_far - sel.mission_near, 1e-6)
    return float(sel.mission_base + (sel.mission_cap - sel.mission_base) * np.clip(x, 0.0, 1.0))


def mission_lanes_away(ps: PolicySet, target_s: float, req: int, final_lane: np.ndarray) -> np.ndarray:
    """[N] int: |lane - required lane| at the step a policy passes the checkpoint (unwrapped
    ``target_s``), or at the horizon for a policy that does not reach it."""
    s = ps.s
    reach = s[:, -1] > target_s
    k = np.argmax(s > target_s, axis=1)
    lane = np.where(reach, ps.lane[np.arange(len(k)), k], final_lane).astype(np.int64)
    return np.abs(lane - req)


def lane_clusters(ps: PolicySet) -> tuple[np.ndarray, np.ndarray]:
    """(final lane [N] int, number of lane changes [N] int) of every policy."""
    lane = ps.lane.astype(np.int16)
    changes = (np.diff(lane, axis=1) != 0).sum(axis=1)
    return lane[:, -1].astype(np.int64), changes.astype(np.int64)


class ExpertDriver:
    """The demonstrator: ``plan(obs) -> Trajectory``; ``last_policy_set`` / ``last_index`` keep the
    executed cycle's PolicySet and the index of the executed policy in it."""

    def __init__(
        self,
        road: Road,
        cfg: PlannerConfig | None = None,
        theta: np.ndarray | None = None,
        selection: SelectionConfig | None = None,
    ):
        self.road = road
        self.planner = Planner(road, cfg)
        names = self.planner.cfg.feature_names
        self.theta = expert_theta(names) if theta is None else np.asarray(theta, dtype=np.float64)
        assert self.theta.shape == (len(names),), self.theta.shape
        self.sel = selection or SelectionConfig()
        self.last_policy_set: PolicySet | None = None
        self.last_index: int = -1
        self._heading_lane: int | None = None
        self._stop_lines = tuple(float(sl.s) for sl in road.stop_lines)

    def select(self, ps: PolicySet, obs: Observation) -> int:
        """Index of the policy the expert executes (see the module docstring)."""
        internals = self.planner.last
        assert internals is not None
        sel = self.sel
        lab = ps.labels
        allowed = ~lab[:, 1] & ~lab[:, 2]
        # a full stop at every active stop line is a hard rule, like the labels
        stops = ps.features[:, FEATURE_NAMES.index("stop_line")] <= 0
        if (allowed & stops).any():
            allowed &= stops
        if not allowed.any():
            return int(np.argmin(ps.progress))  # sorted by progress: the hardest braking comes first
        cand = allowed & ~lab[:, 0]
        if not cand.any():
            cand = allowed
        # risk: the planner's safety-zone intrusion plus the shortfall of the following gap at the horizon
        cfg = self.planner.cfg
        shortfall, outlook = lane_outlook(
            internals, obs, sel, cfg.dt, self._stop_lines, cfg.ego_width, cfg.v_target
        )
        risk = internals.risk.astype(np.float64) + shortfall / sel.follow_scale
        reach = ps.progress + outlook  # progress over the horizon and what the final lane offers after it
        risk = np.where(cand, risk, np.inf)
        value = ps.value(self.theta)
        final_lane, n_lc = lane_clusters(ps)
        req = self.road.required_lane(obs.target_checkpoint, obs.ego.d)
        rem = max(obs.target_s - obs.ego.s, 1.0)
        mission = mission_penalty(sel, rem)
        # lanes away from the required one where the policy passes the checkpoint (at the horizon if
        # it does not reach it): a swerve back into the lane just after the checkpoint does not count
        miss = mission_lanes_away(ps, obs.target_s, req, final_lane)
        keys = (np.minimum(miss, 15) * (self.road.n_lanes + 1) + final_lane + 1) * 16 + np.minimum(n_lc, 15)
        best_key, best_score, best_ok = None, -np.inf, None
        for key in np.unique(keys[cand]):  # a handful of clusters
            members = cand & (keys == key)
            r_min = float(risk[members].min())
            ok = members & (risk <= r_min + 1e-6)  # the cluster's least risky policies
            miss_k, lane_k, lc_k = int(key // 64), int(key // 16 % 4) - 1, int(key % 16)
            score = float(reach[ok].max()) - sel.lc_cost * lc_k - mission * miss_k - sel.risk_cost * r_min
            if self._heading_lane is not None and lane_k == self._heading_lane:
                score += sel.keep_bonus
            if score > best_score + sel.progress_tol or (
                abs(score - best_score) <= sel.progress_tol and best_key is not None and lc_k < best_key % 16
            ):
                best_key, best_score, best_ok = key, score, ok
        assert best_ok is not None
        idx = int(np.argmax(np.where(best_ok, value, -np.inf)))
        self._heading_lane = int(final_lane[idx])
        return idx

    def follow(self, ps: PolicySet, index: int) -> None:
        """Another driver executed policy ``index`` of ``ps`` (DAgger: a learned reward drives, the expert
        labels): the lane the car now heads to is that policy's final lane, so the expert's hysteresis
        (``keep_bonus``) applies to where the car is going, not to where the expert's label went."""
        self._heading_lane = int(ps.lane[index, -1])

    def plan(self, obs: Observation) -> Trajectory:
        ps = self.planner.plan(obs)
        idx = self.select(ps, obs)
        self.last_policy_set, self.last_index = ps, idx
        return self.planner.trajectory(idx)


class ThetaDriver:
    """Executes argmax V = -theta^T f under ``theta_fn(policy_set, obs) -> theta [15]`` each cycle.

    ``safe=True`` first drops policies labelled collision / off-road / exit (model-based safety, as the
    paper's planner does around a learned reward); when that drops all of them it uses all.
    ``choice``: 'argmax' (the paper's), or 'expected' or 'maneuver' with ``lane_change_bias``
    (:mod:`irlsim.planner.choice`). ``commit=True`` finishes the maneuver chosen (``choose_index``'s
    ``heading`` and ``stopping``): once a chosen policy ends in another lane than the ego's, the next
    cycles choose among the policies that end there until the ego is in it (no dithering between two
    lane changes); once a chosen policy comes to a stand, the next one does not cross an active stop
    line without a full stop (no creeping up to the line and over it). ``full_stop=True``: a rule of the
    road, every cycle: no policy that crosses an active stop line without a full stop, nor one above the
    braking curve to it (:func:`within_braking_curve`), while any other policy keeps to them.
    ``keep_distance`` > 0: a rule of the road, every cycle: only the policies that keep a safe following
    distance to the vehicle ahead, with that time headway [s] (:func:`keeping_distance`; the expert's
    check has ``FOLLOW_HEADWAY``); with ``in_lane`` in the lane the reward chooses (``choose_index``'s
    ``in_lane``). Call :meth:`reset` per episode.
    """

    def __init__(
        self,
        planner: Planner,
        theta_fn: Callable[[PolicySet, Observation], Any],
        safe: bool = False,
        choice: str = "argmax",
        lane_change_bias: float = 1.0,
        commit: bool = False,
        full_stop: bool = False,
        keep_distance: float = 0.0,
        in_lane: bool = False,
    ):
        assert choice in CHOICES, choice
        self.planner = planner
        self.theta_fn = theta_fn
        self.safe = safe
        self.choice, self.lane_change_bias, self.commit = choice, lane_change_bias, commit
        self.full_stop, self.keep_distance, self.in_lane = full_stop, keep_distance, in_lane
        self._stop_lines = tuple(float(sl.s) for sl in planner.road.stop_lines) if keep_distance > 0 else ()
        self._follow = SelectionConfig(follow_headway=keep_distance) if keep_distance > 0 else None
        self.last_policy_set: PolicySet | None = None
        self.last_index: int = -1
        self.last_theta: np.ndarray | None = None
        self.heading: int | None = None  # the lane a lane change under way heads to (with commit)
        self.stopping = False  # the last policy chosen comes to a stand (with commit)
        self._speeds: tuple[float, dict[str, float]] = (0.0, {})  # the vehicles' speeds last cycle

    def reset(self) -> None:
        self.heading, self.stopping, self._speeds = None, False, (0.0, {})

    def _accelerations(self, obs: Observation) -> np.ndarray:
        """[M] m/s^2: each vehicle's speed change since the last cycle (0 for one not seen then)."""
        veh, (t0, before) = obs.vehicles, self._speeds
        dt = obs.ego.t - t0
        prev = np.array([before.get(i, np.nan) for i in veh.ids], dtype=np.float64)
        accel = np.where(np.isfinite(prev) & (dt > 0), (veh.v - prev) / max(dt, 1e-9), 0.0)
        self._speeds = (obs.ego.t, dict(zip(veh.ids, veh.v.tolist(), strict=True)))
        return accel

    def plan(self, obs: Observation) -> Trajectory:
        ps = self.planner.plan(obs)
        theta = np.asarray(self.theta_fn(ps, obs), dtype=np.float64).reshape(-1)
        assert theta.shape == (len(self.planner.cfg.feature_names),), theta.shape
        if self.heading is not None and int(ps.lane[0, 0]) == self.heading:
            self.heading = None  # arrived: the lane change is done
        stopping = self.stopping or self.full_stop
        cfg = self.planner.cfg
        braking = within_braking_curve(ps, obs.stop_s, cfg) if self.full_stop else None
        distance = None
        if self._follow is not None and self.planner.last is not None:
            accel = self._accelerations(obs)  # a leader braking hard is predicted braking on
            distance = keeping_distance(self.planner.last, obs, cfg, self._stop_lines, self._follow, accel)
        rules = (self.heading, stopping, braking, distance)
        idx = choose_index(
            ps, theta, self.safe, self.choice, self.lane_change_bias, *rules, in_lane=self.in_lane
        )
        if self.commit:
            start, end = int(ps.lane[idx, 0]), int(ps.lane[idx, -1])
            self.heading = end if end >= 0 and end != start else None
            self.stopping = bool(ps.v[idx].min() < self.planner.cfg.v_stopped)
        self.last_policy_set, self.last_index, self.last_theta = ps, idx, theta
        return self.planner.trajectory(idx)


def choose_index(
    policy_set: PolicySet,
    theta: np.ndarray,
    safety: bool = False,
    choice: str = "argmax",
    lane_change_bias: float = 1.0,
    heading: int | None = None,
    stopping: bool = False,
    braking: np.ndarray | None = None,
    distance: np.ndarray | None = None,
    value: np.ndarray | None = None,
    in_lane: bool = False,
) -> int:
    """The policy a reward theta executes in the set: ``choice`` 'argmax' of V = -theta^T f, or 'expected' or
    'maneuver' (:func:`irlsim.planner.choice.expected_choice`); with ``safety`` among the policies without a
    label (collision / off-road / exit), all of them when every one has one. ``heading``: a lane change under
    way to that lane; only the policies that end in it and are not labelled a predicted collision (nor, with
    ``safety``, anything else) are chosen from, unless there is none; ``stopping``: a stop under way; only the
    policies that do not cross an active stop line without a full stop (``stop_line`` feature 0), unless there
    is none (applied first: a stop outranks a lane change); ``braking`` [N] bool: then only these
    (:func:`within_braking_curve`), unless none; ``distance`` [N] bool: then only these
    (:func:`keeping_distance`), unless none; with ``in_lane`` the lane the policy of highest value (before
    ``distance``) ends in is kept: its policies that keep the distance, where there are (the rule picks the
    speed, the reward the lane; a lane change only where no policy in that lane keeps the distance). ``value``
    [N]: the policies' values instead of -theta^T f (any score, higher is better: ``theta`` is then unused;
    e.g. the nearness to a driver's odometry of ``studies/style_oracle.py``). :class:`ThetaDriver` and
    :meth:`irlsim.reward.LearnedReward.choose` decide with it."""
    value = policy_set.value(theta) if value is None else np.asarray(value, dtype=np.float64)
    allowed: np.ndarray | None = None
    if safety:
        bad = np.asarray(policy_set.labels.any(axis=1))
        allowed = None if bad.all() else np.logical_not(bad)
    if stopping:  # first: a stop outranks a lane change
        allowed = _narrowed(allowed, policy_set.features[:, FEATURE_NAMES.index("stop_line")] <= 0)
    if braking is not None:
        allowed = _narrowed(allowed, braking)
    if distance is not None:
        if in_lane:
            lane = policy_set.lane[:, -1]
            allowed = _narrowed(allowed, distance & (lane == lane[_best(value, allowed)]))
        allowed = _narrowed(allowed, distance)
    if heading is not None:
        there = (policy_set.lane[:, -1] == heading) & np.logical_not(policy_set.labels[:, 0])
        allowed = _narrowed(allowed, there)
    if choice in ("expected", "maneuver"):
        within = "argmax" if choice == "maneuver" else "expected"
        return expected_choice(value, policy_set.control_points, lane_change_bias, allowed, within)
    return _best(value, allowed)


def _best(value: np.ndarray, allowed: np.ndarray | None) -> int:
    """The index of the highest ``value`` among the ``allowed`` policies (None: all)."""
    return int(np.argmax(value if allowed is None else np.where(allowed, value, -np.inf)))


#: [m/s^2] the braking curve of ``full_stop``: above the planner's comfortable 2.5 (its stop profiles keep
#: within it) and below the strongest sampled braking (4 and 6), so a stop from the curve stays sampled
FULL_STOP_DECEL = 4.0


def within_braking_curve(
    policy_set: PolicySet, stop_s: float, cfg: PlannerConfig, decel: float = FULL_STOP_DECEL
) -> np.ndarray:
    """[N] bool: the policies that keep a full stop at the active stop line at ``stop_s`` (unwrapped route
    position, inf: none) within reach: until a policy has stood (below ``v_stopped``), its speed never
    exceeds sqrt(2 ``decel`` d) + ``v_stopped``, d its front bumper's distance to the stop point
    (``stop_margin`` before the line). A policy that only stands in the last metre, braking at the limit,
    passes the stop-line feature's test but not this one: the next cycle's set (sampled from the state
    reached) may hold no stop at all, and a reward that values speed rides that limit (measured on the
    recording's rewards). Every policy passes without an active line within ``stop_reach``."""
    v, s = policy_set.v, policy_set.s
    if not np.isfinite(stop_s) or stop_s - s[0, 0] >= cfg.stop_reach:
        return np.ones(len(v), dtype=bool)
    stood = np.logical_or.accumulate(v < cfg.v_stopped, axis=1)
    over = v > np.sqrt(2.0 * decel * np.maximum(stop_s - cfg.stop_margin - s, 0.0)) + cfg.v_stopped
    return np.logical_not((over & ~stood).any(axis=1))


#: [m] ``keep_distance`` where every policy falls short of the following distance: the policies within
#: this of the least shortfall are kept (the expert counts a shortfall of 5 m as one unit of risk)
KEEP_DISTANCE_TOL = 1.0


def keeping_distance(
    internals: Any,
    obs: Observation,
    cfg: PlannerConfig,
    stop_lines: tuple[float, ...],
    sel: SelectionConfig | None = None,
    accel: np.ndarray | None = None,
) -> np.ndarray:
    """[N] bool: the policies that keep a safe following distance to the vehicle predicted ahead of them
    in their lane at 1..5 s: the expert's following check
    (:func:`~irlsim.planner.following.lane_outlook`'s shortfall with ``sel``, default the expert's: a
    headway of 0.8 s plus 2 m, and room to brake to that vehicle's speed at 3 m/s^2; vehicles at constant
    speed or, with ``accel``, braking on, standing at the stop line they reach; a vehicle the policy would
    drive into stays ahead).
    Where every policy falls short (a car cut in, a leader braked), those within ``KEEP_DISTANCE_TOL`` of
    the least shortfall. ``internals``: the planner's ``last`` of this cycle; ``stop_lines``: the road's
    (route positions [m]); ``accel``: the vehicles' accelerations (a braking one predicted braking on)."""
    sel = sel or SelectionConfig()
    shortfall, _ = lane_outlook(internals, obs, sel, cfg.dt, stop_lines, cfg.ego_width, cfg.v_target, accel)
    least = float(shortfall.min())
    return shortfall <= (least + KEEP_DISTANCE_TOL if least > 0.0 else 0.0)


def _narrowed(allowed: np.ndarray | None, keep: np.ndarray) -> np.ndarray | None:
    """``allowed`` (None: every policy) narrowed to ``keep``; unchanged when that leaves none."""
    both = keep if allowed is None else keep & allowed
    return both if both.any() else allowed


def planner_config_for(scenario_cfg: EpisodeConfig) -> PlannerConfig:
    """A PlannerConfig whose clocks, target speed and ego size match a EpisodeConfig."""
    return PlannerConfig(
        horizon=float(scenario_cfg.horizon),
        dt=float(scenario_cfg.step),
        cycle=float(scenario_cfg.cycle),
        v_target=float(scenario_cfg.ego_target_speed),
        ego_length=float(scenario_cfg.ego_length),
        ego_width=float(scenario_cfg.ego_width),
    )


def make_expert_driver(road: Road, scenario_cfg: EpisodeConfig) -> ExpertDriver:
    """Factory for the driver registry (:mod:`irlsim.rollout.drivers`)."""
    return ExpertDriver(road, planner_config_for(scenario_cfg))
