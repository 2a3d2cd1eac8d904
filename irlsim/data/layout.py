"""The dataset's layout on disk: split folders, each episode's pair of Parquet files and figures, whether
an episode is complete, removing partial ones, and the manifest (docs/design/data.md).
:class:`~irlsim.data.writer.EpisodeWriter` writes the episodes themselves."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES, FEATURE_SETS, __version__
from irlsim.data.reader import BadParquetFile, open_parquet, read_parquet
from irlsim.data.schema import (
    META_CONFIG,
    META_SEED,
    SCHEMA_VERSION,
    TABLE_CYCLES,
    TABLE_POLICIES,
    cycles_name,
    cycles_schema,
    policies_name,
    policies_schema,
    stats_name,
)
from irlsim.errors import IrlsimError
from irlsim.utils import write_json

_SPLIT_RE = re.compile(r"^[A-Za-z0-9_\-]+$")


def check_split(split: str) -> str:
    if not _SPLIT_RE.match(split):
        raise IrlsimError(f"split name {split!r} is not valid: use letters, digits, '_' or '-'")
    return split


def episode_paths(dataset_dir: str | Path, split: str, episode: int) -> tuple[Path, Path]:
    """(cycles file, policies file) of one episode."""
    folder = Path(dataset_dir) / check_split(split)
    return folder / cycles_name(episode), folder / policies_name(episode)


def episode_done(dataset_dir: str | Path, split: str, episode: int) -> bool:
    """True when the episode was written completely (its cycles file, written last, exists)."""
    cycles, policies = episode_paths(dataset_dir, split, episode)
    return cycles.is_file() and policies.is_file()


def remove_partial(dataset_dir: str | Path, split: str) -> list[Path]:
    """Delete what a killed run left in a split folder: temporary files, and a policies or cycles file
    whose partner is missing. Returns the deleted paths. Call before resuming a collection."""
    folder = Path(dataset_dir) / check_split(split)
    if not folder.is_dir():
        return []
    removed = sorted(folder.glob(".episode_*.tmp"))
    pairs = ((".policies.", ".cycles."), (".cycles.", ".policies."))
    for this, other in pairs:
        removed += [
            p
            for p in sorted(folder.glob(f"episode_*{this}parquet"))
            if not p.with_name(p.name.replace(this, other)).exists()
        ]
    for p in removed:
        p.unlink(missing_ok=True)
    return removed


def remove_episode(dataset_dir: str | Path, split: str, episode: int) -> None:
    """Delete an episode's files; the cycles file (the completion marker) goes first."""
    cycles, policies = episode_paths(dataset_dir, split, episode)
    for p in (cycles, policies, cycles.with_name(stats_name(episode))):
        p.unlink(missing_ok=True)


def check_episode(
    dataset_dir: str | Path,
    split: str,
    episode: int,
    *,
    n_policies: int | None = None,
    n_control_points: int | None = None,
    record: Mapping[str, Any] | None = None,
    unrecorded_ok: bool = True,
) -> str | None:
    """Why a finished episode's pair of files cannot be kept (one line naming the file), or None.

    Checks what is cheap at any dataset size, so a resumed collection can run it on every episode:
    both footers (a truncated file has none), the irlsim metadata, the exact schemas, the cycles file's
    episode ids and policy counts (``n_policies`` if given), and that the policies file holds one row per
    policy of its cycles file and ids of this episode (footer statistics). The policies' data pages are
    not read (the reader checks those). ``record`` (seed, config hash: what the collection would write,
    :func:`irlsim.data.collection.episode_record`): both files must record the same (one recorded with
    another seed or config is named); a file of an older irlsim that records none passes only with
    ``unrecorded_ok`` (a manifest of this collection vouches for it).
    """
    cycles_path, policies_path = episode_paths(dataset_dir, split, episode)
    try:
        cpf = open_parquet(cycles_path, TABLE_CYCLES)
        ppf = open_parquet(policies_path, TABLE_POLICIES)
        if not cpf.schema_arrow.equals(cycles_schema()):
            return f"{cycles_path} does not have the columns of an irlsim cycles table"
        k = n_control_points
        if k is None:  # any count: the one the file's control_points column has
            try:
                k = ppf.schema_arrow.field("control_points").type.list_size // 3
            except (KeyError, AttributeError):
                k = -1
        try:  # F: the file's own feature set (open_parquet checked it is one)
            f = ppf.schema_arrow.field("features").type.list_size
        except (KeyError, AttributeError):
            f = -1
        if k < 0 or f < 0 or not ppf.schema_arrow.equals(policies_schema(k, f)):
            want = (
                f"{n_control_points} control points"
                if n_control_points is not None
                else "irlsim policies columns"
            )
            return f"{policies_path} does not have the columns of an irlsim policies table ({want})"
        table = read_parquet(cpf, cycles_path, columns=["episode", "n_policies"])
    except BadParquetFile as exc:
        return exc.problem
    if record is not None:
        for path, pf in ((cycles_path, cpf), (policies_path, ppf)):
            problem = _record_problem(path, pf.schema_arrow.metadata or {}, record, unrecorded_ok)
            if problem is not None:
                return problem
    ids = table.column("episode").to_numpy()
    if (ids != episode).any():
        return f"{cycles_path} holds episode {int(ids[ids != episode][0])}, not {episode}"
    per_cycle = table.column("n_policies").to_numpy().astype(np.int64)
    if n_policies is not None and (per_cycle != n_policies).any():
        bad = int(per_cycle[per_cycle != n_policies][0])
        return f"{cycles_path} has {bad} policies per cycle, the config asks for {n_policies}"
    rows = ppf.metadata.num_rows
    if rows != int(per_cycle.sum()):
        return f"{policies_path} has {rows} rows, its cycles file describes {int(per_cycle.sum())} policies"
    for i in range(ppf.metadata.num_row_groups):  # episode ids from the footer's statistics: no data read
        stats = ppf.metadata.row_group(i).column(0).statistics  # column 0 is "episode" (schema checked)
        if stats is not None and stats.has_min_max and not stats.min == stats.max == episode:
            return f"{policies_path} holds episodes {stats.min}..{stats.max}, not {episode}"
    return None


