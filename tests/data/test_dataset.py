"""Writer / reader round trip, atomicity, determinism, validation errors, cache, info."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim import FEATURE_NAMES, N_FEATURES
from irlsim.data import writer as writer_mod
from irlsim.data.demos import DemoProjector
from irlsim.data.info import dataset_info, format_info
from irlsim.data.layout import episode_done, remove_partial, write_manifest
from irlsim.data.lz4rows import Lz4Rows
from irlsim.data.reader import Dataset, open_dataset
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.data.writer import EpisodeWriter
from irlsim.errors import IrlsimError
from tests.data.conftest import DT, LAP, K, T, make_dataset, make_policy_set, write_episode


def _parquet_files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*.parquet"))


def test_round_trip_is_exact(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    rng = np.random.default_rng(7)
    n, n_cycles = 16, 12
    sets = [make_policy_set(rng, n, 0.2 * k, 50.0 + 4.0 * k) for k in range(n_cycles)]
    dists = rng.random((n_cycles, n)).astype(np.float32)
    dists[-3:] = np.nan  # incomplete windows at the end of the episode
    demo_idx = np.where(
        np.arange(n_cycles) < n_cycles - 3, np.nanargmin(np.where(np.isnan(dists), 9, dists), 1), -1
    )
    executed = rng.integers(n, size=n_cycles)
    with EpisodeWriter(root, "test", 5, cycles_per_row_group=5) as w:
        for k, ps in enumerate(sets):
            ego = {
                "x": 1.5 * k,
                "y": -2.0,
                "yaw": 0.25,
                "v": 19.5,
                "s": 50.0 + 4.0 * k,
                "d": 0.125,
                "lane": 2,
            }
            w.add_cycle(k, ps, ego, executed_index=int(executed[k]), target_checkpoint=1)
        # demonstrations arrive in any order
        for k in reversed(range(n_cycles)):
            dd = float(dists[k, demo_idx[k]]) if demo_idx[k] >= 0 else float("nan")
            w.add_demo(writer_mod.Projection(k, dists[k], int(demo_idx[k]), dd))
    write_manifest(root, {"config": {}, "seeds": [1], "splits": {"test": [5]}})

    ds = open_dataset(root)
    st = ds.split_tensors("test")
    assert (st.n_cycles, st.n_policies) == (n_cycles, n)
    np.testing.assert_array_equal(st.features, np.stack([ps.features for ps in sets]))
    np.testing.assert_array_equal(st.control_points, np.stack([ps.control_points for ps in sets]))
    np.testing.assert_array_equal(st.actions, np.stack([ps.actions for ps in sets]))
    np.testing.assert_array_equal(st.labels, np.stack([ps.labels for ps in sets]))
    np.testing.assert_array_equal(st.distances, dists)  # NaN == NaN for array_equal on floats
    np.testing.assert_array_equal(st.demo_index, demo_idx)
    np.testing.assert_array_equal(st.executed_index, executed)
    np.testing.assert_array_equal(st.cycle, np.arange(n_cycles))
    assert (st.episode == 5).all()
    cyc = ds.read_cycles("test")
    assert list(cyc["ego_lane"].unique()) == [2] and (cyc["n_policies"] == n).all()
    assert (cyc["has_demo"].to_numpy() == (demo_idx >= 0)).all()
    assert np.isnan(cyc["demo_distance"].to_numpy()[-3:]).all()
    np.testing.assert_array_equal(cyc["t"].to_numpy(), (0.2 * np.arange(n_cycles)).astype(np.float32))
    # row groups hold whole cycles, aligned between the two files
    pol = pq.ParquetFile(root / "test" / "episode_00005.policies.parquet")
    assert [pol.metadata.row_group(i).num_rows for i in range(pol.num_row_groups)] == [5 * n, 5 * n, 2 * n]
    cycles_pf = pq.ParquetFile(root / "test" / "episode_00005.cycles.parquet")
    assert [cycles_pf.metadata.row_group(i).num_rows for i in range(cycles_pf.num_row_groups)] == [5, 5, 2]


def test_same_inputs_give_identical_bytes(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    write_episode(a, "train", 3, seed=11)
    write_episode(b, "train", 3, seed=11)
    files = _parquet_files(a)
    assert files == _parquet_files(b) and len(files) == 2
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes()
    assert b"parquet-cpp" in (a / files[0]).read_bytes()[-2000:]  # created_by only, no timestamp


def test_exception_during_episode_leaves_no_file(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    with (
        pytest.raises(RuntimeError, match="killed"),
        EpisodeWriter(tmp_path, "train", 0, cycles_per_row_group=2) as w,
    ):
        for k in range(6):  # enough to have flushed row groups into the temporary file
            ps = make_policy_set(rng, 8, 0.2 * k, 0.0)
            w.add_cycle(
                k,
                ps,
                dict.fromkeys(("x", "y", "yaw", "v", "s", "d", "lane"), 0.0),
                executed_index=0,
                target_checkpoint=0,
            )
            w.add_demo(writer_mod.Projection(k, np.zeros(8, np.float32), 0, 0.0))
        raise RuntimeError("killed")
    assert list((tmp_path / "train").iterdir()) == []
    assert not episode_done(tmp_path, "train", 0)


def test_failure_inside_atomic_write_of_cycles_file_leaves_no_parquet(tmp_path: Path, monkeypatch) -> None:
    write_episode(tmp_path, "train", 0)  # a complete episode stays
    real = pq.write_table

    def boom(table, where, **kwargs):  # write half a file, then die
        real(table, where, **kwargs)
        Path(where).write_bytes(Path(where).read_bytes()[:100])
        raise KeyboardInterrupt("killed while writing")

    monkeypatch.setattr(writer_mod.pq, "write_table", boom)
    with pytest.raises(KeyboardInterrupt):
        write_episode(tmp_path, "train", 1)
    assert _parquet_files(tmp_path) == [
        "train/episode_00000.cycles.parquet",
        "train/episode_00000.policies.parquet",
    ]
    assert [p.name for p in (tmp_path / "train").iterdir() if p.name.endswith(".tmp")] == []
    assert episode_done(tmp_path, "train", 0) and not episode_done(tmp_path, "train", 1)


def test_remove_partial_cleans_a_killed_run(tmp_path: Path) -> None:
    write_episode(tmp_path, "train", 0)
    folder = tmp_path / "train"
    (folder / ".episode_00001.policies.parquet.abc.tmp").write_bytes(b"x")
    (folder / "episode_00001.policies.parquet").write_bytes(b"x")
    removed = remove_partial(tmp_path, "train")
    assert len(removed) == 2
    assert _parquet_files(tmp_path) == [
        "train/episode_00000.cycles.parquet",
        "train/episode_00000.policies.parquet",
    ]


def test_close_requires_every_demonstration(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    w = EpisodeWriter(tmp_path, "train", 0)
    ps = make_policy_set(rng, 8, 0.0, 0.0)
    w.add_cycle(
        0,
        ps,
        dict.fromkeys(("x", "y", "yaw", "v", "s", "d", "lane"), 0.0),
        executed_index=0,
        target_checkpoint=0,
    )
    with pytest.raises(ValueError, match="finish"):
        w.close()
    assert _parquet_files(tmp_path) == []


def test_manifest(dataset: Path) -> None:
    m = json.loads((dataset / "manifest.json").read_text())
    assert m["schema_version"] == SCHEMA_VERSION and m["feature_names"] == list(FEATURE_NAMES)
    assert m["splits"] == {"train": [0, 1], "validation": [2]}
    counts = m["counts"]["train"]
    assert counts["episodes"] == 2 and counts["cycles"] == 120 and counts["policies_per_cycle"] == 24
    assert 0 < counts["cycles_with_demo"] <= counts["cycles"] - 2 * 25
    assert m["created_by"].startswith("irlsim")


def test_split_tensors_shapes_order_and_demos(tmp_path: Path) -> None:
    root = make_dataset(tmp_path / "ds", {"train": [7, 3], "test": [4]})
    st = open_dataset(root).split_tensors("train")
    c = 120
    assert st.features.shape == (c, 24, N_FEATURES) and st.features.dtype == np.float32
    assert st.control_points.shape == (c, 24, K, 3) and st.actions.shape == (c, 24, K, 2)
    assert st.labels.shape == (c, 24, 3) and st.labels.dtype == np.bool_
    assert st.distances.shape == (c, 24) and st.demo_index.dtype == np.int64
    np.testing.assert_array_equal(st.episode, np.repeat([3, 7], 60))  # (episode, cycle) order
    np.testing.assert_array_equal(st.cycle, np.tile(np.arange(60), 2))
    has = st.has_demo
    assert has.sum() > 0
    np.testing.assert_array_equal(st.demo_index[has], np.argmin(st.distances[has], axis=1))
    np.testing.assert_array_equal(st.demo_distance[has], st.distances[has].min(axis=1))
    assert np.isnan(st.demo_distance[~has]).all()
    # the synthetic ego drives exactly one of the policies: distance 0
    assert (st.demo_distance[has] < 1e-4).all()
    # the last cycles of each episode have incomplete windows
    last = st.cycle >= 60 - 25
    assert not has[last].any() and np.isnan(st.distances[last]).all()
    head = open_dataset(root).split_tensors("train", max_cycles=10)
    full = open_dataset(root).split_tensors("train").features
    assert head.n_cycles == 10 and head.features.data is not None  # a view of the rows: nothing read
    assert np.asarray(head.features).tobytes() == full[:10, ...].tobytes()


def _count_cache_builds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = Dataset._build_cache

    def counting(self: Dataset, *args: object, **kwargs: object) -> None:
        calls.append(1)
        real(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Dataset, "_build_cache", counting)
    return calls


def test_cache_is_reused_and_invalidated(dataset: Path, monkeypatch) -> None:
    ds = open_dataset(dataset)
    first = ds.split_tensors("train")
    assert isinstance(first.features, Lz4Rows)
    calls = _count_cache_builds(monkeypatch)
    again = open_dataset(dataset).split_tensors("train")
    assert calls == []
    np.testing.assert_array_equal(again.features, first.features)
    # rewrite one episode with other content: the cache must be rebuilt
    before = np.array(first.features)
    write_episode(dataset, "train", 1, seed=99)
    changed = open_dataset(dataset).split_tensors("train")
    assert len(calls) == 1
    assert not np.array_equal(np.array(changed.features), before)
    np.testing.assert_array_equal(np.array(changed.features[:60]), before[:60])  # episode 0 unchanged


def test_cache_invalidated_by_touch(dataset: Path, monkeypatch) -> None:
    open_dataset(dataset).split_tensors("validation")
    calls = _count_cache_builds(monkeypatch)
    p = dataset / "validation" / "episode_00002.policies.parquet"
    st = p.stat()
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    open_dataset(dataset).split_tensors("validation")
    assert len(calls) == 1


# -- errors ----------------------------------------------------------------------------------------------


def test_missing_dataset_and_manifest(tmp_path: Path) -> None:
    with pytest.raises(IrlsimError, match="does not exist"):
        open_dataset(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(IrlsimError, match="no manifest.json"):
        open_dataset(tmp_path / "empty")


def test_other_schema_version(dataset: Path) -> None:
    m = json.loads((dataset / "manifest.json").read_text())
    m["schema_version"] = SCHEMA_VERSION + 1
    (dataset / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(IrlsimError) as err:
        open_dataset(dataset)
    msg = str(err.value)
    assert f"has schema version {SCHEMA_VERSION + 1}, this irlsim reads {SCHEMA_VERSION}" in msg
    assert "re-collect it with 'irlsim collect'" in msg and "\n" not in msg


def test_other_feature_names(dataset: Path) -> None:
    m = json.loads((dataset / "manifest.json").read_text())
    m["feature_names"] = m["feature_names"][::-1]
    (dataset / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(IrlsimError, match="features"):
        open_dataset(dataset)


def test_truncated_file(dataset: Path) -> None:
    p = dataset / "train" / "episode_00001.policies.parquet"
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    with pytest.raises(IrlsimError) as err:
        open_dataset(dataset).split_tensors("train")
    msg = str(err.value)
    assert str(p) in msg and "delete it and re-run irlsim collect to regenerate it" in msg and "\n" not in msg


def test_corrupt_bytes_inside_a_file(dataset: Path) -> None:
    p = dataset / "train" / "episode_00000.policies.parquet"
    data = bytearray(p.read_bytes())
    data[100:4000] = bytes(3900)  # zero page data, footer intact
    p.write_bytes(bytes(data))
    with pytest.raises(IrlsimError, match="delete it and re-run irlsim collect"):
        open_dataset(dataset).split_tensors("train")


def test_foreign_parquet_file(dataset: Path) -> None:
    p = dataset / "train" / "episode_00000.cycles.parquet"
    pd.DataFrame({"a": [1, 2, 3]}).to_parquet(p)
    with pytest.raises(IrlsimError, match="not an irlsim cycles table"):
        open_dataset(dataset).read_cycles("train")


def test_file_of_other_schema_version(dataset: Path) -> None:
    p = dataset / "train" / "episode_00000.cycles.parquet"
    t = pq.read_table(p)
    pq.write_table(t.replace_schema_metadata({**t.schema.metadata, b"irlsim.schema_version": b"0"}), p)
    with pytest.raises(IrlsimError, match="has schema version 0, this irlsim reads"):
        open_dataset(dataset).read_cycles("train")


def test_policy_count_not_constant(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    write_episode(root, "train", 0, n_policies=24)
    write_episode(root, "train", 1, n_policies=20)
    write_manifest(root, {"config": {}, "seeds": [], "splits": {"train": [0, 1]}})
    with pytest.raises(IrlsimError, match="policies per cycle"):
        open_dataset(root).split_tensors("train")


def test_unknown_split_and_missing_episode(dataset: Path) -> None:
    with pytest.raises(IrlsimError, match="no split 'test': choose one of train, validation"):
        open_dataset(dataset).split_tensors("test")
    (dataset / "validation" / "episode_00002.policies.parquet").unlink()
    with pytest.raises(IrlsimError, match="is missing"):
        open_dataset(dataset).split_tensors("validation")


def test_writer_rejects_changing_policy_count(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    ego = dict.fromkeys(("x", "y", "yaw", "v", "s", "d", "lane"), 0.0)
    w = EpisodeWriter(tmp_path, "train", 0)
    w.add_cycle(0, make_policy_set(rng, 8, 0.0, 0.0), ego, executed_index=0, target_checkpoint=0)
    with pytest.raises(ValueError, match="policies"):
        w.add_cycle(1, make_policy_set(rng, 9, 0.2, 0.0), ego, executed_index=0, target_checkpoint=0)
    w.abort()
    assert _parquet_files(tmp_path) == []


# -- info and foreign readers ------------------------------------------------------------------------------


def test_info(dataset: Path) -> None:
    info = dataset_info(dataset)
    tr = info["splits"]["train"]
    assert tr["cycles"] == 120 and tr["policies_per_cycle"] == 24 and tr["episodes"] == 2
    assert tr["demo_distance"]["mean"] < 1e-4 < tr["random_policy_distance"]
    st = open_dataset(dataset).split_tensors("train")
    feats = np.concatenate(
        [
            np.asarray(st.features).reshape(-1, N_FEATURES),
            np.asarray(open_dataset(dataset).split_tensors("validation").features).reshape(-1, N_FEATURES),
        ]
    )
    assert info["features"]["acc_lon"]["mean"] == pytest.approx(feats[:, 0].mean(dtype=np.float64), rel=1e-9)
    assert info["features"]["proximity"]["std"] == pytest.approx(feats[:, -1].std(dtype=np.float64), rel=1e-6)
    assert info["features"]["velocity"]["max"] == pytest.approx(float(feats[:, 4].max()))
    assert info["disk_bytes"] > 0
    text = format_info(info)
    assert "train" in text and "proximity" in text and "MiB" in text
    json.dumps(info)


def test_files_open_without_project_code(dataset: Path) -> None:
    pol = dataset / "train" / "episode_00000.policies.parquet"
    cyc = dataset / "train" / "episode_00000.cycles.parquet"
    df = pd.read_parquet(pol)
    assert len(df) == 60 * 24 and len(df["features"].iloc[0]) == N_FEATURES
    assert len(df["control_points"].iloc[0]) == 3 * K
    t = pq.read_table(cyc)
    assert t.schema.field("ego_lane").type == pa.int8() and t.num_rows == 60
    assert pq.read_metadata(cyc).metadata[b"irlsim.table"] == b"cycles"


def test_duckdb_reads_dataset(dataset: Path) -> None:
    duckdb = pytest.importorskip("duckdb")
    n = duckdb.sql(f"select count(*) from read_parquet('{dataset}/train/*.policies.parquet')").fetchall()[0][
        0
    ]
    assert n == 120 * 24


def test_polars_reads_dataset(dataset: Path) -> None:
    pl = pytest.importorskip("polars")
    df = pl.read_parquet(dataset / "train" / "episode_00000.cycles.parquet")
    assert df.height == 60 and "demo_index" in df.columns


def test_projector_and_writer_together_store_argmin(tmp_path: Path) -> None:
    # the collection loop of conftest.write_episode, checked against a recomputation from PolicySets
    rng = np.random.default_rng(5)
    proj = DemoProjector(lap_length=LAP)
    ps = make_policy_set(rng, 12, 0.0, 10.0)
    proj.push_cycle(0, 0.0, ps.s, ps.d, ps.yaw)
    j = 3
    for step in range(T):
        proj.push_odometry(step * DT, ps.s[j, step], ps.d[j, step] + 0.2, 0.0)
    ego = {"x": 0.0, "y": 0.0, "yaw": 0.0, "v": 1.0, "s": 10.0, "d": 0.0, "lane": 0}
    with EpisodeWriter(tmp_path, "test", 0) as w:
        w.add_cycle(0, ps, ego, executed_index=j, target_checkpoint=0)
        w.add_demos(proj.finish())
    write_manifest(tmp_path, {"config": {}, "seeds": [], "splits": {"test": [0]}})
    st = open_dataset(tmp_path).split_tensors("test")
    assert st.demo_index[0] == j and st.demo_distance[0] == pytest.approx(0.2, rel=1e-5)
