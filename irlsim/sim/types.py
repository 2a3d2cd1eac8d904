"""Frozen records that cross the simulator / driver boundary. SI units; yaw ENU [rad]."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class EgoState:
    """The ego's kinematic state. Position is the front-bumper centre (as SUMO's moveToXY uses it).

    ``s`` is the unwrapped route-frame arc length [m] (keeps growing over laps; ``s % road.lap_length``
    is the position on the loop), ``d`` the lateral offset [m], positive to the left.
    """

    t: float  # [s] simulation time
    x: float  # [m]
    y: float  # [m]
    yaw: float  # [rad]
    v: float  # [m/s] speed along the path, >= 0
    a: float  # [m/s^2] longitudinal acceleration
    s: float  # [m] unwrapped
    d: float  # [m]
    d_dot: float  # [m/s] lateral velocity in the route frame (dd/dt)
    d_ddot: float  # [m/s^2]
    lane: int  # loop lane 0..2, -1 off the loop


#: [m] spacing of the points of a vehicle's way ahead (:attr:`VehicleStates.path`, :mod:`irlsim.sim.intent`)
PATH_STEP = 1.0


@dataclass(frozen=True)
class VehicleStates:
    """Other vehicles at one instant, M of them; every array is [M]. Position is the front-bumper centre."""

    ids: tuple[str, ...]
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray  # [m/s]
    s: np.ndarray  # [m] route frame, in [0, lap_length)
    d: np.ndarray  # [m]
    length: np.ndarray  # [m]
    width: np.ndarray  # [m]
    #: [M, P, 2] xy [m] of each vehicle's way ahead inside a junction into the ego's route, every metre
    #: from its front, NaN where it has none; None where no vehicle has one (:mod:`irlsim.sim.intent`)
    path: np.ndarray | None = None
    #: [M, T, 2] (s, d) [m] displacement of each vehicle's box over the planner's horizon where it is
    #: predicted along its path, NaN elsewhere (the planner's: ``planner.route_frame_boxes``)
    motion: np.ndarray | None = None

    def __post_init__(self) -> None:
        m = len(self.ids)
        for name in ("x", "y", "yaw", "v", "s", "d", "length", "width"):
            assert getattr(self, name).shape == (m,), f"{name}: {getattr(self, name).shape} != ({m},)"
        for name in ("path", "motion"):
            a = getattr(self, name)
            assert a is None or (a.ndim == 3 and a.shape[0] == m and a.shape[2] == 2), f"{name}: {a.shape}"

    def subset(self, keep: np.ndarray) -> VehicleStates:
        """The vehicles where the [M] bool ``keep`` is true, in their order."""
        arrays = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "ids"}
        kept: dict[str, Any] = {k: (a[keep] if a is not None else None) for k, a in arrays.items()}
        return VehicleStates(tuple(v for v, k in zip(self.ids, keep, strict=True) if k), **kept)

    @property
    def count(self) -> int:
        return len(self.ids)

    def boxes(self) -> np.ndarray:
        """[M, 5] (x, y, yaw, length, width) of every vehicle, front-bumper centre (the pictures' boxes)."""
        if not self.count:
            return np.zeros((0, 5))
        return np.stack([self.x, self.y, self.yaw, self.length, self.width], axis=1)

    @staticmethod
    def empty() -> VehicleStates:
        z = np.zeros(0)
        return VehicleStates((), z, z, z, z, z, z, z, z)


@dataclass(frozen=True)
class Observation:
    """What a driver sees at the start of a planning cycle."""

    ego: EgoState
    vehicles: VehicleStates
    target_checkpoint: int  # index into road.checkpoints: the route target (next checkpoint)
    target_s: float  # [m] unwrapped route position of the target checkpoint (> ego.s)
    # [m] unwrapped position of the next stop line the ego has not yet stopped at; inf if none within reach
    stop_s: float
    lap_length: float  # [m]
    info: dict = field(default_factory=dict)
    #: the stop at ``stop_s`` is a traffic light showing red or yellow: no crossing until it turns green,
    #: whether the ego stood or not (a stop sign is passed once the ego has stood)
    stop_red: bool = False


@dataclass(frozen=True)
class Trajectory:
    """A timed ego trajectory from t0 at step dt; every array is [T], index 0 = the current state.

    The simulator executes states 1..k of it (k = planning cycle / dt) and the next cycle starts from
    the last executed state, so position, velocity and acceleration stay continuous.
    """

    t0: float  # [s]
    dt: float  # [s]
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray
    a: np.ndarray
    s: np.ndarray  # unwrapped [m]
    d: np.ndarray
    d_dot: np.ndarray
    d_ddot: np.ndarray
    lane: np.ndarray
    #: SUMO's own driver model drives the ego through this cycle (the states are not executed): the
    #: reference run the planner's speed is compared with (``irlsim sim --driver sumo``)
    by_sumo: bool = False

    def state(self, j: int) -> EgoState:
        return EgoState(
            t=self.t0 + j * self.dt,
            x=float(self.x[j]),
            y=float(self.y[j]),
            yaw=float(self.yaw[j]),
            v=float(self.v[j]),
            a=float(self.a[j]),
            s=float(self.s[j]),
            d=float(self.d[j]),
            d_dot=float(self.d_dot[j]),
            d_ddot=float(self.d_ddot[j]),
            lane=int(self.lane[j]),
        )
