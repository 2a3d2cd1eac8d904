"""Drivers: ``plan(obs) -> Trajectory``. The built-in :class:`SimpleDriver` (the registry of drivers by name,
``DRIVERS``, lives a layer up in :mod:`irlsim.rollout.drivers`, next to the planner's expert).

A driver plans in the route frame (s along the loop, d lateral) and converts to world coordinates with
the road. Its trajectory starts at the ego's current state (index 0), at ``dt = step`` over the horizon;
the simulation executes the first ``cycle / step`` states of it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from irlsim.road import Road, wrap_angle
from irlsim.road.angles import atan2
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.types import EgoState, Observation, Trajectory


class Driver(Protocol):
    """Anything that turns an observation into the ego's next trajectory."""

    def plan(self, obs: Observation) -> Trajectory: ...


def frenet_trajectory(
    road: Road,
    ego: EgoState,
    dt: float,
    v: np.ndarray,
    d: np.ndarray,
    a: np.ndarray | None = None,
    d_dot: np.ndarray | None = None,
    d_ddot: np.ndarray | None = None,
) -> Trajectory:
    """A :class:`Trajectory` from a speed profile ``v`` [T] and lateral profile ``d`` [T] in the route frame.

    Index 0 must describe the ego's current state (``v[0] == ego.v``, ``d[0] == ego.d``); it is taken
    from ``ego`` verbatim so trajectories chain continuously. Arc length along the reference follows from
    the path speed: ds/dt = v cos(psi) / (1 - kappa d) with the heading error psi from dd/dt (trapezoidal
    integration, curvature evaluated on a first-pass s). Missing derivatives are taken by finite differences.
    """
    v = np.asarray(v, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    n = len(v)
    if a is None:
        a = np.gradient(v, dt) if n > 1 else np.zeros(n)
    if d_dot is None:
        d_dot = np.gradient(d, dt) if n > 1 else np.zeros(n)
    if d_ddot is None:
        d_ddot = np.gradient(d_dot, dt) if n > 1 else np.zeros(n)
    # ds/dt on the reference: path speed minus the lateral part, scaled for the offset on curves
    lon = np.sqrt(np.maximum(v**2 - d_dot**2, 0.0))
    s = ego.s + np.concatenate([[0.0], np.cumsum(0.5 * (lon[1:] + lon[:-1]) * dt)])
    for _ in range(2):  # curvature depends on s: two fixed-point passes are plenty at dt = 0.1 s
        s_dot = lon / np.maximum(1.0 - road.curvature(s) * d, 0.2)
        s = ego.s + np.concatenate([[0.0], np.cumsum(0.5 * (s_dot[1:] + s_dot[:-1]) * dt)])
    x, y = road.to_xy(s, d)
    psi = atan2(d_dot, np.maximum(lon, 1e-3))
    yaw = wrap_angle(road.heading(s) + psi)
    lane = road.lane_of_d(d)
    yaw = np.asarray(yaw)
    v, d = v.copy(), d.copy()
    a, d_dot, d_ddot = (np.array(z, dtype=np.float64) for z in (a, d_dot, d_ddot))
    lane = np.asarray(lane, dtype=np.int8)
    for arr, value in (
        (x, ego.x),
        (y, ego.y),
        (yaw, ego.yaw),
        (s, ego.s),
        (v, ego.v),
        (a, ego.a),
        (d, ego.d),
        (d_dot, ego.d_dot),
        (d_ddot, ego.d_ddot),
        (lane, ego.lane),
    ):
        arr[0] = value  # index 0 is the ego's state, verbatim
    return Trajectory(
        t0=ego.t,
        dt=dt,
        x=x,
        y=y,
        yaw=yaw,
        v=v,
        a=a,
        s=s,
        d=d,
        d_dot=d_dot,
        d_ddot=d_ddot,
        lane=lane,
    )


class SimpleDriver:
    """Lane keeping at the target speed, IDM following of the leader in its lane, full stop at stop lines.

    Each cycle it picks one longitudinal acceleration (the minimum of the IDM acceleration towards the
    target speed / leader and the constant deceleration that stops the front bumper ``stop_margin``
    before the next active stop line) and holds it over the horizon; lateral motion is a critically
    damped approach to the current lane's centre. Closed form over time, no loop over steps. Once the
    ego has stood still before the line, the simulation moves ``obs.stop_s`` on and the driver goes.
    """

    def __init__(
        self,
        road: Road,
        cfg: EpisodeConfig,
        *,
        a_max: float = 1.5,
        b_comf: float = 2.0,
        b_max: float = 6.0,
        time_gap: float = 1.5,
        min_gap: float = 2.5,
        stop_margin: float = 1.0,
        stop_brake: float = 1.5,
        lateral_rate: float = 0.8,
    ):
        self.road, self.cfg = road, cfg
        self.a_max = a_max  # [m/s^2] IDM maximum acceleration
        self.b_comf = b_comf  # [m/s^2] IDM comfortable deceleration
        self.b_max = b_max  # [m/s^2] hardest braking
        self.time_gap = time_gap  # [s] IDM time headway
        self.min_gap = min_gap  # [m] IDM standstill gap
        self.stop_margin = stop_margin  # [m] stop this far before the stop line
        self.stop_brake = stop_brake  # [m/s^2] start braking for a stop line when this deceleration is needed
        self.lateral_rate = lateral_rate  # [1/s] critically damped lane-centre approach
        self.n = cfg.horizon_steps + 1
        self.tau = np.arange(self.n) * cfg.step  # [T] time since the cycle began [s]

    def _leader(self, obs: Observation) -> tuple[float, float] | None:
        """(gap [m] from the ego's front to the leader's rear, leader speed [m/s]) in the ego's lane."""
        veh = obs.vehicles
        if veh.count == 0:
            return None
        ds = (veh.s - obs.ego.s) % obs.lap_length
        same = np.abs(veh.d - obs.ego.d) < 0.5 * self.road.lane_width + 0.4
        gap = ds - veh.length
        ok = same & (ds > 0) & (ds < 250.0) & (gap > -2.0)
        if not ok.any():
            return None
        i = int(np.argmin(np.where(ok, gap, np.inf)))
        return float(gap[i]), float(veh.v[i])

    def acceleration(self, obs: Observation) -> float:
        """The cycle's longitudinal acceleration [m/s^2]."""
        ego, v0 = obs.ego, self.cfg.ego_target_speed
        v = ego.v
        acc = self.a_max * (1.0 - (v / v0) ** 4)
        lead = self._leader(obs)
        if lead is not None:
            gap, v_lead = lead
            s_star = self.min_gap + max(
                0.0, v * self.time_gap + v * (v - v_lead) / (2 * np.sqrt(self.a_max * self.b_comf))
            )
            acc = self.a_max * (1.0 - (v / v0) ** 4 - (s_star / max(gap, 0.1)) ** 2)
        dist = obs.stop_s - self.stop_margin - ego.s
        if np.isfinite(dist) and dist < 150.0:
            if dist <= 0.05:
                acc = min(acc, -self.b_max)  # at (or past) the stop point: stand still
            else:
                need = v * v / (2.0 * dist)
                if need >= self.stop_brake:  # brake at the constant rate that ends exactly at the stop point
                    acc = min(acc, -need)
        return float(np.clip(acc, -self.b_max, self.a_max))

    def plan(self, obs: Observation) -> Trajectory:
        ego = obs.ego
        acc = self.acceleration(obs)
        tau = self.tau
        v_cap = max(ego.v, self.cfg.ego_target_speed)
        v = np.clip(ego.v + acc * tau, 0.0, v_cap)
        a = np.where((v > 0.0) & (v < v_cap) | (tau == 0), acc, 0.0)
        # lateral: critically damped towards the lane centre, continuous in d and dd/dt
        road = self.road
        lane = int(np.clip(np.floor(ego.d / road.lane_width + road.n_lanes / 2), 0, road.n_lanes - 1))
        dc = float(self.road.lane_center(lane))
        w = self.lateral_rate
        e0, e0_dot = ego.d - dc, ego.d_dot
        c1 = e0_dot + w * e0
        ex = np.exp(-w * tau)
        d = dc + (e0 + c1 * tau) * ex
        d_dot = (c1 - w * (e0 + c1 * tau)) * ex
        d_ddot = (-2 * w * c1 + w * w * (e0 + c1 * tau)) * ex
        # a standing car does not move sideways
        d_dot = np.where(v > 0.05, d_dot, 0.0)
        d = ego.d + np.concatenate([[0.0], np.cumsum(0.5 * (d_dot[1:] + d_dot[:-1]) * self.cfg.step)])
        return frenet_trajectory(self.road, ego, self.cfg.step, v, d, a=a, d_dot=d_dot, d_ddot=d_ddot)


class SumoDriver:
    """SUMO's own driver model drives the ego (Krauss car following, its lane changes, junction rules,
    the road's speed limits, at most ``ego_target_speed``): the reference the planner's speed is measured
    against on a scenario. Its trajectory only marks the cycle ``by_sumo``; the simulation executes none
    of its states."""

    def __init__(self, road: Road, cfg: EpisodeConfig):
        self.road = road
        self.n = cfg.horizon_steps + 1
        self.dt = cfg.step

    def plan(self, obs: Observation) -> Trajectory:
        e = obs.ego
        full = {k: np.full(self.n, float(getattr(e, k))) for k in ("x", "y", "yaw", "v", "a", "s", "d")}
        zero = np.zeros(self.n)
        lane = np.full(self.n, e.lane, dtype=np.int8)
        return Trajectory(t0=e.t, dt=self.dt, d_dot=zero, d_ddot=zero.copy(), lane=lane, by_sumo=True, **full)