def _record_problem(
    path: Path, meta: Mapping[bytes, bytes], record: Mapping[str, Any], unrecorded_ok: bool
) -> str | None:
    """Why a file's episode record (irlsim.seed, irlsim.config) is not ``record``, or None."""
    keys = {"seed": META_SEED, "config": META_CONFIG}
    found = {k: meta[m].decode(errors="replace") for k, m in keys.items() if m in meta}
    if not found:
        return None if unrecorded_ok else f"{path} records no seed (an older irlsim, its manifest lost)"
    for key in keys:
        want = str(record.get(key))
        if found.get(key) != want:
            have = found.get(key, "(none)")[:19]
            return f"{path} was collected with {key} {have}, this run's is {want[:19]}"
    return None


# -- manifest ------------------------------------------------------------------------------------------


def split_counts(dataset_dir: str | Path, split: str, episodes: Iterable[int]) -> dict[str, Any]:
    """Counts of a split from its cycles files: episodes, cycles, cycles_with_demo, policies_per_cycle."""
    n_cycles = n_demo = 0
    per_cycle: set[int] = set()
    eps = list(episodes)
    for ep in eps:
        path, _ = episode_paths(dataset_dir, split, ep)
        t = read_parquet(open_parquet(path, TABLE_CYCLES), path, columns=["n_policies", "has_demo"])
        n_cycles += t.num_rows
        n_demo += int(np.count_nonzero(t.column("has_demo").to_numpy()))
        per_cycle.update(np.unique(t.column("n_policies").to_numpy()).tolist())
    return {
        "episodes": len(eps),
        "cycles": n_cycles,
        "cycles_with_demo": n_demo,
        "policies_per_cycle": per_cycle.pop() if len(per_cycle) == 1 else sorted(per_cycle),
    }


def manifest_feature_names(manifest: Mapping[str, Any]) -> tuple[str, ...]:
    """The features a collection's planner computed: its config's ``planner.feature_set`` (the paper's 15
    when it is not set)."""
    planner = (manifest.get("config") or {}).get("planner") or {}
    return FEATURE_SETS.get(str(planner.get("feature_set", "paper")), FEATURE_NAMES)


def write_manifest(dataset_dir: str | Path, manifest: Mapping[str, Any]) -> Path:
    """Write ``<dataset>/manifest.json`` atomically and return its path.

    ``manifest`` must hold ``config`` (dict), ``seeds`` and ``splits`` ({split: [episode ids]}).
    ``schema_version``, ``feature_names`` and ``created_by`` are filled in; ``counts`` is computed from
    the episodes' cycles files when absent (every listed episode must be complete). ``complete``
    (default true) is false while a collection is running: readers refuse such a dataset.
    """
    missing = [k for k in ("config", "seeds", "splits") if k not in manifest]
    if missing:
        raise ValueError(f"manifest lacks {missing}")
    complete = manifest.get("complete", True)
    if not isinstance(complete, bool):
        raise ValueError(f"manifest 'complete' must be true or false, got {complete!r}")
    splits = {check_split(str(s)): sorted(int(e) for e in eps) for s, eps in manifest["splits"].items()}
    for split, eps in splits.items():
        lacking = [e for e in eps if not episode_done(dataset_dir, split, e)]
        if lacking:
            raise ValueError(f"split {split}: episodes {lacking[:5]} are not complete on disk")
    out: dict[str, Any] = {
        # the version and names describe what this code wrote: never taken from the caller
        "schema_version": SCHEMA_VERSION,
        "feature_names": list(manifest_feature_names(manifest)),
        "created_by": manifest.get("created_by", f"irlsim {__version__}"),
        "complete": complete,
        **{
            k: v
            for k, v in manifest.items()
            if k not in ("splits", "schema_version", "feature_names", "created_by", "complete")
        },
        "splits": splits,
    }
    if "counts" not in manifest:
        out["counts"] = {s: split_counts(dataset_dir, s, eps) for s, eps in splits.items()}
    path = Path(dataset_dir) / "manifest.json"
    write_json(path, out)
    return path
