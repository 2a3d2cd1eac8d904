"""Fixtures of the closed-loop tests: tiny trained checkpoints whose shapes match the planner's policy sets.

The networks only need the planner's shapes (N policies, K control points): they are trained for one
epoch on the synthetic known-reward dataset (irlsim.bench.synthetic) with N = the tiny planner's count, so
building them takes a second instead of a SUMO collection run. What they predict is irrelevant here: the
tests check that closed-loop driving with them completes and reports every figure.
"""

from __future__ import annotations

import dataclasses

import pytest

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig

TINY_POLICIES = 200


def tiny_config(**scenario) -> CollectConfig:
    """The planner and scenario of a quick closed-loop run: 200 policies, 3 vehicles."""
    base = load_config(CollectConfig, None, {"planner.n_policies": TINY_POLICIES})
    return dataclasses.replace(base, scenario=dataclasses.replace(base.scenario, n_vehicles=3, **scenario))


@pytest.fixture(scope="session")
def tiny_runs(tmp_path_factory):
    """A runs folder with PACNN+S (1 epoch) and PTACNN+S (1 epoch, H = 4) for 200-policy cycles."""
    from irlsim.bench.synthetic import make_synthetic_dataset
    from irlsim.train import Stage1Config, Stage2Config, train_stage1, train_stage2

    runs = tmp_path_factory.mktemp("runs")
    data = make_synthetic_dataset(n_train=32, n_eval=16, n_policies=TINY_POLICIES, seed=0)
    train_stage1(data, dataclasses.replace(Stage1Config.smoke(), models=("LIRL", "PACNN+S"), epochs=1), runs)
    train_stage2(data, dataclasses.replace(Stage2Config.smoke(), models=("PTACNN+S",), epochs=1), runs)
    return runs
