"""Config and option ranges at parse time, sizes against memory, config files that are not UTF-8 or not
TOML: one line (exit 2) before any work."""

import pytest

from irlsim import config
from irlsim.cli import main
from irlsim.data.collection import CollectConfig
from irlsim.errors import IrlsimError


def _fails(capsys, argv, *needles):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for n in needles:
        assert n in err, err


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--set", "seed=-1"], "seed must be in 0..2147483647, got -1"),
        (["--set", "models=[]"], "models is empty"),
        (["--set", 'models=["LIRL","LIRL"]'], "names a model twice"),
        (["--set", "lr=nan"], "'lr' must be a finite number, got nan"),
        (["--set", "lr=inf"], "'lr' must be a finite number, got inf"),
    ],
)
def test_train_config_ranges(tmp_path, capsys, argv, needle):
    _fails(
        capsys,
        ["train", "--stage", "1", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "r"), *argv],
        needle,
    )
    assert not (tmp_path / "r").exists()


def test_collect_seed_3000_is_refused_with_its_range(tmp_path, capsys):
    _fails(
        capsys,
        ["collect", "--config", "configs/collect/tiny.toml", "--out", str(tmp_path / "d"), "--seed", "3000"],
        "seed must be in 0..2147 (episode seeds are seed * 1,000,000",
    )
    assert not (tmp_path / "d").exists()
    cfg = config.load_config(CollectConfig, "configs/collect/tiny.toml", {"seed": 2147})
    assert (
        max(s for split in ("train", "validation", "test") for _, s in cfg.episodes(split)) <= config.MAX_SEED
    )


def test_sizes_are_checked_against_memory_before_allocation(tmp_path, capsys, monkeypatch):
    _fails(
        capsys,
        [
            "collect",
            "--config",
            "configs/collect/tiny.toml",
            "--out",
            str(tmp_path / "d"),
            "--set",
            "planner.n_policies=10000000",
        ],
        "planner.n_policies=10000000 needs about",
        "GiB",
    )
    monkeypatch.setattr(config, "available_memory", lambda: 100 << 20)  # a 100 MiB machine
    with pytest.raises(IrlsimError) as e:
        config.load_config(CollectConfig, None, {"planner.n_policies": 2500, "workers": 2})
    assert "with 2 workers needs about" in str(e.value)
    config.load_config(CollectConfig, None, {"planner.n_policies": 1000, "workers": 1})  # 32 MiB fits


@pytest.mark.parametrize(
    "content, needle",
    [
        (b"epochs = 3\n\xff\xfe\n", "is not UTF-8 text (byte 11)"),
        (b"epochs = = 3\n", "is not valid TOML"),
        (b"\x00\x01\x02PK", "is not valid TOML"),
    ],
)
def test_a_config_file_that_is_not_utf8_toml_is_one_line(tmp_path, capsys, content, needle):
    path = tmp_path / "c.toml"
    path.write_bytes(content)
    _fails(
        capsys,
        [
            "train",
            "--stage",
            "1",
            "--config",
            str(path),
            "--data",
            str(tmp_path),
            "--out",
            str(tmp_path / "r"),
        ],
        needle,
    )


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["drive", "--episodes", "0"], "argument --episodes: must be an integer >= 1, got 0"),
        (["drive", "--seed", "2147483648"], "must be an integer 0..2147483647"),
        (["evaluate", "--data", "x", "--runs", "y", "--threads", "0"], "argument --threads"),
        (["collect", "--out", "x", "--workers", "1e9"], "must be an integer, got '1e9'"),
        (["sim", "--max-time", "nan"], "must be a finite number >= 0, got nan"),
        (
            ["collect", "--out", "x", "--episode-timeout", "0"],
            "argument --episode-timeout: must be a finite number > 0, got 0",
        ),
        (["drive", "--episode-timeout", "inf"], "argument --episode-timeout: must be a finite number > 0"),
        (["drive", "--episode-timeout", "soon"], "argument --episode-timeout: must be a number, got 'soon'"),
    ],
)
def test_numeric_options_are_range_checked_at_parse_time(capsys, argv, needle):
    with pytest.raises(SystemExit) as e:  # argparse's own exit, one line (irlsim.cli._Parser)
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
