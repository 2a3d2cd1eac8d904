"""Caches are verified, never trusted: every file of a dataset's ``.cache`` carries its size and sha256 in
its ``meta.json`` (itself hashed), checked when a process first opens it. A flipped bit, a truncation, two
swapped files, a missing file or a ``meta.json`` not as written is one line on stderr naming the file and
the cache is rebuilt from the Parquet: the next training writes the checkpoint bytes of a clean cache
and the evaluation Table I's bytes. Real collections (the tiny preset), real caches, real training."""

from __future__ import annotations

import errno
import json
import shutil
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from irlsim import outputs
from irlsim.cli import main
from irlsim.data import cache
from irlsim.data.reader import open_dataset
from irlsim.data.tensors import ARRAY_NAMES
from irlsim.errors import IrlsimError

STAGE1 = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml"]
ONE_MODEL = ["--set", 'models=["PACNN"]', "--set", "epochs=1"]
CHECK_LINE = "irlsim: the cache of split "


@pytest.fixture(scope="module")
def trained(tiny_dataset, tmp_path_factory):
    """(a copy of the tiny dataset with its caches built by a real training, that training's checkpoint
    bytes, and Table I of the evaluation)."""
    root = tmp_path_factory.mktemp("integrity")
    data = root / "data"
    shutil.copytree(tiny_dataset, data, ignore=shutil.ignore_patterns(".cache", ".lock"))
    runs = root / "runs"
    assert main([*STAGE1, "--data", str(data), "--out", str(runs), *ONE_MODEL]) == 0
    assert main(["evaluate", "--data", str(data), "--runs", str(runs), "--no-references"]) == 0
    results = (runs / "eval" / "results.md").read_bytes()
    return data, (runs / "stage1" / "PACNN" / "checkpoint.pt").read_bytes(), results


def _flip(path: Path, at: float = 0.5, mask: int = 0x10) -> None:
    data = bytearray(path.read_bytes())
    data[int(at * (len(data) - 1))] ^= mask
    path.write_bytes(bytes(data))


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:-7])


def _swap(a: Path, b: Path) -> None:
    tmp = a.with_name("swap.tmp")
    a.rename(tmp)
    b.rename(a)
    tmp.rename(b)


def _old_version(folder: Path) -> None:
    """The meta.json the previous irlsim wrote: cache version 4, no sizes or hashes."""
    meta = json.loads((folder / "meta.json").read_text())
    for key in ("files", "meta_sha256"):
        meta.pop(key)
    (folder / "meta.json").write_text(json.dumps({**meta, "cache_version": 4}))


#: (what is done to the train split's cache folder, what the line must name, whether it is on stderr)
CORRUPTIONS = {
    "flip compressed rows": (lambda f: _flip(f / "features.lz4"), "features.lz4", True),
    "flip offsets": (lambda f: _flip(f / "actions.offsets.npy", 0.9), "actions.offsets.npy", True),
    "flip a per-cycle array": (lambda f: _flip(f / "demo_index.npy", 0.99, 0x01), "demo_index.npy", True),
    "truncate rows": (lambda f: _truncate(f / "labels.lz4"), "labels.lz4", True),
    "swap two files": (lambda f: _swap(f / "episode.npy", f / "cycle.npy"), "episode.npy", True),
    "swap the offsets of two arrays": (
        lambda f: _swap(f / "features.offsets.npy", f / "distances.offsets.npy"),
        "features.offsets.npy",
        True,
    ),
    "remove a file": (lambda f: (f / "distances.lz4").unlink(), "distances.lz4", True),
    "flip the record": (lambda f: _flip(f / "meta.json", 0.5, 0x01), "meta.json", True),
    "garble the record": (lambda f: (f / "meta.json").write_bytes(b"\xff{"), "meta.json", True),
    "previous irlsim's cache": (_old_version, "written by another irlsim", False),
    "swap two splits' records": (
        lambda f: _swap(f / "meta.json", f.parent / "validation" / "meta.json"),
        "out of date: built from other files",
        False,
    ),
}
#: lines expected when not one: each swapped split's cache is out of date, and said so
LINES = {"swap two splits' records": 2}


