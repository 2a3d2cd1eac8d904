"""Every error line names its object: a disk that fills during a write is one line naming the file being
written (a ``write`` or ``flush`` error carries no file name, which the line printed as ``?``), and a
Gymnasium reward callable that returns the wrong type gets the one line of a wrong shape.

The full disk is real: the file a write goes to is a private character device with the numbers of
``/dev/full``, on which every ``write(2)`` fails with ENOSPC (made with ``mknod``; skipped where that is
not allowed)."""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path

import numpy as np
import pytest

from irlsim import N_FEATURES
from irlsim.cli import main
from irlsim.errors import IrlsimError

DEV_FULL = os.makedev(1, 7)


@pytest.fixture()
def full_disk_under(monkeypatch):
    """``full_disk_under(folder)``: from then on the temporary files irlsim writes below ``folder`` (every
    file goes through ``irlsim.utils.atomic_path``, i.e. ``tempfile.mkstemp``) are /dev/full devices."""
    real = tempfile.mkstemp

    def install(folder: Path) -> None:
        def mkstemp(suffix=None, prefix=None, dir=None, text=False):  # noqa: A002 - mkstemp's own names
            fd, name = real(suffix=suffix, prefix=prefix, dir=dir, text=text)
            if dir is not None and Path(dir).resolve().is_relative_to(folder.resolve()):
                os.close(fd)
                os.unlink(name)
                os.mknod(name, stat.S_IFCHR | 0o600, DEV_FULL)
                fd = os.open(os.devnull, os.O_RDONLY)
            return fd, name

        monkeypatch.setattr(tempfile, "mkstemp", mkstemp)

    probe = Path(tempfile.mkdtemp())
    try:
        os.mknod(probe / "full", stat.S_IFCHR | 0o600, DEV_FULL)
    except OSError as exc:
        pytest.skip(f"mknod of a /dev/full device is not allowed here ({exc.strerror})")
    finally:
        shutil.rmtree(probe)
    return install


def _the_line(capsys, argv: list[str], rc: int = 1) -> str:
    capsys.readouterr()
    assert main(argv) == rc
    err = [x for x in capsys.readouterr().err.splitlines() if x.startswith("irlsim: error:")]
    assert len(err) == 1, err
    return err[0]


def test_a_full_disk_names_the_file_being_written(tiny_dataset, tmp_path, capsys, full_disk_under):
    out = tmp_path / "info" / "info.json"
    out.parent.mkdir()
    full_disk_under(out.parent)
    line = _the_line(capsys, ["data", "info", str(tiny_dataset), "--json", str(out)])
    assert line == (
        f"irlsim: error: No space left on device: {out}: free disk space and re-run the command "
        "(finished files are kept, it resumes)"
    )
    assert list(out.parent.iterdir()) == []  # no temporary left


def test_a_full_disk_while_building_the_cache_names_the_cache_file(
    tiny_dataset, tmp_path, capsys, full_disk_under
):
    data = tmp_path / "data"
    shutil.copytree(tiny_dataset, data, ignore=shutil.ignore_patterns(".cache", ".lock"))
    (data / ".cache").mkdir()
    full_disk_under(data / ".cache")
    argv = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(data)]
    line = _the_line(capsys, [*argv, "--out", str(tmp_path / "runs"), "--set", 'models=["LIRL"]'])
    assert line.startswith(f"irlsim: error: No space left on device: {data / '.cache' / 'train'}/"), line
    assert ": ?:" not in line and ".tmp" not in line, line
    assert not [p for p in (data / ".cache").rglob("*") if p.is_file()]  # nothing half-written left


class _Theta:
    """Something that is not numbers."""


@pytest.mark.parametrize(
    "returned, what",
    [
        ("fifteen", "str of <U7"),
        (None, "NoneType"),
        ({"lane": 1.0}, "dict"),
        (["1.0"] * N_FEATURES, "list of <U3"),
        (np.ones(N_FEATURES, complex), "ndarray of complex128"),
        (np.ones(N_FEATURES, bool), "ndarray of bool"),
        (_Theta(), "_Theta"),
        (np.ones(N_FEATURES - 1), f"shape ({N_FEATURES - 1},)"),
    ],
)
def test_a_reward_callable_of_the_wrong_type_is_the_one_line_of_a_wrong_shape(returned, what):
    from irlsim.envs.planning import callable_theta

    with pytest.raises(IrlsimError) as exc:
        callable_theta(returned)
    assert (
        str(exc.value) == f"the reward callable must return theta [{N_FEATURES}] (real numbers), got {what}"
    )
    np.testing.assert_array_equal(callable_theta(list(range(N_FEATURES))), np.arange(N_FEATURES, dtype=float))


def test_the_environment_refuses_a_reward_of_the_wrong_type_in_one_line():
    gym = pytest.importorskip("gymnasium")
    from tests.reliability.test_edges import TINY_ENV

    env = gym.make("irlsim/Planning-v0", overrides=TINY_ENV, max_cycles=6, reward=lambda ps, obs: "fast")
    try:
        with pytest.raises(IrlsimError) as exc:
            env.reset(seed=3)
        assert str(exc.value) == (
            f"the reward callable must return theta [{N_FEATURES}] (real numbers), got str of <U4"
        )
    finally:
        env.close()


def test_a_full_disk_while_collecting_names_the_episode_file(tmp_path, capsys, full_disk_under):
    """pyarrow's write error carries no file name (its message only): the failed episodes' line names
    the Parquet file being written, and the other episodes are kept."""
    from tests.conftest import TINY_COLLECT

    out = tmp_path / "data"
    full_disk_under(out / "train")
    argv = ["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT]
    line = _the_line(capsys, [*argv, "--set", "max_cycles=10"])
    for e in (0, 1):
        assert f"No space left on device: '{out}/train/episode_0000{e}.policies.parquet'" in line, line
    assert line.endswith("re-run the same command to collect the failed ones")
    assert not list((out / "train").iterdir())  # nothing half-written
    assert (out / "test" / "episode_00000.cycles.parquet").is_file()
