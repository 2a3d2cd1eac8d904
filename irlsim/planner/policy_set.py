"""The record a planning cycle produces: a set of sampled policies, sorted by progress ascending."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from irlsim import N_FEATURES

#: labels stored per policy, in this order
LABEL_NAMES: tuple[str, ...] = ("collision", "offroad", "exit")


@dataclass(frozen=True)
class PolicySet:
    """One planning cycle's policies. N policies, T = round(horizon / dt) + 1 states (t = 0 is now).

    Route frame: ``s`` is arc length along the loop reference line [m], unwrapped (it may exceed the
    lap length when a policy crosses the start line), ``d`` the lateral offset, positive to the left [m].
    Lane 0 is the outer (rightmost) lane, 2 the inner one; lane -1 is an exit ramp or off the road.

    Arrays (shapes asserted in ``__post_init__``):
        x, y, yaw, v, s, d: [N, T] float64  world position [m], heading [rad, ENU, 0 = east, CCW],
                                             speed [m/s], route-frame position [m]
        lane:               [N, T] int8
        progress:           [N] float32      route progress gained over the horizon [m]; sort key
        features:           [N, 15] float32  path-integral feature costs, >= 0 (names: irlsim.FEATURE_NAMES)
        control_points:     [N, K, 3] float32  (lateral offset to the ego [m], yaw to the ego [rad],
                                               progress along the route [m]) at K time-equidistant points
        actions:            [N, K, 2] float32  (longitudinal acceleration [m/s^2], lateral velocity [m/s])
        labels:             [N, 3] bool      predicted collision, off-road, exit taken (LABEL_NAMES)
    """

    t: float
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray
    s: np.ndarray
    d: np.ndarray
    lane: np.ndarray
    progress: np.ndarray
    features: np.ndarray
    control_points: np.ndarray
    actions: np.ndarray
    labels: np.ndarray

    def __post_init__(self) -> None:
        n, t = self.x.shape
        for name in ("y", "yaw", "v", "s", "d", "lane"):
            assert getattr(self, name).shape == (n, t), f"{name}: {getattr(self, name).shape} != {(n, t)}"
        assert self.progress.shape == (n,), self.progress.shape
        assert self.features.shape == (n, N_FEATURES), self.features.shape
        assert self.control_points.ndim == 3 and self.control_points.shape[0] == n
        assert self.control_points.shape[2] == 3
        assert self.actions.shape == (n, self.control_points.shape[1], 2), self.actions.shape
        assert self.labels.shape == (n, len(LABEL_NAMES)), self.labels.shape

    @property
    def n_policies(self) -> int:
        return int(self.x.shape[0])

    @property
    def n_steps(self) -> int:
        return int(self.x.shape[1])

    def value(self, theta: np.ndarray) -> np.ndarray:
        """V(pi) = -theta^T f^pi for every policy: [N]."""
        return -(self.features.astype(np.float64) @ np.asarray(theta, dtype=np.float64))
