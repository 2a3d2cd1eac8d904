"""Property of DAgger's round records: a round counts as finished exactly when it was asked the same
(every input equal, by content) and its outputs are there as recorded; any other input is refused in
one line, any missing or changed output makes it run again. On real files (configs, a manifest, a driver
and checkpoints as bytes), the pure logic of ``irlsim.workflows.dagger_record``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from irlsim.config import load_config
from irlsim.errors import IrlsimError
from irlsim.utils import write_json
from irlsim.workflows.dagger import DaggerConfig, DaggerRun
from irlsim.workflows.dagger_record import round_finished, round_inputs, round_outputs

CHANGES = {
    "seed": ("seed", 7),
    "episodes": ("episodes", 3),
    "validation_episodes": ("validation_episodes", 2),
    "model": ("model", "PTACNN+S"),
    "stage2_models": ("stage2_models", ["PTACNN+S"]),
    "scenario": ("scenario", "ramp"),
}


def _setup(root: Path) -> tuple[DaggerRun, Path, Path]:
    for name in ("collect.toml", "stage1.toml", "stage2.toml"):
        (root / name).write_text(f"# {name}\n")
    data = root / "data"
    data.mkdir()
    write_json(data / "manifest.json", {"config": {"seed": 0}, "splits": {"train": [0]}, "complete": True})
    driver = root / "driver.pt"
    driver.write_bytes(b"driver weights")
    here = root / "round_1"
    write_json(here / "data" / "manifest.json", {"config": {"seed": 0}, "complete": True})
    ckpt = here / "runs" / "stage1" / "PACNN+S" / "checkpoint.pt"
    ckpt.parent.mkdir(parents=True)
    ckpt.write_bytes(b"round 1 weights")
    cfg = load_config(
        DaggerConfig,
        None,
        {f"{k}_config": str(root / f"{k}.toml") for k in ("collect", "stage1", "stage2")},
    )
    run = DaggerRun(cfg, data, root / "runs", root)
    record = {"round": 1, "inputs": round_inputs(run, 1, driver), "outputs": round_outputs(run, 1, here)}
    write_json(here / "round.json", record)
    return run, here, driver


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(change=st.sampled_from(sorted(CHANGES) + [None]), tamper=st.sampled_from([None, "delete", "edit"]))
def test_a_round_is_finished_only_when_asked_the_same_and_its_outputs_match(tmp_path_factory, change, tamper):
    root = tmp_path_factory.mktemp("round")
    run, here, driver = _setup(root)
    if change is not None:
        key, value = CHANGES[change]
        cfg = load_config(DaggerConfig, None, {**_paths(root), key: value})
        other = DaggerRun(cfg, run.data, run.runs, run.out)
        with pytest.raises(IrlsimError) as e:
            round_finished(other, 1, here, driver)
        assert "\n" not in str(e.value) and f"with {key} = " in str(e.value)
        return
    ckpt = here / "runs" / "stage1" / "PACNN+S" / "checkpoint.pt"
    if tamper == "delete":
        ckpt.unlink()
    elif tamper == "edit":
        ckpt.write_bytes(b"other weights")
    assert round_finished(run, 1, here, driver) is (tamper is None)


def test_another_driver_or_config_file_is_another_round(tmp_path):
    run, here, driver = _setup(tmp_path)
    driver.write_bytes(b"retrained driver")
    with pytest.raises(IrlsimError, match="was run with driver = "):
        round_finished(run, 1, here, driver)
    driver.write_bytes(b"driver weights")
    before = Path(run.config.stage1_config).read_text()
    Path(run.config.stage1_config).write_text(f"# edited since\n{before}")  # comments: the same config
    assert round_finished(run, 1, here, driver) is True
    Path(run.config.stage1_config).write_text("epochs = 3\n")
    with pytest.raises(IrlsimError, match="another stage1_config than .*stage1.toml: their values differ"):
        round_finished(run, 1, here, driver)
    # a record of an older irlsim (no inputs) is not trusted: the round runs again
    write_json(here / "round.json", {"round": 1})
    assert round_finished(run, 1, here, driver) is False
    assert json.loads((here / "round.json").read_text()) == {"round": 1}


def _paths(root: Path) -> dict[str, str]:
    return {f"{k}_config": str(root / f"{k}.toml") for k in ("collect", "stage1", "stage2")}
