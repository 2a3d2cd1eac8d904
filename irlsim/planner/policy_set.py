"""The record a planning cycle produces: a set of sampled policies, sorted by progress ascending."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from irlsim import N_FEATURES

#: labels stored per policy, in this order
LABEL_NAMES: tuple[str, ...] = ("collision", "offroad", "exit")


class WorldSource(Protocol):
    """Computes the world-frame arrays of a PolicySet on first access (see :class:`LazyWorld`)."""

    shape: tuple[int, int]

    def xy(self) -> tuple[np.ndarray, np.ndarray]: ...

    def yaw(self) -> np.ndarray: ...


class LazyWorld:
    """Marker for ``PolicySet(x=..., y=..., yaw=...)``: pass ``LazyWorld(source)`` for all three and
    the arrays are computed by ``source`` when first read (x and y together), then kept. The planner
    uses it: most consumers (the dataset writer, the expert) never read x / y, and yaw only sometimes."""

    __slots__ = ("source",)

    def __init__(self, source: WorldSource):
        self.source = source


class _WorldArray:
    """Data descriptor of the x / y / yaw fields: a plain array, or computed lazily from a LazyWorld.

    Reading always yields an ``np.ndarray`` [N, T] float64 (the public contract is unchanged); the
    dataclass machinery (``__init__``, ``fields``, ``replace``, ``==``, pickling) sees ordinary fields.
    """

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.slot = "_" + name

    def __get__(self, obj: Any, owner: type | None = None) -> np.ndarray:
        if obj is None:
            raise AttributeError(self.name)  # no default: a required dataclass field
        val = obj.__dict__[self.slot]
        if isinstance(val, LazyWorld):
            src = val.source
            if self.name == "yaw":
                obj.__dict__["_yaw"] = src.yaw()
            else:
                x, y = src.xy()
                obj.__dict__["_x"], obj.__dict__["_y"] = x, y
            val = obj.__dict__[self.slot]
        return val

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.slot] = value

    @staticmethod
    def shape_of(obj: Any, name: str) -> tuple[int, ...]:
        val = obj.__dict__["_" + name]
        return tuple(val.source.shape) if isinstance(val, LazyWorld) else tuple(np.shape(val))


@dataclass(frozen=True)
class PolicySet:
    """One planning cycle's policies. N policies, T = round(horizon / dt) + 1 states (t = 0 is now).

    Route frame: ``s`` is arc length along the loop reference line [m], unwrapped (it may exceed the
    lap length when a policy crosses the start line), ``d`` the lateral offset, positive to the left [m].
    Lane 0 is the outer (rightmost) lane, 2 the inner one; lane -1 is an exit ramp or off the road.

    Arrays (shapes asserted in ``__post_init__``):
        x, y, yaw, v, s, d: [N, T] float64  world position [m], heading [rad, ENU, 0 = east, CCW],
                                             speed [m/s], route-frame position [m]; x, y and yaw may be
                                             given as a ``LazyWorld`` and are then computed on first
                                             read (the planner does this: they cost ~40 % of a cycle)
        lane:               [N, T] int8
        progress:           [N] float32      route progress gained over the horizon [m]; sort key
        features:           [N, F] float32  path-integral feature costs, >= 0 (F = 15, irlsim.FEATURE_NAMES,
                            or a larger set's: irlsim.FEATURE_SETS, the planner's ``feature_set``)
        control_points:     [N, K, 3] float32  (lateral offset to the ego [m], yaw to the ego [rad],
                                               progress along the route [m]) at K time-equidistant points
        actions:            [N, K, 2] float32  (longitudinal acceleration [m/s^2], lateral velocity [m/s])
        labels:             [N, 3] bool      predicted collision, off-road, exit taken (LABEL_NAMES)
    """

    t: float
    x: np.ndarray = _WorldArray()  # type: ignore[assignment]
    y: np.ndarray = _WorldArray()  # type: ignore[assignment]
    yaw: np.ndarray = _WorldArray()  # type: ignore[assignment]
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
        n, t = self.v.shape
        for name in ("x", "y", "yaw"):
            shape = _WorldArray.shape_of(self, name)
            assert shape == (n, t), f"{name}: {shape} != {(n, t)}"
        for name in ("s", "d", "lane"):
            assert getattr(self, name).shape == (n, t), f"{name}: {getattr(self, name).shape} != {(n, t)}"
        assert self.progress.shape == (n,), self.progress.shape
        assert self.features.shape[0] == n and self.features.shape[1] >= N_FEATURES, self.features.shape
        assert self.control_points.ndim == 3 and self.control_points.shape[0] == n
        assert self.control_points.shape[2] == 3
        assert self.actions.shape == (n, self.control_points.shape[1], 2), self.actions.shape
        assert self.labels.shape == (n, len(LABEL_NAMES)), self.labels.shape

    def __getstate__(self) -> dict:
        """Pickling / copying materialises the lazy x / y / yaw (the source holds the road)."""
        for name in ("x", "y", "yaw"):
            getattr(self, name)
        return dict(self.__dict__)

    @property
    def n_policies(self) -> int:
        return int(self.v.shape[0])

    @property
    def n_steps(self) -> int:
        return int(self.v.shape[1])

    def value(self, theta: np.ndarray) -> np.ndarray:
        """V(pi) = -theta^T f^pi for every policy: [N]."""
        return -(self.features.astype(np.float64) @ np.asarray(theta, dtype=np.float64))
