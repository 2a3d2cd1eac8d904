"""A split as arrays: :class:`SplitTensors`, the record the reader gives and training reads.

The arrays of one dataset folder are read-only memory maps of its cache (:mod:`irlsim.data.reader`);
an aggregate's per-policy arrays are :class:`~irlsim.data.npy.RowConcat` views over its folders' memory
maps (:mod:`irlsim.data.aggregate`), indexed by rows like an array.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from irlsim import N_FEATURES
from irlsim.data.lz4rows import Lz4Rows
from irlsim.data.npy import RowConcat
from irlsim.data.schema import DEMO_EXPERT, DEMO_SOURCES
from irlsim.planner.policy_set import LABEL_NAMES

#: an array [C, ...], compressed rows (a cache's per-policy arrays) or a view of several along their rows
#: (what an aggregate's split holds)
Rows = np.ndarray | RowConcat | Lz4Rows


@dataclass(frozen=True)
class SplitTensors:
    """A split as arrays; C cycles ordered by (episode, cycle), N policies progress-sorted, K control points.

    Arrays (read-only memory maps, or for an aggregate's per-policy arrays ``RowConcat`` views over them;
    shapes checked on construction):
        features:       [C, N, F] float32  path-integral feature costs (the dataset's feature_names)
        control_points: [C, N, K, 3] float32  (lateral offset [m], yaw [rad], progress [m]) to the ego
        actions:        [C, N, K, 2] float32  (longitudinal acceleration [m/s^2], lateral velocity [m/s])
        distances:      [C, N] float32      d(zeta, pi) [m]; NaN where the window is incomplete
        demo_index:     [C] int64           index of pi^D, -1 = no demonstration (do not train on it)
        demo_distance:  [C] float32         d(zeta, pi^D) [m], NaN = no demonstration
        episode:        [C] int32
        cycle:          [C] int32
        executed_index: [C] int32           index of the policy the driver executed
        labels:         [C, N, 3] bool      collision, offroad, exit (LABEL_NAMES)
        demo_source:    [C] int8            index into DEMO_SOURCES: 0 odometry (projected), 1 expert (DAgger)
    """

    features: Rows
    control_points: Rows
    actions: Rows
    distances: Rows
    demo_index: np.ndarray
    demo_distance: np.ndarray
    episode: np.ndarray
    cycle: np.ndarray
    executed_index: np.ndarray
    labels: Rows
    demo_source: np.ndarray = None  # type: ignore[assignment]  # None: all odometry (code 0)

    def __post_init__(self) -> None:
        c, n = self.distances.shape
        if self.demo_source is None:
            object.__setattr__(self, "demo_source", np.zeros(c, np.int8))
        k = self.control_points.shape[2] if self.control_points.ndim == 4 else -1
        nf = self.features.shape[-1] if self.features.ndim == 3 else N_FEATURES  # the feature set's F
        expected = {
            "features": ((c, n, nf), np.float32),
            "control_points": ((c, n, k, 3), np.float32),
            "actions": ((c, n, k, 2), np.float32),
            "distances": ((c, n), np.float32),
            "demo_index": ((c,), np.int64),
            "demo_distance": ((c,), np.float32),
            "episode": ((c,), np.int32),
            "cycle": ((c,), np.int32),
            "executed_index": ((c,), np.int32),
            "labels": ((c, n, len(LABEL_NAMES)), np.bool_),
            "demo_source": ((c,), np.int8),
        }
        for name, (shape, dtype) in expected.items():
            arr = getattr(self, name)
            if arr.shape != shape or arr.dtype != dtype:
                raise ValueError(
                    f"SplitTensors.{name}: {arr.dtype}{list(arr.shape)}, "
                    f"expected {dtype.__name__}{list(shape)}"
                )

    @property
    def n_cycles(self) -> int:
        return int(self.distances.shape[0])

    @property
    def n_policies(self) -> int:
        return int(self.distances.shape[1])

    @property
    def expert_labelled(self) -> np.ndarray:
        """[C] bool: cycles whose demonstration is the expert's selection (DAgger), not projected odometry."""
        return np.asarray(self.demo_source == DEMO_SOURCES.index(DEMO_EXPERT))

    @property
    def has_demo(self) -> np.ndarray:
        """[C] bool: cycles that have a demonstration (the ones to train and evaluate on)."""
        return np.asarray(self.demo_index >= 0)

    def head(self, n: int) -> SplitTensors:
        """The first n cycles (views, no copy)."""
        return SplitTensors(**{f.name: getattr(self, f.name)[:n] for f in fields(self)})


#: the arrays of a SplitTensors (a cache holds each per-cycle one as <name>.npy, each per-policy one as
#: LZ4-compressed rows: irlsim.data.lz4rows)
ARRAY_NAMES = tuple(f.name for f in fields(SplitTensors))
#: the per-policy arrays [C, N, ...] (the bulk of a cache; an aggregate views them, copies the others)
POLICY_ARRAYS = ("features", "control_points", "actions", "distances", "labels")


def policy_array_specs(
    c: int, n: int, k: int, n_features: int = N_FEATURES
) -> dict[str, tuple[tuple[int, ...], Any]]:
    """{name: (shape, dtype)} of the per-policy arrays of a split of ``c`` cycles of ``n`` policies with
    ``k`` control points and ``n_features`` features each."""
    return {
        "features": ((c, n, n_features), np.float32),
        "control_points": ((c, n, k, 3), np.float32),
        "actions": ((c, n, k, 2), np.float32),
        "distances": ((c, n), np.float32),
        "labels": ((c, n, len(LABEL_NAMES)), np.bool_),
    }
