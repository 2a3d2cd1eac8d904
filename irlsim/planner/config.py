"""Planner configuration: one frozen, validated dataclass (SI units inside; units in every comment).

Load from TOML with ``irlsim.config.load_config(PlannerConfig, path)``; unknown keys are an error.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from irlsim import FEATURE_SETS
from irlsim.config import STORED_IF_SET, require, require_memory

#: [bytes] memory one policy of a planning cycle takes, an upper estimate: the planner's peak is 4.8-5.7 KB
#: per policy (tracemalloc over planner.plan at N = 1,000 and 4,000), collection buffers a row group of 64
#: cycles at ~280 B per policy (~18 KB) on top; rounded up. N x this must fit in the available memory.
PLANNER_BYTES_PER_POLICY = 32_768


@dataclass(frozen=True)
class PlannerConfig:
    """Sampling, feasibility and feature parameters of the reward-agnostic planner."""

    n_policies: int = 2500
    """exact number of policies per cycle (datasets need a fixed count): subsampled or padded to it"""
    horizon: float = 5.0
    """[s] planning horizon"""
    dt: float = 0.1
    """[s] trajectory step (the simulation step)"""
    cycle: float = 0.2
    """[s] planning cycle: the simulator executes cycle / dt steps, then replans"""
    n_control_points: int = 10
    """K time-equidistant control points at t = horizon * k / K, k = 1..K"""
    gamma: float = 0.98
    """discount per trajectory step in the path integrals f = sum_t gamma^t f_t dt"""
    stage_split: float = 2.5
    """[s] the second action stage starts here (two stages: [0, split], [split, horizon])"""

    # ---- longitudinal feasibility and sampling
    a_max: float = 2.5
    """[m/s^2] largest longitudinal acceleration"""
    a_min: float = -6.0
    """[m/s^2] strongest longitudinal deceleration (emergency braking)"""
    v_max: float = 25.0
    """[m/s] no policy exceeds this speed (90 km/h)"""
    v_target: float = 70.0 / 3.6
    """[m/s] the ego's target velocity (70 km/h)"""
    accel_ramp: float = 1.0
    """[s] smooth (cubic smoothstep) transition time from one acceleration to the next"""
    lon_split: float = field(default=0.0, metadata={STORED_IF_SET: True})
    """[s] the second longitudinal action starts here (0: at ``stage_split``, as the lateral one). A
    shorter first action lets a policy brake or speed up briefly and then hold, as a human driver does"""
    accels_stage1: tuple[float, ...] = (-6.0, -4.0, -3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5)
    """[m/s^2] target accelerations sampled in stage 1 (a 'reach v_target' action is added)"""
    accels_stage2: tuple[float, ...] = (-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0)
    """[m/s^2] target accelerations sampled in stage 2 (a 'reach v_target' action is added)"""
    stop_margin: float = 1.0
    """[m] the stop profiles bring the front bumper to rest this far before an active stop line"""
    stop_line_gap: float = 0.2
    """[m] when the ego can no longer stand at the stop point comfortably (closer to it than
    v^2 / (2 stop_decel_comfort), or past it) while the line itself is still ahead, stop profiles also
    bring the front bumper to rest this far before the line (0 = off). Without them the only standing
    policies in the last metre brake at the limit, and a policy that creeps over looks smoother (learned
    rewards found that in closed loop)"""
    stop_decel_comfort: float = 2.5
    """[m/s^2] comfortable braking: the velocity feature's stop-line reference speed sqrt(2 b dist), and
    the reach below which the sampler adds stops at the line itself (``stop_line_gap``)"""
    stop_reach: float = 150.0
    """[m] an active stop line closer than this gets stop profiles and a zero target speed"""
    v_stopped: float = 0.1
    """[m/s] below this speed the ego counts as standing (full stop)"""

    # ---- lateral feasibility and sampling
    lat_durations: tuple[float, ...] = (2.5, 3.5, 4.5)
    """[s] durations of the stage-1 lateral transitions (quintics to the target offset)"""
    swerves: tuple[float, ...] = (0.8, 1.6)
    """[m] partial swerves: stage-1 targets this far left / right of the current lane centre"""
    a_lat_max: float = 5.0
    """[m/s^2] largest total lateral acceleration |d_ddot + v^2 kappa|"""
    yaw_speed_floor: float = 1.0
    """[m/s] the heading to the lane is atan2(d_dot, max(v, this)): below this speed a lateral drift
    (at most 0.05 m/s at a standstill, see ``max_slip``) moves the car sideways instead of turning its body"""
    max_slip: float = 0.35
    """[rad] largest heading to the lane direction: |d_dot| <= tan(max_slip) v + 0.05 m/s"""
    exit_reach: float = 120.0
    """[m] exit-taking policies are sampled when an exit starts within this distance ahead"""

    # ---- vehicles and features
    ego_length: float = 4.5
    """[m] ego length (sumo_net/vtypes.add.xml)"""
    ego_width: float = 1.8
    """[m] ego width"""
    cull_distance: float = 120.0
    """[m] vehicles farther than this (route-frame |ds| at t = 0) are ignored by proximity and labels"""
    collision_margin_lon: float = 0.5
    """[m] extra longitudinal margin of the predicted-collision label"""
    collision_margin_lat: float = 0.25
    """[m] extra lateral margin of the predicted-collision label (covers the yaw of a lane change)"""
    proximity_sigma_s: float = 1.0
    """[m] proximity: the safety distance D at standstill (bumper gap; D grows with speed, see below)"""
    proximity_headway: float = 0.8
    """[s] proximity: time headway in D when the ego is behind the other vehicle (at the ego's speed)"""
    proximity_rear_headway: float = 0.5
    """[s] proximity: time headway in D when the ego is ahead (at the other vehicle's speed)"""
    proximity_decel: float = 4.0
    """[m/s^2] proximity: braking assumed in D's closing term max(0, v_behind^2 - v_ahead^2) / (2 b)"""
    proximity_sigma_d: float = 1.6
    """[m] lateral length scale of the proximity Gaussian (centre to centre)"""
    proximity_overlap: float = 50.0
    """[-] proximity: extra cost per second that the boxes are predicted to overlap (the collision
    label's test), on top of the Gaussian closeness (at most 1 per second)"""
    safety_gap: float = 2.0
    """[m] expert safety signal ('unsafe'): bumper gap kept to a predicted vehicle ahead, plus headway"""
    safety_headway: float = 0.8
    """[s] expert safety signal: time headway to a predicted vehicle ahead (at the ego's speed)"""
    safety_rear_headway: float = 0.3
    """[s] expert safety signal: time headway left to a predicted vehicle behind (at its speed)"""
    safety_time: float = 3.0
    """[s] the expert safety signal looks this far ahead (later conflicts are left to later cycles)"""
    safety_margin_lat: float = 0.5
    """[m] expert safety signal: extra lateral margin"""
    creep_speed: float = 2.0
    """[m/s] creep counts speeds up to this near an active stop line"""
    creep_zone: float = 12.0
    """[m] creep counts within this distance before an active stop line"""
    edge_margin: float = 0.5
    """[m] road_edge costs the ego's side closer than this to the drivable edge"""
    mission_distance: float = 300.0
    """[m] mission_lane urgency = min(urgency_max, mission_distance / remaining distance)"""
    mission_urgency_max: float = 10.0
    """[-] cap of the mission_lane urgency"""
    mission_event: float = 2.0
    """[s] mission_lane's event at the checkpoint: where a policy passes its target checkpoint (step
    tc) it adds gamma^tc * mission_urgency_max * mission_event * |d_tc - d_req| / LW, the lanes away at the
    instant the simulator checks the lane (0 = off: the path integral alone, the paper's feature). Without
    it a lane change started 15-20 m before the checkpoint costs almost nothing (urgency is 0 past it) and
    learned rewards leave the required lane just too early: PACNN+S met 22/40 checkpoints in lane on the
    development seeds without it, 40/40 with it (docs/results/closed-loop-fixes.md)"""
    progress_lookahead: float = 200.0
    """[m] progress measures the distance to a goal this far beyond the target checkpoint"""
    feature_set: str = field(default="paper", metadata={STORED_IF_SET: True})
    """the features computed (``irlsim.FEATURE_SETS``): "paper", the 15; "lanes", the 15 and the
    lane-preference pair (lane_right, lane_left), for drivers who keep to a side (docs/design/planner.md)"""

    @property
    def feature_names(self) -> tuple[str, ...]:
        """The names of the features this planner computes, in their column order."""
        return FEATURE_SETS[self.feature_set]

    @property
    def n_steps(self) -> int:
        """T: states per trajectory, t = 0 included."""
        return int(round(self.horizon / self.dt)) + 1

    @property
    def lon_stage_split(self) -> float:
        """[s] where the second longitudinal action starts (``lon_split``, else ``stage_split``)."""
        return self.lon_split or self.stage_split

    @property
    def cycle_steps(self) -> int:
        return int(round(self.cycle / self.dt))

    def validate(self) -> None:
        require(self.n_policies >= 1, f"planner.n_policies must be >= 1, got {self.n_policies}")
        require_memory(
            f"planner.n_policies={self.n_policies}",
            self.n_policies * PLANNER_BYTES_PER_POLICY,
            "use fewer policies per cycle (the paper uses 2,500)",
        )
        require(self.dt > 0 and self.horizon > self.dt, "planner.horizon must exceed planner.dt > 0")
        require(
            abs(self.horizon / self.dt - round(self.horizon / self.dt)) < 1e-6,
            "planner.horizon must be a multiple of planner.dt",
        )
        require(
            abs(self.cycle / self.dt - round(self.cycle / self.dt)) < 1e-6 and self.cycle >= self.dt,
            "planner.cycle must be a positive multiple of planner.dt",
        )
        k = self.n_control_points
        require(
            k >= 1 and (self.n_steps - 1) % k == 0,
            f"planner.n_control_points ({k}) must divide horizon / dt ({self.n_steps - 1})",
        )
        require(0 < self.gamma <= 1, f"planner.gamma must be in (0, 1], got {self.gamma}")
        require(0 < self.stage_split < self.horizon, "planner.stage_split must lie inside the horizon")
        require(self.a_min < 0 < self.a_max, "planner.a_min < 0 < planner.a_max")
        for a in self.accels_stage1 + self.accels_stage2:
            require(self.a_min <= a <= self.a_max, f"planner accelerations must lie in [a_min, a_max]: {a}")
        require(0 < self.v_target <= self.v_max, "planner.v_target must be in (0, v_max]")
        require(self.accel_ramp > 0, "planner.accel_ramp must be > 0")
        require(
            self.lon_split == 0 or 0 < self.lon_split < self.horizon,
            f"planner.lon_split must be 0 (at stage_split) or inside the horizon, got {self.lon_split}",
        )
        require(
            all(t > 0 for t in self.lat_durations) and len(self.lat_durations) >= 1,
            "planner.lat_durations must be positive",
        )
        require(self.a_lat_max > 0 and self.max_slip > 0, "planner lateral limits must be > 0")
        require(self.yaw_speed_floor > 0, "planner.yaw_speed_floor must be > 0")
        require(self.ego_length > 0 and self.ego_width > 0, "planner ego size must be > 0")
        require(self.stop_line_gap >= 0, f"planner.stop_line_gap must be >= 0 m, got {self.stop_line_gap}")
        require(
            self.feature_set in FEATURE_SETS,
            f"planner.feature_set must be one of {', '.join(FEATURE_SETS)}, got {self.feature_set!r}",
        )
        require(self.mission_event >= 0, f"planner.mission_event must be >= 0 s, got {self.mission_event}")
        require(self.proximity_sigma_s > 0 and self.proximity_sigma_d > 0, "proximity sigmas must be > 0")
        require(
            self.proximity_headway >= 0
            and self.proximity_rear_headway >= 0
            and self.proximity_decel > 0
            and self.proximity_overlap >= 0,
            "planner.proximity_headway, proximity_rear_headway, proximity_overlap must be >= 0 and "
            "proximity_decel > 0",
        )