@pytest.mark.parametrize("name", list(CORRUPTIONS))
def test_a_corrupt_cache_is_named_rebuilt_and_trains_the_same_weights(trained, tmp_path, capsys, name):
    data, checkpoint, _ = trained
    corrupt, named, on_stderr = CORRUPTIONS[name]
    corrupt(data / ".cache" / "train")
    cache._VERIFIED.clear()  # the next command is a new process
    capsys.readouterr()
    runs = tmp_path / "runs"
    assert main([*STAGE1, "--data", str(data), "--out", str(runs), *ONE_MODEL]) == 0
    out, err = capsys.readouterr()
    lines = [x for x in (err if on_stderr else out).splitlines() if named in x]
    assert len(lines) == LINES.get(name, 1), (out, err)
    assert "Traceback" not in err
    if on_stderr:
        assert lines[0].startswith(CHECK_LINE + "train failed its check") and "rebuilding" in lines[0]
    assert (runs / "stage1" / "PACNN" / "checkpoint.pt").read_bytes() == checkpoint
    # rebuilt once: the next command uses it without a word
    capsys.readouterr()
    open_dataset(data).split_tensors("train")
    assert CHECK_LINE not in capsys.readouterr().err


def test_a_corrupt_test_cache_gives_the_same_table_one(trained, tmp_path, capsys):
    data, _, results = trained
    runs = tmp_path / "runs"
    shutil.copytree(data.parent / "runs", runs, ignore=shutil.ignore_patterns("eval"))
    _flip(data / ".cache" / "test" / "control_points.lz4", 0.3)
    cache._VERIFIED.clear()  # the next command is a new process
    capsys.readouterr()
    assert main(["evaluate", "--data", str(data), "--runs", str(runs), "--no-references"]) == 0
    err = capsys.readouterr().err
    assert sum(CHECK_LINE + "test failed its check" in x for x in err.splitlines()) == 1, err
    assert (runs / "eval" / "results.md").read_bytes() == results


def test_a_cache_changed_after_its_check_is_one_line_naming_the_file(trained):
    """Bytes that change under a running process (after the check) are one line, never a traceback."""
    data, _, _ = trained
    tensors = open_dataset(data).split_tensors("validation")
    path = Path(tensors.features.filename)
    raw = bytearray(path.read_bytes())
    raw[: len(raw) // 2] = bytes(len(raw) // 2)  # zeros are no LZ4 block of the row's size
    path.write_bytes(bytes(raw))
    reopened = cache.Lz4Rows.open(path.parent, "features", tensors.features.shape[1:], np.float32)
    with pytest.raises(IrlsimError) as exc:
        np.asarray(reopened)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and "cannot be decoded" in msg
    path.unlink()  # the next reader rebuilds it
    open_dataset(data).split_tensors("validation")


def _arrays(data: Path, split: str) -> dict[str, np.ndarray]:
    """The split's arrays as a new process reads them (one that has verified nothing yet: a process
    checks a cache once, and again when a file's inode, size or mtime changed, which a write within the
    file system's clock tick may not show)."""
    cache._VERIFIED.clear()
    tensors = open_dataset(data).split_tensors(split)
    return {n: np.array(getattr(tensors, n), copy=True) for n in ARRAY_NAMES}  # not views of the maps


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    which=st.integers(0, 1000),
    at=st.floats(0, 1),
    mask=st.integers(1, 255),
    cut=st.integers(0, 3),
)
def test_any_corruption_of_a_cache_file_is_detected_never_used(trained, capsys, which, at, mask, cut):
    """A random byte of a random cache file XORed (or the file cut short by 0-3 bytes after it): the
    arrays read are those of the clean cache and the corruption was named on stderr."""
    data, _, _ = trained
    clean = _arrays(data, "validation")
    folder = data / ".cache" / "validation"
    files = sorted([*cache.cache_files(folder), folder / cache.META_NAME])
    path = files[which % len(files)]
    raw = bytearray(path.read_bytes())
    before = bytes(raw)
    i = int(at * (len(raw) - 1))
    raw[i] ^= mask
    path.write_bytes(bytes(raw[: len(raw) - cut] if cut else raw))
    capsys.readouterr()
    got = _arrays(data, "validation")
    err = capsys.readouterr().err
    for n in ARRAY_NAMES:
        np.testing.assert_array_equal(got[n], clean[n])
    lines = [x for x in err.splitlines() if x.startswith(CHECK_LINE)]
    if path.name == cache.META_NAME and not cut and _same_json(before, bytes(raw)):
        assert lines == [], err  # e.g. a space made a tab, 'e' an 'E' in a number: the same record
    else:
        assert len(lines) == 1 and path.name in lines[0], err


def _same_json(a: bytes, b: bytes) -> bool:
    try:
        return bool(json.loads(a) == json.loads(b))
    except ValueError:
        return False


