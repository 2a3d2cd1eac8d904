"""Write a dataset: one pair of Parquet files per episode, and the manifest (docs/design/data.md).

Collection drives an ``EpisodeWriter`` together with a ``DemoProjector``::

    proj = DemoProjector(lap_length=road.lap_length, horizon=cfg.horizon, dt=cfg.dt)
    with EpisodeWriter(dataset_dir, "train", episode) as writer:
        for each simulation step:
            proj.push_odometry(t, ego.s, ego.d, ego.yaw)
            if planning step:
                ps = planner.plan(state)                        # PolicySet
                proj.push_cycle(k, ps.t, ps.s, ps.d, ps.yaw)
                writer.add_cycle(k, ps, ego_dict, executed_index=i, target_checkpoint=c)
            writer.add_demos(proj.pop_ready())
        writer.add_demos(proj.finish())
    # leaving the ``with`` block without an exception calls close(); with one, abort()

Policies are streamed to a temporary file in row groups of whole cycles as soon as their demonstrations
are known, so memory stays bounded by the cycles still waiting for their window (plus one row group).
``close()`` renames the policies file first and writes the cycles file last: an existing cycles file means
the episode is complete (``episode_done``). Output bytes depend only on the inputs (no timestamps).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from irlsim import N_FEATURES
from irlsim.data.demos import Projection
from irlsim.data.layout import (
    episode_paths,
)
from irlsim.data.schema import (
    COMPRESSION,
    COMPRESSION_LEVEL,
    CYCLES_PER_ROW_GROUP,
    DEMO_ODOMETRY,
    DEMO_SOURCES,
    EGO_KEYS,
    N_CONTROL_POINTS,
    POLICIES_DICTIONARY_COLUMNS,
    POLICIES_FLOAT_COLUMNS,
    cycles_schema,
    policies_schema,
)
from irlsim.planner.policy_set import PolicySet
from irlsim.utils import atomic_path, naming


def _nearest(distances: np.ndarray) -> int:
    """The index of the smallest finite distance, 0 when none is finite."""
    d = np.asarray(distances, dtype=np.float64)
    return int(np.nanargmin(d)) if np.isfinite(d).any() else 0


def _policies_writer(path: Path, schema: pa.Schema) -> pq.ParquetWriter:
    return pq.ParquetWriter(
        str(path),
        schema,
        compression=COMPRESSION,
        compression_level=COMPRESSION_LEVEL,
        use_dictionary=list(POLICIES_DICTIONARY_COLUMNS),
        use_byte_stream_split=list(POLICIES_FLOAT_COLUMNS),
        write_statistics=True,
    )


@dataclass
class _Cycle:
    """A cycle waiting for its demonstration. Arrays as stored (float32, bool)."""

    cycle: int
    t: float
    ego: tuple[float, ...]  # EGO_KEYS order
    target_checkpoint: int
    executed_index: int
    situation: int
    features: np.ndarray  # [N, 15]
    control_points: np.ndarray  # [N, K, 3]
    actions: np.ndarray  # [N, K, 2]
    progress: np.ndarray  # [N]
    labels: np.ndarray  # [N, 3]
    demo: Projection | None = None


class EpisodeWriter:
    """Collects one episode's planning cycles and writes its two Parquet files atomically.

    Cycles must be added in increasing ``cycle`` order with a constant policy count N and control-point
    count K; demonstrations may arrive later and in any order. Usable as a context manager.
    """

    def __init__(
        self,
        dataset_dir: str | Path,
        split: str,
        episode: int,
        *,
        cycles_per_row_group: int = CYCLES_PER_ROW_GROUP,
        demo_source: str = DEMO_ODOMETRY,
        record: Mapping[str, Any] | None = None,
        n_features: int = N_FEATURES,
    ) -> None:
        if cycles_per_row_group < 1:
            raise ValueError(f"cycles_per_row_group must be >= 1, got {cycles_per_row_group}")
        if demo_source not in DEMO_SOURCES:
            raise ValueError(f"demo_source must be one of {DEMO_SOURCES}, got {demo_source!r}")
        self.demo_source = demo_source
        # the episode record (seed, config hash) each file's key-value metadata carries as irlsim.<key>
        self._meta = {f"irlsim.{k}".encode(): str(v).encode() for k, v in (record or {}).items()}
        self.episode = int(episode)
        self.cycles_path, self.policies_path = episode_paths(dataset_dir, split, episode)
        self.cycles_per_row_group = int(cycles_per_row_group)
        self._pending: list[_Cycle] = []
        self._by_cycle: dict[int, _Cycle] = {}
        self._rows: list[tuple[Any, ...]] = []  # cycles-table rows already flushed, in order
        self._n: int | None = None
        self._k: int | None = None
        self._f = int(n_features)  # F: the planner's feature set's size (every cycle's)
        self._last_cycle: int | None = None
        self._stack = ExitStack()
        self._pol_tmp: Path | None = None
        self._pol_writer: pq.ParquetWriter | None = None
        self._closed = False

    # -- input ---------------------------------------------------------------------------------------

    def add_cycle(
        self,
        cycle: int,
        policy_set: PolicySet,
        ego: Mapping[str, float],
        *,
        executed_index: int,
        target_checkpoint: int,
        situation: int = -1,
    ) -> None:
        """Add one planning cycle.

        Args:
            cycle: cycle index within the episode (strictly increasing).
            policy_set: the cycle's N progress-sorted policies; only features, control points, actions,
                progress and labels are kept (trajectories go to the ``DemoProjector``).
            ego: ego state at the cycle, keys ``x, y [m], yaw [rad], v [m/s], s, d [m], lane``.
            executed_index: progress-sorted index of the policy the driver executed; -1 for a driver
                that executes none of them (a SUMO demonstrator): the policy nearest to what it drove
                (the smallest demonstration distance, even beyond ``max_distance``; 0 where the horizon
                was not driven to its end) is recorded.
            target_checkpoint: index of the next route checkpoint.
            situation: the cycle's situation code (``irlsim.data.situations``), -1 = not labelled.
        """
        self._check_open()
        cycle = int(cycle)
        if self._last_cycle is not None and cycle <= self._last_cycle:
            raise ValueError(f"cycles must be added in increasing order: {cycle} after {self._last_cycle}")
        missing = [k for k in EGO_KEYS if k not in ego]
        if missing:
            raise ValueError(f"ego state lacks {missing}; expected keys {EGO_KEYS}")
        n, k = policy_set.n_policies, int(policy_set.control_points.shape[1])
        if int(policy_set.features.shape[1]) != self._f:
            raise ValueError(
                f"cycle {cycle}: {policy_set.features.shape[1]} features, the writer's are {self._f}"
            )
        if self._n is None:
            self._n, self._k = n, k
        elif (n, k) != (self._n, self._k):
            raise ValueError(
                f"cycle {cycle}: {n} policies x {k} control points, "
                f"the episode started with {self._n} x {self._k}"
            )
        if not -1 <= int(executed_index) < n:
            raise ValueError(f"cycle {cycle}: executed_index {executed_index} not in [-1, {n})")
        rec = _Cycle(
            cycle=cycle,
            t=float(policy_set.t),
            ego=tuple(float(ego[key]) for key in EGO_KEYS),
            target_checkpoint=int(target_checkpoint),
            executed_index=int(executed_index),
            situation=int(situation),
            features=np.asarray(policy_set.features, dtype=np.float32),
            control_points=np.asarray(policy_set.control_points, dtype=np.float32),
            actions=np.asarray(policy_set.actions, dtype=np.float32),
            progress=np.asarray(policy_set.progress, dtype=np.float32),
            labels=np.asarray(policy_set.labels, dtype=bool),
        )
        self._pending.append(rec)
        self._by_cycle[cycle] = rec
        self._last_cycle = cycle

    def add_demo(self, projection: Projection) -> None:
        """Attach a cycle's demonstration (from ``DemoProjector``); flushes complete row groups."""
        self._check_open()
        rec = self._by_cycle.get(int(projection.cycle_index))
        if rec is None:
            raise ValueError(f"demonstration for cycle {projection.cycle_index}, which is not pending")
        if np.shape(projection.distances) != (self._n,):
            raise ValueError(
                f"cycle {rec.cycle}: {np.shape(projection.distances)} distances, expected {self._n}"
            )
        rec.demo = projection
        self._flush(final=False)

    def add_demos(self, projections: Iterable[Projection]) -> None:
        for p in projections:
            self.add_demo(p)

    # -- output --------------------------------------------------------------------------------------

    def _flush(self, *, final: bool) -> None:
        g = self.cycles_per_row_group
        while self._pending and (len(self._pending) >= g or final):
            group = self._pending[:g]
            if any(rec.demo is None for rec in group):
                if final:
                    lacking = [rec.cycle for rec in group if rec.demo is None][:5]
                    raise ValueError(
                        f"episode {self.episode}: cycles {lacking}... have no demonstration result; "
                        "pass DemoProjector.finish() to add_demos before close()"
                    )
                return
            with naming(self.policies_path):  # a full disk (pyarrow's error has no file name) names it
                self._write_group(group)
            del self._pending[: len(group)]
            for rec in group:
                del self._by_cycle[rec.cycle]

    def _write_group(self, group: list[_Cycle]) -> None:
        assert self._n is not None and self._k is not None
        if self._pol_writer is None:
            schema = self._recorded(policies_schema(self._k, self._f))
            self._pol_tmp = self._stack.enter_context(atomic_path(self.policies_path))
            self._pol_writer = self._stack.enter_context(_policies_writer(self._pol_tmp, schema))
        table = build_policies_table(
            episode=self.episode,
            cycles=np.array([rec.cycle for rec in group], dtype=np.int32),
            features=np.stack([rec.features for rec in group]),
            control_points=np.stack([rec.control_points for rec in group]),
            actions=np.stack([rec.actions for rec in group]),
            progress=np.stack([rec.progress for rec in group]),
            distances=np.stack([np.asarray(rec.demo.distances, np.float32) for rec in group]),  # type: ignore[union-attr]
            labels=np.stack([rec.labels for rec in group]),
        )
        self._pol_writer.write_table(table, row_group_size=table.num_rows)
        for rec in group:
            assert rec.demo is not None
            self._rows.append(
                (
                    rec.cycle,
                    rec.t,
                    *rec.ego,
                    rec.target_checkpoint,
                    rec.demo.demo_index,
                    rec.demo.demo_distance,
                    rec.executed_index if rec.executed_index >= 0 else _nearest(rec.demo.distances),
                    rec.situation,
                )
            )

    def close(self) -> None:
        """Write the remaining cycles and rename both files into place (policies first, cycles last).

        Raises ``ValueError`` (and discards the episode) when a cycle still lacks its demonstration
        result. Safe to call twice.
        """
        if self._closed:
            return
        policies_renamed = False
        try:
            self._flush(final=True)
            if self._pol_writer is None:  # an episode without cycles still gets (empty) files
                self._pol_tmp = self._stack.enter_context(atomic_path(self.policies_path))
                with naming(self.policies_path):
                    self._pol_writer = self._stack.enter_context(
                        _policies_writer(
                            self._pol_tmp,
                            self._recorded(policies_schema(self._k or N_CONTROL_POINTS, self._f)),
                        )
                    )
            table = build_cycles_table(self.episode, self._rows, self._n or 0, self.demo_source)
            table = table.replace_schema_metadata(self._recorded(table.schema).metadata)
            self._stack.close()  # closes the Parquet writer, then renames the policies file
            policies_renamed = True
            with atomic_path(self.cycles_path) as tmp:
                pq.write_table(
                    table,
                    str(tmp),
                    row_group_size=self.cycles_per_row_group,
                    compression=COMPRESSION,
                    compression_level=COMPRESSION_LEVEL,
                )
        except BaseException:
            self.abort()
            if policies_renamed:  # a new policies file beside an old or no cycles file: drop the pair
                self.cycles_path.unlink(missing_ok=True)
                self.policies_path.unlink(missing_ok=True)
            raise
        self._closed = True

    def abort(self) -> None:
        """Drop everything written so far (temporary files are removed); nothing appears on disk."""
        if self._closed:
            return
        self._closed = True
        self._pending.clear()
        self._by_cycle.clear()
        try:
            raise _Aborted
        except _Aborted as exc:
            # exiting atomic_path with an exception deletes its temporary file instead of renaming it
            self._stack.__exit__(type(exc), exc, exc.__traceback__)

    def _recorded(self, schema: pa.Schema) -> pa.Schema:
        """``schema`` with the episode record added to its key-value metadata."""
        return schema.with_metadata({**(schema.metadata or {}), **self._meta}) if self._meta else schema

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"EpisodeWriter for episode {self.episode} is closed")

    def __enter__(self) -> EpisodeWriter:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


