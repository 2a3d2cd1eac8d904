"""Robustness of the dataset reader and writer: incomplete datasets, corrupt or foreign episode files,
concurrent cache builds, and the resume-config comparison."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data import reader as reader_mod
from irlsim.data.layout import check_episode, remove_partial, write_manifest
from irlsim.data.reader import Dataset, open_dataset
from irlsim.errors import IrlsimError
from tests.data.conftest import K, make_dataset, write_episode

INCOMPLETE = (
    "is incomplete (collection was interrupted): re-run the same 'irlsim collect' command to finish it"
)


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


@pytest.fixture()
def tiny_synthetic(tmp_path: Path) -> Path:
    """Train episodes 0 and 1 of 60 cycles; validation episode 2 of 10 cycles (another row count)."""
    root = make_dataset(tmp_path / "ds", {"train": [0, 1]})
    write_episode(root, "validation", 2, n_steps=20)
    return root


def _mark_incomplete(root: Path) -> None:
    """The manifest 'irlsim collect' writes while it runs: no episodes listed, complete false."""
    write_manifest(root, {"config": {}, "seeds": {}, "splits": {"train": []}, "complete": False})


def test_incomplete_dataset_is_refused_everywhere(dataset: Path, tmp_path: Path, capsys) -> None:
    assert json.loads((dataset / "manifest.json").read_text())["complete"] is True
    open_dataset(dataset).split_tensors("train")  # complete: fine
    _mark_incomplete(dataset)
    with pytest.raises(IrlsimError) as exc:
        open_dataset(dataset)
    assert str(exc.value) == f"dataset {dataset} {INCOMPLETE}"
    manifest = json.loads((dataset / "manifest.json").read_text())
    with pytest.raises(IrlsimError, match="is incomplete"):
        Dataset(dataset, manifest).split_tensors("train")
    for argv in (
        ["data", "info", str(dataset)],
        ["train", "--stage", "1", "--data", str(dataset), "--out", str(tmp_path / "runs")],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"irlsim: error: dataset {dataset} {INCOMPLETE}"], argv
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("splits, ok", [({"train": [], "validation": []}, False), ({"train": [0, 1]}, True)])
def test_manifest_without_the_complete_flag(dataset: Path, splits: dict, ok: bool) -> None:
    """Manifests from before the flag: an unfinished run listed no episode at all."""
    manifest = json.loads((dataset / "manifest.json").read_text())
    del manifest["complete"]
    manifest["splits"] = splits
    (dataset / "manifest.json").write_text(json.dumps(manifest))
    if ok:
        assert open_dataset(dataset).episodes("train") == [0, 1]
    else:
        with pytest.raises(IrlsimError, match="is incomplete"):
            open_dataset(dataset)


def test_write_manifest_rejects_a_non_boolean_complete(dataset: Path) -> None:
    with pytest.raises(ValueError, match="'complete' must be true or false"):
        write_manifest(dataset, {"config": {}, "seeds": {}, "splits": {}, "complete": "yes"})


def test_two_readers_building_the_cache_at_once(dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A second reader builds the whole cache while the first is half way: both must succeed and leave
    the same arrays (with fixed temporary names the second would overwrite the first's files)."""
    real = reader_mod.iter_policy_groups
    nested: list[np.ndarray] = []

    def interleaved(*args, **kwargs):
        if not nested:
            nested.append(np.zeros(0))  # only once, and not inside the nested build
            nested[0] = np.array(open_dataset(dataset).split_tensors("train").features)
        yield from real(*args, **kwargs)

    monkeypatch.setattr(reader_mod, "iter_policy_groups", interleaved)
    first = np.array(open_dataset(dataset).split_tensors("train").features)
    monkeypatch.undo()
    assert first.shape == nested[0].shape and first.shape[0] == 120
    np.testing.assert_array_equal(first, nested[0])
    cache = dataset / reader_mod.CACHE_DIR / "train"
    assert not list(cache.glob(".*")), "temporary files left behind"
    # the cache both wrote is valid: a third reader reuses it without rebuilding
    monkeypatch.setattr(reader_mod.Dataset, "_build_cache", lambda *a: pytest.fail("cache rebuilt"))
    np.testing.assert_array_equal(np.array(open_dataset(dataset).split_tensors("train").features), first)


