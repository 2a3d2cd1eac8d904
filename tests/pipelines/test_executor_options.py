"""The executor's options checked before any work: the episode time limit's default per scenario and
executor, --executor ray without the extra, --address without Ray (tests/pipelines/test_executor.py has
the workers, the timeouts and the Ray cluster)."""

from __future__ import annotations

import sys

from irlsim.cli import main
from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.workflows.collect import default_episode_timeout, episode_timeout
from tests.pipelines.test_executor import _collect_args


def test_default_episode_timeout_follows_the_scenario():
    """600 s + 2 x the simulated time limit (max_time, or max_cycles x cycle when shorter); none for the
    local executor's one worker in this process unless asked, and then the asked one."""
    cfg = load_config(CollectConfig, "configs/collect/default.toml")  # max_cycles 800 of 0.2 s, max_time 600
    assert default_episode_timeout(cfg.scenario, cfg.max_cycles) == 600 + 2 * 160 == 920
    assert default_episode_timeout(cfg.scenario, 0) == 600 + 2 * 600  # drive without --max-cycles
    assert default_episode_timeout(cfg.scenario, 10_000) == 1800  # max_time is the shorter
    assert episode_timeout(None, "local", 2, cfg.scenario, 800) == 920
    assert episode_timeout(None, "ray", 1, cfg.scenario, 800) == 920
    assert episode_timeout(None, "local", 1, cfg.scenario, 800) is None
    assert episode_timeout(30.0, "local", 1, cfg.scenario, 800) == 30.0


def test_ray_without_the_extra_is_one_line(tmp_path, capsys, monkeypatch):
    """Without Ray installed ('ray' not importable), --executor ray is one line naming the extra."""
    monkeypatch.setitem(sys.modules, "ray", None)  # what an environment without the extra sees
    assert main(_collect_args(tmp_path / "x", "--executor", "ray")) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install -e '.[ray]'" in err[0], err
    assert not (tmp_path / "x").exists()


def test_address_without_ray_is_refused(tmp_path, capsys):
    assert main(_collect_args(tmp_path / "x", "--address", "auto")) == 2
    assert "--executor ray" in capsys.readouterr().err