class _Aborted(Exception):
    pass


# -- table builders (vectorised) -----------------------------------------------------------------------


def _fixed_list(values: np.ndarray, width: int) -> pa.FixedSizeListArray:
    flat = np.ascontiguousarray(values, dtype=np.float32).reshape(-1)
    return pa.FixedSizeListArray.from_arrays(pa.array(flat, type=pa.float32()), width)


def build_policies_table(
    *,
    episode: int,
    cycles: np.ndarray,
    features: np.ndarray,
    control_points: np.ndarray,
    actions: np.ndarray,
    progress: np.ndarray,
    distances: np.ndarray,
    labels: np.ndarray,
) -> pa.Table:
    """Policies rows of C cycles x N policies, cycle-major.

    Shapes: cycles [C], features [C, N, F], control_points [C, N, K, 3], actions [C, N, K, 2],
    progress [C, N], distances [C, N], labels [C, N, 3].
    """
    c, n = progress.shape
    k = control_points.shape[2]
    f = features.shape[-1]
    assert features.shape == (c, n, f) and f >= N_FEATURES, features.shape
    assert control_points.shape == (c, n, k, 3), control_points.shape
    assert actions.shape == (c, n, k, 2), actions.shape
    assert distances.shape == (c, n) and labels.shape == (c, n, 3), (distances.shape, labels.shape)
    rows = c * n
    lab = labels.reshape(rows, 3)
    columns = [
        pa.array(np.full(rows, episode, dtype=np.int32)),
        pa.array(np.repeat(np.asarray(cycles, dtype=np.int32), n)),
        pa.array(np.tile(np.arange(n, dtype=np.int32), c)),
        _fixed_list(features, f),
        _fixed_list(control_points, 3 * k),
        _fixed_list(actions, 2 * k),
        pa.array(progress.reshape(rows).astype(np.float32)),
        pa.array(distances.reshape(rows).astype(np.float32)),
        pa.array(lab[:, 0]),
        pa.array(lab[:, 1]),
        pa.array(lab[:, 2]),
    ]
    return pa.Table.from_arrays(columns, schema=policies_schema(k, f))


