"""Readers validate the manifest and every file's columns; every command checks its outputs before work
and turns OS errors into one line; training locks its runs folder."""

import errno
import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim import outputs
from irlsim.cli import main
from irlsim.data.reader import open_dataset
from irlsim.errors import IrlsimError
from irlsim.utils import exclusive_lock

TINY1 = ["--config", "configs/train/tiny_stage1.toml", "--set", 'models=["LIRL"]', "--set", "epochs=1"]


def _fails(capsys, argv: list[str], *needles: str, rc: int = 2) -> str:
    assert main(argv) == rc
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for n in needles:
        assert n in err, err
    return err


@pytest.fixture()
def data(tiny_dataset, tmp_path):
    out = tmp_path / "data"
    shutil.copytree(tiny_dataset, out, ignore=shutil.ignore_patterns(".cache", ".lock"))
    return out


# -------------------------------------------------------------------------------------------- readers


def _rewrite_policies(path: Path, column: str, width: int) -> None:
    """Replace a fixed-size-list column by one of another width (the file's irlsim metadata kept)."""
    t = pq.read_table(path)
    col = t.column(column).combine_chunks()
    flat = col.flatten().to_numpy().reshape(len(col), -1)
    flat = np.resize(flat, (len(col), width)).astype(np.float32)
    new = pa.FixedSizeListArray.from_arrays(pa.array(flat.ravel()), width)
    i = t.schema.get_field_index(column)
    t = t.set_column(i, pa.field(column, new.type, nullable=False), new)
    pq.write_table(t.replace_schema_metadata(pq.read_schema(path).metadata), path)


@pytest.mark.parametrize(
    "column, width, needle",
    [
        ("features", 14, "column features is fixed_size_list<element: float>[14]"),
        ("control_points", 15, "(another planner.n_control_points?)"),  # an episode of K = 5
    ],
)
def test_a_file_whose_columns_differ_is_one_line(data, capsys, tmp_path, column, width, needle):
    path = data / "train" / "episode_00000.policies.parquet"
    _rewrite_policies(path, column, width)
    _fails(
        capsys, ["train", "--stage", "1", "--data", str(data), "--out", str(tmp_path / "r"), *TINY1], needle
    )
    _fails(capsys, ["data", "info", str(data)], str(path))


@pytest.mark.parametrize(
    "key, value, needle",
    [
        ("splits.train", ["x"], "splits.train = ['x'], not a list of episode ids"),
        ("splits.train", 5, "splits.train = 5, not a list"),
        ("splits.train", [0, 0], "lists an episode of splits.train twice"),
        ("complete", "yes", "'complete': 'yes', not true or false"),
        ("counts", {"train": 3}, "'counts' that are not a table per split"),
        ("config.planner.n_policies", -3, "config.planner.n_policies = -3"),
        ("config", [], "'config' that is not a table"),
    ],
)
def test_a_manifest_outside_its_schema_is_one_line(data, capsys, tmp_path, key, value, needle):
    m = json.loads((data / "manifest.json").read_text())
    node, *path = key.split(".")
    target = m
    for part in [node, *path][:-1]:
        target = target[part]
    target[[node, *path][-1]] = value
    (data / "manifest.json").write_text(json.dumps(m))
    _fails(capsys, ["data", "info", str(data)], needle)
    _fails(
        capsys, ["train", "--stage", "1", "--data", str(data), "--out", str(tmp_path / "r"), *TINY1], needle
    )


def test_a_truncated_file_is_one_line(data, capsys, tmp_path):
    path = data / "train" / "episode_00001.policies.parquet"
    path.write_bytes(path.read_bytes()[:-100])
    _fails(
        capsys,
        ["train", "--stage", "1", "--data", str(data), "--out", str(tmp_path / "r"), *TINY1],
        str(path),
    )


