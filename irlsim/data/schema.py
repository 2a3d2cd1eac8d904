"""Parquet schemas of a dataset (docs/design/data.md).

A dataset folder holds ``manifest.json`` and, per split and episode, two Parquet files:

- ``<split>/episode_<id:05d>.cycles.parquet``: one row per planning cycle (``cycles_schema``);
- ``<split>/episode_<id:05d>.policies.parquet``: one row per policy, N rows per cycle in cycle order and
  progress-sorted policy order (``policies_schema``).

Large per-policy vectors are fixed-size lists of float32. float16 was considered for control points and
actions and rejected: it would halve those two columns before compression, but the Parquet FLOAT16
logical type is not read by every DuckDB/polars version, and progress along the route in control points
(tens of metres) would lose centimetres. Float columns are written BYTE_STREAM_SPLIT + zstd (read by
pyarrow, pandas, DuckDB and polars; tested), integer id columns dictionary-encoded.

A split folder holds both tables (two schemas) and each episode's ``.stats.json``, so the folder is not one
table (``pd.read_parquet('<ds>/train')`` fails): name the files, by glob in DuckDB and polars
(``'<ds>/train/*.cycles.parquet'``) or by a sorted list in pyarrow.dataset and pandas (tested in
tests/data/test_third_party.py).

Both files carry Parquet key-value metadata ``irlsim.schema_version`` and ``irlsim.table`` (``cycles`` or
``policies``), so a foreign or outdated Parquet file in a dataset folder is recognised, and (files written
by ``irlsim collect`` since the seed record) ``irlsim.seed``, the episode's seed, and ``irlsim.config``,
the hash of the data config it was collected with (:func:`irlsim.data.collection.config_hash`), so a
resumed collection checks every finished file against what it would collect (``check_episode``).
Row groups hold ``CYCLES_PER_ROW_GROUP`` whole cycles in both files, so row group i of the cycles file
describes the cycles of row group i of the policies file.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from irlsim import N_FEATURES
from irlsim.errors import IrlsimError

#: bump when a column is added, removed or changes meaning; readers refuse other versions
SCHEMA_VERSION = 2
#: control points per policy (docs/design/planner.md)
N_CONTROL_POINTS = 10
#: whole planning cycles per Parquet row group (policies: this x N rows; ~40 MB uncompressed at N=2,500)
CYCLES_PER_ROW_GROUP = 64
#: Parquet compression codec and level
COMPRESSION = "zstd"
COMPRESSION_LEVEL = 3

#: float columns of the policies table: stored BYTE_STREAM_SPLIT (zstd then compresses the exponent bytes
#: well; reads ~2x faster), without dictionary encoding (unique floats make it a costly failed attempt)
POLICIES_FLOAT_COLUMNS: tuple[str, ...] = ("features", "control_points", "actions", "progress", "distance")
#: columns of the policies table worth dictionary encoding (few distinct values per row group)
POLICIES_DICTIONARY_COLUMNS: tuple[str, ...] = ("episode", "cycle", "policy")

META_VERSION = b"irlsim.schema_version"
META_TABLE = b"irlsim.table"
#: the episode record of a collected file: its seed and its data config's hash (absent in older files)
META_SEED = b"irlsim.seed"
META_CONFIG = b"irlsim.config"
TABLE_CYCLES = "cycles"
TABLE_POLICIES = "policies"

#: where a cycle's demonstration comes from (cycles column ``demo_source``, since version 2):
#: ``odometry``: what the driver drove, projected onto the policy set (DemoProjector; expert collection);
#: ``expert``: the expert's own selection on the same policy set at the learner's state (DAgger labels,
#: ``irlsim collect --driver``)
DEMO_SOURCES: tuple[str, ...] = ("odometry", "expert")
DEMO_ODOMETRY, DEMO_EXPERT = DEMO_SOURCES

#: ego-state keys the writer expects, with their column names in the cycles table
EGO_KEYS: tuple[str, ...] = ("x", "y", "yaw", "v", "s", "d", "lane")


def _metadata(table: str) -> dict[bytes, bytes]:
    return {META_VERSION: str(SCHEMA_VERSION).encode(), META_TABLE: table.encode()}


def cycles_schema() -> pa.Schema:
    """One row per planning cycle. Units: t [s], x/y/s/d [m], yaw [rad], v [m/s]."""
    f32 = pa.float32()
    return pa.schema(
        [
            pa.field("episode", pa.int32(), nullable=False),
            pa.field("cycle", pa.int32(), nullable=False),
            pa.field("t", f32, nullable=False),
            pa.field("ego_x", f32, nullable=False),
            pa.field("ego_y", f32, nullable=False),
            pa.field("ego_yaw", f32, nullable=False),
            pa.field("ego_v", f32, nullable=False),
            pa.field("ego_s", f32, nullable=False),
            pa.field("ego_d", f32, nullable=False),
            pa.field("ego_lane", pa.int8(), nullable=False),
            pa.field("target_checkpoint", pa.int8(), nullable=False),
            pa.field("n_policies", pa.int32(), nullable=False),
            # progress-sorted index of the demonstration, -1 = no demonstration
            pa.field("demo_index", pa.int32(), nullable=False),
            # d(zeta, pi^D) [m], NaN = no demonstration
            pa.field("demo_distance", f32, nullable=False),
            pa.field("has_demo", pa.bool_(), nullable=False),
            # progress-sorted index of the policy the driver executed
            pa.field("executed_index", pa.int32(), nullable=False),
            # situation code (irlsim.data.situations.SITUATION_NAMES), -1 = not labelled; since version 2
            pa.field("situation", pa.int8(), nullable=False),
            # DEMO_SOURCES: 'odometry' (projected) or 'expert' (DAgger label); since version 2
            pa.field("demo_source", pa.string(), nullable=False),
        ],
        metadata=_metadata(TABLE_CYCLES),
    )


def policies_schema(n_control_points: int = N_CONTROL_POINTS, n_features: int = N_FEATURES) -> pa.Schema:
    """One row per policy. Lists are row-major flattenings: control_points [K, 3], actions [K, 2];
    features [F] (the dataset's feature set: 15, or irlsim.FEATURE_SETS's larger one)."""
    f32 = pa.float32()
    k = int(n_control_points)
    return pa.schema(
        [
            pa.field("episode", pa.int32(), nullable=False),
            pa.field("cycle", pa.int32(), nullable=False),
            pa.field("policy", pa.int32(), nullable=False),
            pa.field("features", pa.list_(f32, int(n_features)), nullable=False),
            # (lateral offset to ego [m], yaw to ego [rad], progress along route [m]) x K
            pa.field("control_points", pa.list_(f32, 3 * k), nullable=False),
            # (longitudinal acceleration [m/s^2], lateral velocity [m/s]) x K
            pa.field("actions", pa.list_(f32, 2 * k), nullable=False),
            pa.field("progress", f32, nullable=False),
            # d(zeta, pi) [m], NaN when the cycle's demonstration window is incomplete
            pa.field("distance", f32, nullable=False),
            pa.field("collision", pa.bool_(), nullable=False),
            pa.field("offroad", pa.bool_(), nullable=False),
            pa.field("exit", pa.bool_(), nullable=False),
        ],
        metadata=_metadata(TABLE_POLICIES),
    )


def episode_stem(episode: int) -> str:
    return f"episode_{int(episode):05d}"


def cycles_name(episode: int) -> str:
    return f"{episode_stem(episode)}.cycles.parquet"


def policies_name(episode: int) -> str:
    return f"{episode_stem(episode)}.policies.parquet"


def stats_name(episode: int) -> str:
    """The episode's driving figures (JSON), written beside its two tables."""
    return f"{episode_stem(episode)}.stats.json"


def with_demo_source(table: pa.Table) -> pa.Table:
    """A cycles table with its ``demo_source`` column; a version-2 file written before the column existed
    (its demonstrations were all projected odometry, the only source then) gets 'odometry' rows."""
    if "demo_source" in table.column_names:
        return table
    return table.append_column(
        cycles_schema().field("demo_source"), pa.array([DEMO_ODOMETRY] * table.num_rows, pa.string())
    )


def demo_source_codes(column: pa.ChunkedArray | pa.Array) -> np.ndarray:
    """[C] int8 indices into DEMO_SOURCES of a ``demo_source`` column; an unknown value is refused."""
    idx = pc.index_in(column, value_set=pa.array(DEMO_SOURCES, pa.string()))
    if idx.null_count:
        bad = pc.filter(column, pc.is_null(idx))[0].as_py()
        raise IrlsimError(
            f"demo_source {bad!r} is none of {', '.join(DEMO_SOURCES)}: delete the file and re-run irlsim "
            "collect to regenerate it"
        )
    return np.asarray(idx.to_numpy(zero_copy_only=False), dtype=np.int8)