def _flip_weights(checkpoint: Path) -> str:
    """Flip a bit in the middle of the largest tensor of a checkpoint (its zip record's data); its name."""
    with zipfile.ZipFile(checkpoint) as archive:
        info = max(archive.infolist(), key=lambda i: i.file_size)
    raw = bytearray(checkpoint.read_bytes())
    name_len, extra_len = struct.unpack("<HH", raw[info.header_offset + 26 : info.header_offset + 30])
    raw[info.header_offset + 30 + name_len + extra_len + info.file_size // 2] ^= 0x04
    checkpoint.write_bytes(bytes(raw))
    return info.filename


def test_a_flipped_bit_in_a_checkpoint_is_one_line_naming_it(trained, tmp_path, capsys):
    """torch.load does not check the CRC-32 of a checkpoint's records (a flipped weight loaded silently):
    irlsim does, and a checkpoint cannot be rebuilt, so it is one line naming the file and the record."""
    data, _, _ = trained
    runs = tmp_path / "runs"
    shutil.copytree(data.parent / "runs", runs, ignore=shutil.ignore_patterns("eval"))
    checkpoint = runs / "stage1" / "PACNN" / "checkpoint.pt"
    record = _flip_weights(checkpoint)
    capsys.readouterr()
    assert main(["evaluate", "--data", str(data), "--runs", str(runs), "--no-references"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        f"irlsim: error: checkpoint {checkpoint} is corrupt (its record {record} fails its CRC-32 check): "
        "delete it and train again"
    )
    assert not (runs / "eval" / "results.md").exists()


def test_a_corrupt_metrics_log_changes_no_result(trained, tmp_path, capsys):
    """metrics.csv is a log, not an input: Table I's convergence plot reads the checkpoint's verified
    metrics (the same bytes as from a clean log), and a resume that cannot read the log's wall times says
    so in one line and trains on."""
    data, _, _ = trained
    runs = tmp_path / "runs"
    shutil.copytree(data.parent / "runs", runs)
    clean = (runs / "eval" / "convergence.png").read_bytes()
    log = runs / "stage1" / "PACNN" / "metrics.csv"
    text = log.read_text()
    digit = next(i for i, ch in enumerate(text) if ch.isdigit() and i > text.index("\n"))
    log.write_text(text[:digit] + str((int(text[digit]) + 5) % 10) + text[digit + 1 :])
    assert main(["evaluate", "--data", str(data), "--runs", str(runs), "--no-references"]) == 0
    assert (runs / "eval" / "convergence.png").read_bytes() == clean
    log.write_bytes(b"\xff\xfe not a table")
    capsys.readouterr()
    args = [
        *STAGE1,
        "--data",
        str(data),
        "--out",
        str(runs),
        "--set",
        'models=["PACNN"]',
        "--set",
        "epochs=2",
    ]
    assert main(args) == 0
    err = [x for x in capsys.readouterr().err.splitlines() if "metrics.csv" in x]
    assert len(err) == 1 and err[0].startswith(f"irlsim: {log} is not a metrics table"), err
    assert "the checkpoint's metrics are" in err[0]


def test_a_corrupt_cache_that_cannot_be_rebuilt_is_one_line_naming_it(trained, tmp_path, capsys, monkeypatch):
    """A read-only dataset (the probe's OS call fails below .cache: root ignores file modes) whose cache
    failed its check: the check's line, then one error line naming the cache and the fix; no Table I."""
    data = tmp_path / "data"
    shutil.copytree(trained[0], data)
    _flip(data / ".cache" / "validation" / "labels.lz4")
    cache._VERIFIED.clear()
    runs = tmp_path / "runs"
    shutil.copytree(trained[0].parent / "runs", runs, ignore=shutil.ignore_patterns("eval"))
    (runs / "eval").mkdir()

    def read_only_cache(folder):
        if ".cache" in str(folder):
            raise OSError(errno.EROFS, "Read-only file system", str(folder))

    monkeypatch.setattr(outputs, "_probe", read_only_cache)
    capsys.readouterr()
    assert main(["evaluate", "--data", str(data), "--runs", str(runs), "--split", "validation"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2, err
    assert err[0].startswith(CHECK_LINE + "validation failed its check (") and "labels.lz4" in err[0]
    assert err[1].startswith(f"irlsim: error: dataset {data}: its cache {data}/.cache/validation cannot be ")
    assert not (runs / "eval" / "results.md").exists()