def test_a_files_policy_count_must_match_the_manifest(data):
    m = json.loads((data / "manifest.json").read_text())
    m["config"]["planner"]["n_policies"] += 1
    (data / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(IrlsimError) as e:
        open_dataset(data).split_tensors("train")
    assert "policies per cycle, the dataset's manifest" in str(e.value)


# -------------------------------------------------------------------------------------------- outputs


def _read_only(monkeypatch) -> None:
    """A read-only file system under every output (root ignores chmod): the probe's OS call fails."""

    def probe(folder):
        raise OSError(errno.EROFS, "Read-only file system", str(folder))

    monkeypatch.setattr(outputs, "_probe", probe)


def _commands(data: Path, out: Path, tiny_runs: Path | None = None) -> dict[str, list[str]]:
    return {
        "collect": [
            "collect",
            "--config",
            "configs/collect/tiny.toml",
            "--out",
            str(out),
            "--set",
            "train_episodes=1",
        ],
        "train": ["train", "--stage", "1", "--data", str(data), "--out", str(out), *TINY1],
        "evaluate": ["evaluate", "--data", str(data), "--runs", str(tiny_runs or out), "--out", str(out)],
        "drive": [
            "drive",
            "--model",
            "expert",
            "--episodes",
            "1",
            "--max-cycles",
            "3",
            "--frames",
            "0",
            "--out",
            str(out),
        ],
        "data info": ["data", "info", str(data), "--json", str(out / "info.json")],
        "bench": ["bench", "--planner", "--cycles", "1", "--out", str(out)],
    }


@pytest.mark.parametrize("command", ["collect", "train", "evaluate", "drive", "data info", "bench"])
@pytest.mark.parametrize("fault", ["read-only", "a file", "under a file", "disk full"])
def test_outputs_are_checked_before_any_work(data, tmp_path, capsys, monkeypatch, command, fault):
    (tmp_path / "afile").write_text("x")
    runs = tmp_path / "runs"
    (runs / "stage1").mkdir(parents=True)  # evaluate looks for checkpoints after the output check
    out = {"a file": tmp_path / "afile", "under a file": tmp_path / "afile" / "sub"}.get(
        fault, tmp_path / "o"
    )
    if command == "data info" and fault == "a file":
        out = tmp_path / "afile" / "x"
    if fault == "read-only":
        _read_only(monkeypatch)
    if fault == "disk full":
        monkeypatch.setattr(outputs, "free_bytes", lambda folder: 1000)
    argv = _commands(data, out, runs)[command]
    needle = {
        "read-only": "Read-only file system",
        "a file": "is a file",
        "under a file": "is a file, not a folder",
        "disk full": "free disk space",
    }[fault]
    before = sorted(p.name for p in tmp_path.iterdir())
    _fails(capsys, argv, needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing was written
    assert not (data / ".cache").exists()  # nor read


def test_a_read_only_dataset_cache_is_one_line(data, tmp_path, capsys, monkeypatch):
    _read_only(monkeypatch)  # everything read-only, the runs folder included: the cache is checked too
    with pytest.raises(IrlsimError) as e:
        open_dataset(data).split_tensors("train")
    assert "its cache" in str(e.value) and "make the dataset folder writable" in str(e.value)


def test_an_os_error_during_the_work_is_one_line_naming_the_path(data, tmp_path, capsys, monkeypatch):
    def full(self, payload):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    monkeypatch.setattr(Path, "write_bytes", full)
    out = tmp_path / "info.json"
    err = _fails(capsys, ["data", "info", str(data), "--json", str(out)], "No space left on device", rc=1)
    assert str(out) in err and "free disk space" in err
    assert list(tmp_path.iterdir()) == [data]  # no temporary file left


# ----------------------------------------------------------------------------------------------- lock


def test_a_second_training_on_one_runs_folder_is_refused(data, tmp_path, capsys):
    runs = tmp_path / "runs"
    with exclusive_lock(runs / ".lock"):  # as a running 'irlsim train' holds it
        _fails(
            capsys,
            ["train", "--stage", "1", "--data", str(data), "--out", str(runs), *TINY1],
            "another 'irlsim train' is writing",
        )
    assert not (runs / "stage1" / "LIRL").exists()
    assert main(["train", "--stage", "1", "--data", str(data), "--out", str(runs), *TINY1]) == 0  # released


def test_summary_names_models_trained_earlier(data, tmp_path, capsys):
    runs = tmp_path / "runs"
    assert main(["train", "--stage", "1", "--data", str(data), "--out", str(runs), *TINY1]) == 0
    argv = [
        "train",
        "--stage",
        "1",
        "--data",
        str(data),
        "--out",
        str(runs),
        *TINY1[:2],
        "--set",
        'models=["PACNN"]',
        "--set",
        "epochs=1",
    ]
    assert main(argv) == 0
    summary = json.loads((runs / "stage1" / "summary.json").read_text())
    assert list(summary["models"]) == ["PACNN"] and summary["other_models"] == ["LIRL"]
    assert summary["dataset"].startswith("sha256:")
    capsys.readouterr()


@pytest.mark.parametrize(
    "command, rest",
    [
        ("train", ["--stage", "1", "--out", "O"]),
        ("evaluate", ["--runs", "R"]),
        ("dagger", ["--runs", "R", "--out", "O"]),
    ],
)
def test_repeated_data_flags_add_up(command, rest):
    """``--data A --data B C`` is the aggregate A, B, C: a repeated flag used to keep only its last
    folder, silently training on one dataset where several were named."""
    from pipelines.commands import build_parser

    args = build_parser(command).parse_args([command, "--data", "A", "--data", "B", "C", *rest])
    assert [str(p) for p in args.data] == ["A", "B", "C"]
