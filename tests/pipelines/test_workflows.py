"""The chains (``irlsim demo``, DAgger rounds) call the library's workflows, not the command line; the
command lines they print (and DAgger records in round.json) must still be the same steps: each parses,
through the command's own argument handling, to the very request the chain runs."""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path

import pytest

from irlsim.config import load_config
from irlsim.workflows.dagger import DaggerConfig, DaggerRun, round_plan
from pipelines.commands import build_parser
from pipelines.demo import steps


def _request(command: tuple[str, ...]):
    """The library request the ``irlsim`` command line ``command`` makes (nothing runs)."""
    args = build_parser(command[0]).parse_args(list(command))
    return importlib.import_module(f"pipelines.{command[0]}").request(args)


@pytest.mark.parametrize("preset", ["tiny", "default"])
def test_demo_steps_are_the_commands_they_print(preset, tmp_path):
    args = argparse.Namespace(
        data=tmp_path / "d", runs=tmp_path / "r", seed=3, preset=preset, skip_drive=False
    )
    chain = steps(args)
    assert [s.command[0] for s in chain] == ["net", "collect", "train", "train", "evaluate", "drive", "drive"]
    for step in chain[1:]:
        assert step.request == _request(step.command), step.command
    drive, safety = (_request(s.command) for s in chain[-2:])
    assert not drive.safety and safety.safety and safety.frames == 0
    assert drive.seed == 103 and drive.episodes == (1 if preset == "tiny" else 3)


def test_dagger_round_steps_are_the_commands_it_records():
    cfg = load_config(DaggerConfig, "configs/dagger/paper.toml", {"seed": 1})
    run = DaggerRun(cfg, Path("D"), Path("R"), Path("O"))
    for r in (1, 2):
        plan = round_plan(run, r)
        assert len(plan.commands) == 1 + len(plan.train) == 3
        assert _request(plan.commands[0]) == plan.collect
        assert plan.collect.config.dagger_round == r and plan.collect.driver == cfg.model
        for cmd, train in zip(plan.commands[1:], plan.train, strict=True):
            assert _request(cmd) == train
        assert plan.train[0].config.epochs == cfg.epochs[r - 1] and plan.train[0].config.seed == 1


def test_a_chain_steps_exit_status_is_the_commands(capsys):
    from irlsim.errors import IrlsimError
    from irlsim.workflows.steps import exit_status

    def fails(error: BaseException):
        def step() -> bool:
            raise error

        return step

    assert exit_status(lambda: True) == 0 and exit_status(lambda: False) == 1
    assert exit_status(fails(IrlsimError("bad thing: fix it"))) == 2
    assert capsys.readouterr().err == "irlsim: error: bad thing: fix it\n"
    assert exit_status(fails(PermissionError(13, "Permission denied", "/x"))) == 1
    assert "/x" in capsys.readouterr().err
    assert exit_status(fails(KeyboardInterrupt())) == 130
    with pytest.raises(ValueError):  # a bug is no user error: it propagates
        exit_status(fails(ValueError("bug")))