def build_cycles_table(
    episode: int, rows: list[tuple[Any, ...]], n_policies: int, demo_source: str = DEMO_ODOMETRY
) -> pa.Table:
    """Cycles rows from (cycle, t, x, y, yaw, v, s, d, lane, target, demo_index, demo_distance, executed,
    situation); every row's ``demo_source`` is ``demo_source`` (one episode has one source)."""
    schema = cycles_schema()
    if rows:
        a = np.array(rows, dtype=np.float64)  # [C, 14]; every value is exactly representable
    else:
        a = np.zeros((0, 14), dtype=np.float64)
    c = a.shape[0]
    demo_index = a[:, 10].astype(np.int32)
    demo_distance = a[:, 11].astype(np.float32)
    f32 = [a[:, j].astype(np.float32) for j in range(1, 8)]  # t, x, y, yaw, v, s, d
    columns = [
        np.full(c, episode, dtype=np.int32),
        a[:, 0].astype(np.int32),
        *f32,
        a[:, 8].astype(np.int8),
        a[:, 9].astype(np.int8),
        np.full(c, n_policies, dtype=np.int32),
        demo_index,
        demo_distance,
        demo_index >= 0,
        a[:, 12].astype(np.int32),
        a[:, 13].astype(np.int8),
        np.full(c, demo_source, dtype=object),
    ]
    return pa.Table.from_arrays([pa.array(col) for col in columns], schema=schema)
