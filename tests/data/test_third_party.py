"""A dataset opened without irlsim: the guide's DuckDB queries (docs/guide/data.md), and the ways a
split folder is read by DuckDB, polars, pyarrow and pandas.

A split folder holds two tables (cycles and policies files, two schemas) and each episode's
``stats.json``, so the folder itself is not one table: ``pd.read_parquet('<ds>/train')`` cannot work. The
documented ways name the files, by glob (DuckDB, polars) or by list (pyarrow.dataset, pandas).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.dataset as pads
import pyarrow.parquet as pq
import pytest

from irlsim import FEATURE_NAMES, N_FEATURES
from irlsim.data.reader import fixed_list_to_numpy, open_dataset

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "data.md"


def _guide_queries() -> list[str]:
    """The SQL statements of the guide's page on data, comments dropped."""
    blocks = re.findall(r"```sql\n(.*?)```", GUIDE.read_text(), flags=re.S)
    assert len(blocks) == 1, "expected one SQL block in docs/guide/data.md"
    lines = [line for line in blocks[0].splitlines() if not line.lstrip().startswith("--")]
    return [q.strip() for q in "\n".join(lines).split(";") if q.strip()]


def test_guide_duckdb_queries_give_the_numbers_numpy_gives(tiny_dataset: Path) -> None:
    duckdb = pytest.importorskip("duckdb")
    queries = _guide_queries()
    assert len(queries) == 2 and all("'data/default/train/" in q for q in queries)
    queries = [q.replace("'data/default/", f"'{tiny_dataset}/") for q in queries]

    # the expected answers straight from the files with pyarrow and numpy (no irlsim reader)
    cyc = pq.read_table(_files(tiny_dataset, "train", "cycles"))
    pol = pq.read_table(
        _files(tiny_dataset, "train", "policies"), columns=["episode", "cycle", "policy", "features"]
    )
    has = cyc.column("has_demo").to_numpy(zero_copy_only=False)
    demo_index = cyc.column("demo_index").to_numpy()
    assert 0 < has.sum() < len(has)  # both kinds of cycle, so the WHERE clause matters

    # query 1: mean demonstration distance, and how often the executed policy was the demonstration
    (row,) = duckdb.sql(queries[0]).fetchall()
    expected = (
        cyc.column("demo_distance").to_numpy()[has].astype(np.float64).mean(),
        (cyc.column("executed_index").to_numpy()[has] == demo_index[has]).mean(),
    )
    np.testing.assert_allclose(row, expected, rtol=1e-6)

    # query 2: feature means of the demonstrated policies vs the others, over cycles with a demonstration;
    # DuckDB lists count from 1, so features[11] and features[15] are the guide's progress and proximity
    assert FEATURE_NAMES[11 - 1] == "progress" and FEATURE_NAMES[15 - 1] == "proximity"
    n = pol.num_rows // cyc.num_rows  # policies per cycle; both files are in (episode, cycle) order
    for key in ("episode", "cycle"):  # the join by position is the join USING (episode, cycle)
        np.testing.assert_array_equal(pol.column(key).to_numpy(), np.repeat(cyc.column(key).to_numpy(), n))
    feats = pol.column("features").combine_chunks().flatten().to_numpy().reshape(-1, N_FEATURES)
    in_demo_cycle = np.repeat(has, n)
    is_demo = pol.column("policy").to_numpy() == np.repeat(demo_index, n)
    got = {r[0]: r[1:] for r in duckdb.sql(queries[1]).fetchall()}
    assert set(got) == {True, False}
    for flag, mask in ((True, in_demo_cycle & is_demo), (False, in_demo_cycle & ~is_demo)):
        f = feats[mask].astype(np.float64)
        np.testing.assert_allclose(got[flag], (f[:, 10].mean(), f[:, 14].mean()), rtol=1e-6)


def _assert_same(table: pa.Table, ref: pa.Table) -> None:
    """Same column names, types and values (NaN equal to NaN; nullability and metadata ignored; a string
    column may come back as large_string, as polars and DuckDB return strings)."""

    def kind(t: pa.DataType) -> pa.DataType:
        return pa.string() if t == pa.large_string() else t

    assert [(f.name, kind(f.type)) for f in table.schema] == [(f.name, kind(f.type)) for f in ref.schema]
    pd.testing.assert_frame_equal(table.to_pandas(), ref.to_pandas())


def _files(root: Path, split: str, table: str) -> list[str]:
    return sorted(str(p) for p in (root / split).glob(f"*.{table}.parquet"))


def test_split_folder_read_by_glob_or_file_list(dataset: Path) -> None:
    """Every documented way gives the rows the irlsim reader gives, in (episode, cycle) order."""
    duckdb = pytest.importorskip("duckdb")
    pl = pytest.importorskip("polars")
    ref = open_dataset(dataset).read_cycles_table("train")
    n_rows = ref.num_rows * int(ref.column("n_policies")[0].as_py())

    cycles = _files(dataset, "train", "cycles")
    _assert_same(pads.dataset(cycles, format="parquet").to_table(), ref)
    pd.testing.assert_frame_equal(pd.read_parquet(cycles), ref.to_pandas())
    glob = f"{dataset}/train/*.cycles.parquet"
    _assert_same(pl.read_parquet(glob).sort(["episode", "cycle"]).to_arrow(), ref)
    by_duckdb = duckdb.sql(f"SELECT * FROM '{glob}' ORDER BY episode, cycle").arrow()
    if isinstance(by_duckdb, pa.RecordBatchReader):  # DuckDB >= 1.4 returns a reader
        by_duckdb = by_duckdb.read_all()
    _assert_same(by_duckdb, ref)

    policies = _files(dataset, "train", "policies")
    table = pads.dataset(policies, format="parquet").to_table()
    assert table.num_rows == n_rows
    feats = fixed_list_to_numpy(table.column("features"), N_FEATURES)
    st = open_dataset(dataset).split_tensors("train")
    np.testing.assert_array_equal(feats, np.asarray(st.features).reshape(-1, N_FEATURES))
    assert pl.scan_parquet(f"{dataset}/train/*.policies.parquet").select(pl.len()).collect().item() == n_rows
    one = pd.read_parquet(policies[0])  # pandas on a single file
    assert len(one) == n_rows // 2 and len(one["features"].iloc[0]) == N_FEATURES