def test_failed_cache_build_leaves_no_temporary_file(dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args, **kwargs):
        raise OSError("disk full")
        yield  # pragma: no cover - makes this a generator

    monkeypatch.setattr(reader_mod, "iter_policy_groups", broken)
    with pytest.raises(OSError, match="disk full"):
        open_dataset(dataset).split_tensors("train")
    cache = dataset / reader_mod.CACHE_DIR / "train"
    assert sorted(p.name for p in cache.iterdir()) == []


# -- corrupt or foreign episode files ---------------------------------------------------------------------


def test_check_episode_accepts_a_good_pair(dataset: Path) -> None:
    assert check_episode(dataset, "train", 0, n_policies=24, n_control_points=K) is None


def _swap_in(dataset: Path, name: str, source: str) -> Path:
    """Replace train/<name> by a copy of another file of the dataset."""
    target = dataset / "train" / name
    shutil.copyfile(dataset / source, target)
    return target


@pytest.mark.parametrize(
    "damage, expected",
    [
        (
            lambda d: _truncate(d / "train/episode_00000.cycles.parquet"),
            "cycles.parquet is truncated or corrupt",
        ),
        (lambda d: _truncate(d / "train/episode_00000.policies.parquet"), "policies.parquet is truncated"),
        (
            lambda d: pq.write_table(pa.table({"x": [1]}), d / "train/episode_00000.cycles.parquet"),
            "cycles.parquet is not an irlsim cycles table",
        ),
        (
            lambda d: _swap_in(d, "episode_00000.cycles.parquet", "train/episode_00001.cycles.parquet"),
            "cycles.parquet holds episode 1, not 0",
        ),
        (
            lambda d: _swap_in(d, "episode_00000.policies.parquet", "train/episode_00001.policies.parquet"),
            "policies.parquet holds episodes 1..1, not 0",
        ),
        (
            lambda d: _swap_in(
                d, "episode_00000.policies.parquet", "validation/episode_00002.policies.parquet"
            ),
            "policies.parquet has 240 rows, its cycles file describes 1440 policies",
        ),
    ],
)
def test_check_episode_names_the_bad_file(tiny_synthetic: Path, damage, expected: str) -> None:
    damage(tiny_synthetic)
    problem = check_episode(tiny_synthetic, "train", 0, n_policies=24, n_control_points=K)
    assert problem is not None and expected in problem and str(tiny_synthetic / "train") in problem
    assert "\n" not in problem


def test_check_episode_compares_with_the_config(dataset: Path) -> None:
    problem = check_episode(dataset, "train", 0, n_policies=25)
    assert (
        problem
        == f"{dataset}/train/episode_00000.cycles.parquet has 24 policies per cycle, the config asks for 25"
    )
    problem = check_episode(dataset, "train", 0, n_control_points=K + 1)
    assert problem is not None and f"({K + 1} control points)" in problem


def test_manifest_counts_over_a_truncated_file_is_one_line(dataset: Path) -> None:
    path = dataset / "validation" / "episode_00002.cycles.parquet"
    _truncate(path)
    with pytest.raises(IrlsimError) as exc:
        write_manifest(dataset, {"config": {}, "seeds": {}, "splits": {"train": [0, 1], "validation": [2]}})
    msg = str(exc.value)
    assert msg.startswith(f"{path} is truncated or corrupt (") and "\n" not in msg


def test_remove_partial_drops_unpaired_files(dataset: Path) -> None:
    (dataset / "train" / "episode_00001.policies.parquet").unlink()
    (dataset / "validation" / "episode_00002.cycles.parquet").unlink()
    assert remove_partial(dataset, "train") == [dataset / "train" / "episode_00001.cycles.parquet"]
    assert remove_partial(dataset, "validation") == [
        dataset / "validation" / "episode_00002.policies.parquet"
    ]
    assert sorted(p.name for p in (dataset / "train").iterdir()) == [
        "episode_00000.cycles.parquet",
        "episode_00000.policies.parquet",
    ]


def test_first_difference_names_the_dotted_key() -> None:
    from irlsim.data.collection import MISSING, data_config, first_difference

    old = {"seed": 0, "workers": 1, "planner": {"n_policies": 120, "dt": 0.1}}
    assert first_difference(old, old) is None
    assert first_difference(old, {**old, "planner": {"n_policies": 121, "dt": 0.1}}) == (
        "planner.n_policies",
        120,
        121,
    )
    assert first_difference(old, {"seed": 0, "workers": 1, "planner": {"n_policies": 120}}) == (
        "planner.dt",
        0.1,
        MISSING,
    )
    assert repr(MISSING) == "(not set)"
    assert first_difference(data_config(old), data_config({**old, "workers": 2})) is None
