"""Every shipped collect, training and DAgger config loads and validates (a SUMO demonstrator's vehicle type
accepted by SUMO itself), and the files a DAgger config names exist.

A config that goes stale (a renamed field, a value out of range, a stage config that moved) fails here, in
parsing alone, instead of minutes into a recipe.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import SUMO, resolve
from irlsim.road.scenario import Scenarios
from irlsim.train.config import Stage1Config, Stage2Config
from irlsim.workflows.dagger import DaggerConfig

ROOT = Path(__file__).resolve().parents[2]
COLLECT = sorted((ROOT / "configs" / "collect").rglob("*.toml"))
TRAIN = sorted((ROOT / "configs" / "train").glob("*.toml"))
DAGGER = sorted((ROOT / "configs" / "dagger").glob("*.toml"))


def test_the_shipped_configs_are_found() -> None:
    assert len(COLLECT) >= 4 and len(TRAIN) >= 2 and len(DAGGER) >= 2


@pytest.mark.parametrize("path", COLLECT, ids=lambda p: str(p.relative_to(ROOT / "configs" / "collect")))
def test_collect_config_loads_and_sumo_accepts_its_demonstrator(path: Path) -> None:
    cfg = load_config(CollectConfig, path)
    demo, record = resolve(cfg.demonstrator, tuple(Scenarios()(name) for name in cfg.scenario_names))
    assert record["kind"] == cfg.demonstrator.kind
    if demo.kind == SUMO:  # resolved as collection records it: both models named, SUMO's or the config's
        assert demo.car_follow_model and demo.lane_change_model


@pytest.mark.parametrize("path", TRAIN, ids=lambda p: p.name)
def test_training_config_loads(path: Path) -> None:
    cls = Stage2Config if "stage2" in path.name else Stage1Config
    cfg = load_config(cls, path)
    cfg.validate()


@pytest.mark.parametrize("path", DAGGER, ids=lambda p: p.name)
def test_dagger_config_loads_and_names_existing_configs(path: Path) -> None:
    cfg = load_config(DaggerConfig, path)
    cfg.validate()
    for name in (cfg.collect_config, cfg.stage1_config, cfg.stage2_config):
        assert (ROOT / name).is_file(), f"{path.name} names {name}, which is not a file"
    assert "stage2" in Path(cfg.stage2_config).name and "stage2" not in Path(cfg.stage1_config).name


def test_the_driving_stage2_config_differs_from_the_default_only_in_the_pull() -> None:
    default = load_config(Stage2Config, ROOT / "configs" / "train" / "stage2.toml")
    plain = load_config(Stage2Config, ROOT / "configs" / "train" / "stage2_plain.toml")
    assert default.weight_reg > 0 and plain.weight_reg == 0
    assert plain == type(default)(**{**vars(default), "weight_reg": 0.0})
