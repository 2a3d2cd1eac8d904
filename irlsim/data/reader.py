"""Read a dataset: validation, cycles as a DataFrame, splits as memory-mapped tensors.

``Dataset.split_tensors(split)`` turns a split into arrays ``[cycles, policies, ...]`` ordered by
(episode, cycle), i.e. sequential playback order. The arrays are memory-mapped ``.npy`` files of a cache
under ``<dataset>/.cache/<split>/``: built once, one episode and one row group at a time (bounded memory),
each file written under a temporary name and renamed, ``meta.json`` last. The cache is reused while
``meta.json`` records the same Parquet files (name, size, mtime) and is newer than all of them, and its
files are those it records (sizes and content hashes, checked once per process); otherwise it is
rebuilt, the out-of-date arrays removed first (:mod:`irlsim.data.cache`). Deleting ``.cache`` is
always safe. An aggregate of folders reads each folder's own cache (:mod:`irlsim.data.aggregate`).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from irlsim import N_FEATURES
from irlsim.data import roads
from irlsim.data.cache import (
    CACHE_DIR,
    REBUILD,
    invalidate_cache,
    open_cache,
    read_cache_meta,
    record_problem,
    remove_cache,
    verify_cache,
    write_cache_meta,
)
from irlsim.data.lz4rows import Lz4RowsWriter
from irlsim.data.schema import (
    META_TABLE,
    META_VERSION,
    SCHEMA_VERSION,
    TABLE_CYCLES,
    TABLE_POLICIES,
    cycles_name,
    cycles_schema,
    demo_source_codes,
    policies_name,
    with_demo_source,
)
from irlsim.data.tensors import ARRAY_NAMES as ARRAY_NAMES  # re-exported, as SplitTensors
from irlsim.data.tensors import SplitTensors as SplitTensors
from irlsim.data.tensors import policy_array_specs
from irlsim.data.validate import _REGENERATE, BadParquetFile, check_columns, validate_manifest
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.planner.policy_set import LABEL_NAMES
from irlsim.utils import atomic_path

#: per-cycle arrays read straight from the cycles table's column of the same name
_SMALL_COLUMNS: tuple[tuple[str, Any], ...] = (
    ("demo_index", np.int64),
    ("demo_distance", np.float32),
    ("episode", np.int32),
    ("cycle", np.int32),
    ("executed_index", np.int32),
)
#: the policies-table columns the cache is built from (with the LABEL_NAMES)
_POLICY_COLUMNS = ["episode", "cycle", "policy", "features", "control_points", "actions", "distance"]


def _corrupt(path: Path, exc: BaseException) -> BadParquetFile:
    reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return BadParquetFile(path, f"is truncated or corrupt ({reason})", _REGENERATE)


def open_parquet(
    path: Path, table: str, n_control_points: int | None = None, n_features: int | None = None
) -> pq.ParquetFile:
    """Open an irlsim Parquet file, checking it is complete, ours, of this schema version and has the
    columns, types and list widths of this irlsim's ``table`` (with ``n_control_points`` K and
    ``n_features`` F if given).

    Raises ``BadParquetFile`` (an ``IrlsimError``) naming the file."""
    try:
        pf = pq.ParquetFile(str(path))
    except FileNotFoundError:
        raise BadParquetFile(path, "is missing", "re-run irlsim collect to regenerate it") from None
    except (pa.ArrowException, OSError) as exc:
        raise _corrupt(path, exc) from None
    meta = pf.schema_arrow.metadata or {}
    if meta.get(META_TABLE) != table.encode():
        raise BadParquetFile(
            path,
            f"is not an irlsim {table} table (no irlsim metadata)",
            "remove it from the dataset folder, or re-collect the dataset with 'irlsim collect'",
        )
    version = meta.get(META_VERSION, b"?").decode()
    if version != str(SCHEMA_VERSION):
        raise BadParquetFile(
            path,
            f"has schema version {version}, this irlsim reads {SCHEMA_VERSION}",
            "re-collect it with 'irlsim collect'",
        )
    check_columns(pf.schema_arrow, path, table, n_control_points, n_features)
    return pf


def read_parquet(pf: pq.ParquetFile, path: Path, **kwargs: Any) -> pa.Table:
    """pf.read / read_row_group with corrupt data turned into a one-line ``BadParquetFile``."""
    try:
        if "row_group" in kwargs:
            return pf.read_row_group(kwargs.pop("row_group"), **kwargs)
        return pf.read(**kwargs)
    except (pa.ArrowException, OSError) as exc:
        raise _corrupt(path, exc) from None


def fixed_list_to_numpy(column: pa.ChunkedArray | pa.Array, width: int) -> np.ndarray:
    """A fixed-size-list column as a [rows, width] numpy array (one copy at most, no Python loop)."""
    arr = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    flat = arr.flatten().to_numpy(zero_copy_only=False)  # flatten() honours slice offsets, .values does not
    return flat.reshape(len(arr), width)


def iter_policy_groups(pf: pq.ParquetFile, path: Path, columns: list[str]) -> Iterator[pa.Table]:
    """The row groups of a policies file, read one at a time."""
    for i in range(pf.num_row_groups):
        yield read_parquet(pf, path, row_group=i, columns=columns)


def check_complete(path: Path, manifest: dict[str, Any]) -> None:
    """Refuse the manifest of a collection that has not finished (one-line ``IrlsimError``).

    ``irlsim collect`` writes ``"complete": false`` until its last episode is on disk. Manifests written
    before that flag existed are complete unless every split is empty (how an unfinished run looked).
    """
    complete = manifest.get("complete")
    if complete is None:
        splits = manifest.get("splits")
        complete = not isinstance(splits, dict) or any(splits.values())
    if complete is not True:
        raise IrlsimError(
            f"dataset {path} is incomplete (collection was interrupted): "
            "re-run the same 'irlsim collect' command to finish it"
        )


class Dataset:
    """A validated, complete dataset folder. Use ``open_dataset``."""

    def __init__(
        self, path: Path, manifest: dict[str, Any], scenarios: tuple[str, ...] | None = None
    ) -> None:
        self.path = path
        self.manifest = manifest
        check_complete(path, manifest)
        planner = (manifest.get("config") or {}).get("planner") or {}
        #: K and N the collection was configured with (None: not recorded, taken from the files)
        self.n_control_points: int | None = planner.get("n_control_points")
        self.n_policies: int | None = planner.get("n_policies")
        #: F, the features of its feature set (the manifest's names)
        self.n_features = len(manifest.get("feature_names") or ()) or N_FEATURES
        #: the scenarios read (None: all); a selection has its own identity and cache
        self.selection = scenarios
        self.legacy_identities: tuple[str, ...] = ()
        if scenarios is not None:
            self.identity = roads.selection_identity(manifest, scenarios)

    @property
    def scenarios(self) -> list[str]:
        """The scenarios the dataset was collected on (all of them, whatever the selection)."""
        return roads.manifest_scenarios(self.manifest)

    def scenario_of_cycle(self, split: str) -> np.ndarray:
        """[C] the scenario name of every cycle of ``split``, rows as ``split_tensors`` orders them."""
        eps = self.episodes(split)
        rows = [open_parquet(self.cycles_path(split, e), TABLE_CYCLES).metadata.num_rows for e in eps]
        names = [roads.episode_scenario(self.manifest, split, e) for e in eps]
        return np.repeat(np.asarray(names, dtype=str), rows)

    def demonstrator_of_cycle(self, split: str) -> np.ndarray:
        """[C] the demonstrator's identity (:func:`irlsim.data.demonstrator.identity`) of every cycle of
        ``split``: a folder is the data of its manifest's one demonstrator."""
        from irlsim.data.by_demonstrator import dataset_demonstrator

        return np.full(len(self.scenario_of_cycle(split)), dataset_demonstrator(self))

    @property
    def splits(self) -> list[str]:
        return list(self.manifest["splits"])

    def episodes(self, split: str) -> list[int]:
        """Episode ids of a split, ascending."""
        splits = self.manifest["splits"]
        if split not in splits:
            raise IrlsimError(
                f"dataset {self.path} has no split {split!r}: choose one of {', '.join(splits) or '(none)'}"
            )
        eps = sorted(int(e) for e in splits[split])
        if self.selection is None:
            return eps
        return [e for e in eps if roads.episode_scenario(self.manifest, split, e) in self.selection]

    def cycles_path(self, split: str, episode: int) -> Path:
        return self.path / split / cycles_name(episode)

    def policies_path(self, split: str, episode: int) -> Path:
        return self.path / split / policies_name(episode)

    # -- cycles --------------------------------------------------------------------------------------

    def read_cycles_table(self, split: str) -> pa.Table:
        """All cycles rows of a split as one Arrow table, ordered by (episode, cycle)."""
        tables = []
        for ep in self.episodes(split):
            path = self.cycles_path(split, ep)
            tables.append(with_demo_source(read_parquet(open_parquet(path, TABLE_CYCLES), path)))
            self._check_policy_count(path, tables[-1])
        if not tables:
            return cycles_schema().empty_table()
        table = pa.concat_tables(tables)
        self._check_cycles(split, table)
        return table

    def read_cycles(self, split: str) -> pd.DataFrame:
        """All cycles rows of a split as a DataFrame, ordered by (episode, cycle)."""
        return self.read_cycles_table(split).to_pandas()

    def _check_policy_count(self, path: Path, table: pa.Table) -> None:
        n_pol = table.column("n_policies").to_numpy()
        if self.n_policies is not None and n_pol.size and (n_pol != self.n_policies).any():
            raise BadParquetFile(
                path,
                f"has {int(n_pol[n_pol != self.n_policies][0])} policies per cycle, the dataset's manifest "
                f"{self.n_policies} (planner.n_policies)",
                "remove it from the dataset folder, or re-collect the dataset with 'irlsim collect'",
            )

    def _check_cycles(self, split: str, table: pa.Table) -> None:
        n_pol = table.column("n_policies").to_numpy()
        if n_pol.size and (n_pol != n_pol[0]).any():
            raise IrlsimError(
                f"dataset {self.path} split {split} has between {n_pol.min()} and {n_pol.max()} policies per "
                "cycle, the reader needs a constant count: re-collect it with a fixed planner n_policies"
            )
        ep = table.column("episode").to_numpy().astype(np.int64)
        cy = table.column("cycle").to_numpy().astype(np.int64)
        if ep.size > 1 and not ((ep[1:] > ep[:-1]) | ((ep[1:] == ep[:-1]) & (cy[1:] > cy[:-1]))).all():
            raise IrlsimError(
                f"dataset {self.path} split {split}: cycles are not in (episode, cycle) order: "
                "re-collect it with 'irlsim collect'"
            )

    # -- tensors -------------------------------------------------------------------------------------

    def sources(self, split: str) -> list[list[Any]]:
        """[name, size, mtime_ns] of every Parquet file of the split: what its cache records."""
        out = []
        for ep in self.episodes(split):
            for p in (self.cycles_path(split, ep), self.policies_path(split, ep)):
                try:
                    st = p.stat()
                except FileNotFoundError:
                    raise IrlsimError(f"{p} is missing: re-run irlsim collect to regenerate it") from None
                out.append([p.name, st.st_size, st.st_mtime_ns])
        return out

    def cache_dir(self, split: str) -> Path:
        if self.selection is not None:
            return self.path / CACHE_DIR / roads.selection_key(self.selection) / split
        return self.path / CACHE_DIR / split

    def cache_valid(self, split: str, sources: list[list[Any]] | None = None) -> bool:
        """Whether the split's cache is complete and was built from its files as they are (``sources``:
        :meth:`sources`, read again when not given)."""
        sources = self.sources(split) if sources is None else sources
        found = read_cache_meta(self.cache_dir(split))
        if found is None or found[0].get("sources") != sources:
            return False
        return found[1].st_mtime_ns >= max((s[2] for s in sources), default=0)

    def split_tensors(self, split: str, max_cycles: int | None = None) -> SplitTensors:
        """A split as memory-mapped arrays (``SplitTensors``); only the first ``max_cycles`` if given.

        The cache is verified when first opened (:func:`irlsim.data.cache.verify_cache`); one that fails
        (a file flipped, truncated, swapped or missing, a ``meta.json`` not as written) is rebuilt from the
        Parquet files with one line on stderr naming the file."""
        sources = self.sources(split)
        folder = self.cache_dir(split)
        problem = record_problem(folder)  # first: a flipped record could look out of date
        found = read_cache_meta(folder) if problem is None and self.cache_valid(split, sources) else None
        problem = problem or (None if found is None else verify_cache(folder, found[0]))
        if problem is not None:
            print(
                f"irlsim: the cache of split {split} failed its check ({problem}): rebuilding it from "
                "the Parquet files",
                file=sys.stderr,
                flush=True,
            )
        if found is None or problem is not None:
            self._build_cache(split, sources, quiet=problem is not None)
            found = read_cache_meta(folder)
            if found is None:
                raise IrlsimError(f"the cache {folder} was rebuilt but cannot be read back: {REBUILD}")
        tensors = open_cache(folder, found[0])
        return tensors if max_cycles is None else tensors.head(max_cycles)

    def _build_cache(self, split: str, sources: list[list[Any]], quiet: bool = False) -> None:
        cycles = self.read_cycles_table(split)
        c = cycles.num_rows
        n = int(cycles.column("n_policies")[0].as_py()) if c else 0
        k = self._n_control_points(split)
        folder = self.cache_dir(split)
        # the out-of-date arrays go first: the space check then counts the disk they took as free
        remove_cache(
            folder, f"the cache of split {split}, out of date (other files, or another irlsim)", quiet
        )
        # LZ4 takes the rows to a third to a fifth of their float32 bytes: half of those is the estimate
        self._check_cache_place(folder, c * n * (4 * (self.n_features + 5 * k + 1) + len(LABEL_NAMES)) // 2)
        invalidate_cache(folder)
        f = self.n_features
        specs = policy_array_specs(c, n, k, f)
        small = {name: cycles.column(name).to_numpy().astype(dtype) for name, dtype in _SMALL_COLUMNS}
        small["demo_source"] = demo_source_codes(cycles.column("demo_source"))
        with Lz4RowsWriter(folder, specs) as big:
            row = 0  # next cycle row to fill
            for ep in self.episodes(split):
                path = self.policies_path(split, ep)
                pf = open_parquet(path, TABLE_POLICIES, self.n_control_points, self.n_features)
                for group in iter_policy_groups(pf, path, [*_POLICY_COLUMNS, *LABEL_NAMES]):
                    if group.num_rows % max(n, 1):
                        raise IrlsimError(
                            f"{path}: a row group of {group.num_rows} rows is not whole cycles of "
                            f"{n} policies: {_REGENERATE}"
                        )
                    g = group.num_rows // max(n, 1)
                    sl = slice(row, row + g)
                    _check_policy_ids(path, group, small["episode"][sl], small["cycle"][sl], n)
                    big["features"].append(fixed_list_to_numpy(group.column("features"), f).reshape(g, n, f))
                    big["control_points"].append(
                        fixed_list_to_numpy(group.column("control_points"), 3 * k).reshape(g, n, k, 3)
                    )
                    big["actions"].append(
                        fixed_list_to_numpy(group.column("actions"), 2 * k).reshape(g, n, k, 2)
                    )
                    big["distances"].append(group.column("distance").to_numpy().reshape(g, n))
                    big["labels"].append(
                        np.stack(
                            [group.column(name).to_numpy(zero_copy_only=False) for name in LABEL_NAMES],
                            axis=-1,
                        ).reshape(g, n, len(LABEL_NAMES))
                    )
                    row += g
            if row != c:
                raise IrlsimError(
                    f"dataset {self.path} split {split}: policies files hold {row} cycles, cycles "
                    f"files {c}: delete the split's episode files and re-run irlsim collect"
                )
        for name, arr in small.items():
            with atomic_path(folder / f"{name}.npy") as tmp, open(tmp, "wb") as fh:
                np.save(fh, arr)
        shape = {"cycles": c, "policies": n, "control_points": k} | (
            {"features": f} if f != N_FEATURES else {}
        )
        write_cache_meta(folder, {**shape, "sources": sources})
        # Arrow's allocator keeps the row groups' freed buffers (0.2 GB and more at 2,500 policies): given
        # back, so they do not sit in the training's anonymous memory beside what it allocates next
        pa.default_memory_pool().release_unused()

    def _check_cache_place(self, folder: Path, nbytes: int) -> None:
        """Before any array is written: the cache folder takes files and its disk has ``nbytes``."""
        check_output_dir(
            folder,
            f"dataset {self.path}: its cache",
            nbytes,
            fix="make the dataset folder writable (the cache of memory-mapped arrays lives in it), or copy "
            "the dataset to a writable place",
        )

    def _n_control_points(self, split: str) -> int:
        eps = self.episodes(split)
        if not eps:
            return 0
        path = self.policies_path(split, eps[0])
        pf = open_parquet(path, TABLE_POLICIES, self.n_control_points)
        width = pf.schema_arrow.field("control_points").type.list_size
        return int(width) // 3


def _check_policy_ids(path: Path, group: pa.Table, episode: np.ndarray, cycle: np.ndarray, n: int) -> None:
    """The row group's (episode, cycle, policy) columns must match the cycles rows it fills."""
    g = len(cycle)
    ok = (
        np.array_equal(
            group.column("episode").to_numpy().reshape(g, n), np.broadcast_to(episode[:, None], (g, n))
        )
        and np.array_equal(
            group.column("cycle").to_numpy().reshape(g, n), np.broadcast_to(cycle[:, None], (g, n))
        )
        and np.array_equal(
            group.column("policy").to_numpy().reshape(g, n),
            np.broadcast_to(np.arange(n, dtype=np.int32), (g, n)),
        )
    )
    if not ok:
        raise IrlsimError(
            f"{path} does not match its cycles file (episode/cycle/policy ids differ): {_REGENERATE}"
        )


def open_dataset(path: str | Path, scenarios: tuple[str, ...] | None = None) -> Dataset:
    """Open and validate a dataset folder (manifest, schema version, feature names); ``scenarios``: read
    only the episodes of these (refused in one line when one is not the dataset's)."""
    path = Path(path)
    if not path.is_dir():
        raise IrlsimError(
            f"dataset {path} does not exist: collect it with 'irlsim collect' or check the path"
        )
    manifest_path = path / "manifest.json"
    if not manifest_path.is_file():
        raise IrlsimError(
            f"dataset {path} has no manifest.json (collection not finished?): re-run 'irlsim collect', "
            "which resumes finished episodes"
        )
    try:
        manifest = json.loads(manifest_path.read_text())
    except (OSError, ValueError) as exc:
        raise IrlsimError(f"{manifest_path} is not valid JSON ({exc}): {_REGENERATE}") from None
    if not isinstance(manifest, dict):
        raise IrlsimError(f"{manifest_path} is not a JSON object: {_REGENERATE}")
    validate_manifest(manifest, manifest_path)
    if scenarios is not None:
        scenarios = roads.check_selection(path, roads.manifest_scenarios(manifest), scenarios)
    return Dataset(path, manifest, scenarios)
