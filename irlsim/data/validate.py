"""Validation of a dataset's files before use: the manifest against its schema, each Parquet file's
columns, types and fixed list widths against this irlsim's table schemas (``irlsim.data.schema``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pyarrow as pa

from irlsim import FEATURE_NAMES, FEATURE_SETS, feature_names_of, feature_set_of
from irlsim.data.schema import SCHEMA_VERSION, TABLE_POLICIES, cycles_schema, policies_schema
from irlsim.errors import IrlsimError

_REGENERATE = "delete it and re-run irlsim collect to regenerate it"


class BadParquetFile(IrlsimError):
    """A dataset file that is missing, truncated, corrupt, foreign or of another schema version.

    ``str()`` is the one-line user message; ``problem`` is the same without the fix, for callers that
    repair the file themselves (``irlsim collect`` re-collects the episode)."""

    def __init__(self, path: Path, problem: str, fix: str) -> None:
        super().__init__(f"{path} {problem}: {fix}")
        self.path = path
        self.problem = f"{path} {problem}"


def check_columns(
    schema: pa.Schema,
    path: Path,
    table: str,
    n_control_points: int | None = None,
    n_features: int | None = None,
) -> None:
    """The file's columns, their types and fixed list widths must be those of this irlsim's ``table``
    schema (``irlsim.data.schema``): a file whose metadata claims the table but whose columns differ (a
    'features' list of 14, another K) is refused in one line naming the column, not read into a reshape
    error. ``n_control_points``: the dataset's K (from its manifest); None = the file's own K.
    ``n_features``: the dataset's F (its manifest's feature set); None = the file's own, if a feature
    set has that many (irlsim.FEATURE_SETS), else the paper's 15."""
    if table == TABLE_POLICIES:
        k = n_control_points
        if k is None:
            field = schema.field("control_points") if "control_points" in schema.names else None
            size = getattr(field.type, "list_size", 0) if field is not None else 0
            k = max(int(size) // 3, 1)
        f = n_features
        if f is None:
            field = schema.field("features") if "features" in schema.names else None
            size = int(getattr(field.type, "list_size", 0)) if field is not None else 0
            f = len(feature_names_of(size, default=FEATURE_NAMES))
        expected = policies_schema(k, f)
    else:
        expected = cycles_schema()
    names = list(schema.names)
    if table != TABLE_POLICIES and names == expected.names[:-1] and expected.names[-1] == "demo_source":
        # a version-2 cycles file written before demo_source was added: the reader reads it as 'odometry'
        expected = pa.schema(list(expected)[:-1])
    if names != expected.names:
        missing = [n for n in expected.names if n not in names]
        extra = [n for n in names if n not in expected.names]
        what = (
            f"lacks column {missing[0]}"
            if missing
            else f"has an unknown column {extra[0]}"
            if extra
            else "has its columns in another order"
        )
        raise BadParquetFile(path, f"{what} (not an irlsim {table} table of this version)", _REGENERATE)
    for f in expected:
        got = schema.field(f.name).type
        if got != f.type:
            raise BadParquetFile(
                path,
                f"column {f.name} is {got}, this irlsim's {table} table has {f.type}"
                + (" (another planner.n_control_points?)" if f.name in ("control_points", "actions") else ""),
                "remove it from the dataset folder, or re-collect the dataset with 'irlsim collect'",
            )


def _manifest_error(manifest_path: Path, what: str) -> IrlsimError:
    return IrlsimError(
        f"{manifest_path} {what}: re-collect the dataset with 'irlsim collect' (or restore it)"
    )


def _int_list(v: Any) -> bool:
    return isinstance(v, list) and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in v)


def validate_manifest(manifest: dict[str, Any], manifest_path: Path) -> None:
    """The manifest against its schema, before anything is read by it (one-line IrlsimError naming the
    key): schema_version, feature_names, complete (bool), config (a table; planner.n_policies and
    n_control_points positive integers when present), splits ({split: [episode ids >= 0, unique]}),
    seeds and counts (tables per split, when present)."""
    path = manifest_path.parent
    version = manifest.get("schema_version")
    if version != SCHEMA_VERSION:
        raise IrlsimError(
            f"dataset {path} has schema version {version}, this irlsim reads {SCHEMA_VERSION}: "
            "re-collect it with 'irlsim collect'"
        )
    names = manifest.get("feature_names")
    if feature_set_of(names) is None:
        raise IrlsimError(
            f"dataset {path} has features {names}, this irlsim computes {list(FEATURE_NAMES)} (or a "
            f"larger set, planner.feature_set: {', '.join(FEATURE_SETS)}): re-collect it with "
            "'irlsim collect'"
        )
    if "complete" in manifest and not isinstance(manifest["complete"], bool):
        raise _manifest_error(manifest_path, f"has 'complete': {manifest['complete']!r}, not true or false")
    splits = manifest.get("splits")
    if not isinstance(splits, dict):
        raise IrlsimError(f"{manifest_path} has no 'splits' mapping: re-collect it with 'irlsim collect'")
    for name, episodes in splits.items():
        if not _int_list(episodes):
            raise _manifest_error(
                manifest_path, f"has splits.{name} = {str(episodes)[:40]}, not a list of episode ids >= 0"
            )
        if len(set(episodes)) != len(episodes):
            raise _manifest_error(manifest_path, f"lists an episode of splits.{name} twice")
    config = manifest.get("config", {})
    if not isinstance(config, dict):
        raise _manifest_error(manifest_path, "has a 'config' that is not a table")
    planner = config.get("planner", {})
    if not isinstance(planner, dict):
        raise _manifest_error(manifest_path, "has a 'config.planner' that is not a table")
    for key in ("n_policies", "n_control_points"):
        v = planner.get(key, 1)
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise _manifest_error(manifest_path, f"has config.planner.{key} = {v!r}, not an integer >= 1")
    if not isinstance(manifest.get("seeds", {}), (dict, list)):
        raise _manifest_error(manifest_path, "has 'seeds' that are neither a table nor a list")
    counts = manifest.get("counts", {})
    if not isinstance(counts, dict) or not all(isinstance(v, dict) for v in counts.values()):
        raise _manifest_error(manifest_path, "has 'counts' that are not a table per split")
