"""DAgger with SUMO's driver as the labeller, in real SUMO at a tiny size: a learned reward drives, and each
cycle's demonstration is what SUMO's driver drives from that state (a look ahead), projected; a recording
cannot label and is refused in one line."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from irlsim.cli import main
from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from tests.pipelines.conftest import MODEL

SUMO_LABELLER = (
    '\n[demonstrator]\nkind = "sumo"\ncar_follow_model = "IDM"\nparams = {tau = 0.6, accel = 3.0}\n'
)


def test_a_sumo_driver_labels_from_the_learners_states(learner, tmp_path):
    """With a SUMO demonstrator, SUMO's driver labels: each cycle's demonstration is the projection of
    what it drives from that very state over the horizon (a look ahead the episode never sees), while the
    learned reward drives; the same seed gives the same bytes."""
    collect_cfg, runs = learner
    cfg_path = tmp_path / "sumo.toml"
    cfg_path.write_text(collect_cfg.read_text() + SUMO_LABELLER)
    args = ["collect", "--config", str(cfg_path), "--driver", MODEL, "--runs", str(runs)]
    args += ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]
    for name in ("a", "b"):
        assert main([*args, "--out", str(tmp_path / name)]) == 0
    files = sorted((tmp_path / "a" / "train").glob("*.parquet"))
    assert files and all(f.read_bytes() == (tmp_path / "b" / "train" / f.name).read_bytes() for f in files)
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["driver"]["model"] == MODEL and manifest["demonstrator"]["car_follow_model"] == "IDM"
    cyc = pd.concat([pd.read_parquet(p) for p in sorted((tmp_path / "a").glob("*/*.cycles.parquet"))])
    pol = pd.concat([pd.read_parquet(p) for p in sorted((tmp_path / "a").glob("*/*.policies.parquet"))])
    n = load_config(CollectConfig, cfg_path).planner.n_policies
    dist = pol["distance"].to_numpy().reshape(len(cyc), n)
    assert set(cyc["demo_source"]) == {"odometry"}  # projected odometry, not the expert's selection
    has = cyc["demo_index"].to_numpy() >= 0
    assert has.mean() > 0.5, has.mean()
    # a projection: the nearest policy to SUMO's odometry, at its distance (not 0 as an expert label);
    # beyond the distance limit only where SUMO changed lanes within one step (the nearest policy into
    # that lane then: irlsim.data.demos.lane_jump_projection)
    k, far = cyc["demo_index"].to_numpy()[has], cyc["demo_distance"].to_numpy()[has] > 1.5
    np.testing.assert_array_equal(k[~far], np.nanargmin(dist[has][~far], axis=1))
    assert (cyc["demo_distance"].to_numpy()[has] > 0).all()
    assert (np.take_along_axis(dist[has][far], k[far, None], 1)[:, 0] >= np.nanmin(dist[has][far], 1)).all()
    # the learned reward drove (its argmax executed), and SUMO's driver would often have driven otherwise
    assert (cyc["executed_index"] >= 0).all()
    assert (cyc["executed_index"].to_numpy()[has] != k).any()


def test_dagger_with_a_recording_is_refused(learner, tmp_path, capsys):
    collect_cfg, runs = learner
    cfg_path = tmp_path / "rec.toml"
    cfg_path.write_text(collect_cfg.read_text() + '\n[demonstrator]\nkind = "recording"\nfile = "x.xml"\n')
    capsys.readouterr()
    rc = main(
        ["collect", "--config", str(cfg_path), "--driver", MODEL, "--runs", str(runs)]
        + ["--out", str(tmp_path / "x")]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "a recording cannot label states" in err[0], err
    assert not (tmp_path / "x").exists()


def test_irlsim_dagger_on_a_sumo_drivers_data_labels_with_that_driver(tmp_path, capsys):
    """``irlsim dagger`` on a SUMO driver's dataset with its collect config (which names no lane-change
    model: the manifest records SUMO's default, and the config is still the data's): its rounds are
    labelled by that driver's look ahead."""
    cfg = tmp_path / "sumo.toml"
    cfg.write_text(
        "seed = 0\nworkers = 1\ntrain_episodes = 1\nvalidation_episodes = 1\ntest_episodes = 1\n"
        "max_cycles = 30\n"
        "[scenario]\nn_vehicles = 4\nlaps = 1\nmax_time = 120.0\n[planner]\nn_policies = 120\n"
        '[demonstrator]\nkind = "sumo"\ncar_follow_model = "IDM"\n'
    )
    data, runs, out = tmp_path / "data", tmp_path / "runs", tmp_path / "dagger"
    assert main(["collect", "--config", str(cfg), "--out", str(data)]) == 0
    train = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(data)]
    assert main([*train, "--out", str(runs), "--set", f"models=['{MODEL}']"]) == 0
    capsys.readouterr()
    args = ["dagger", "--config", "configs/dagger/tiny.toml", "--data", str(data), "--runs", str(runs)]
    assert main([*args, "--out", str(out), "--set", f"collect_config='{cfg}'"]) == 0
    said = capsys.readouterr().out
    assert "labelled by the sumo demonstrator's look ahead" in said and "drives and sumo IDM/LC2013" in said
    manifest = json.loads((out / "round_1" / "data" / "manifest.json").read_text())
    assert manifest["demonstrator"]["car_follow_model"] == "IDM" and manifest["driver"]["model"] == MODEL
    cyc = pd.concat(
        [pd.read_parquet(p) for p in sorted((out / "round_1" / "data").glob("*/*.cycles.parquet"))]
    )
    assert set(cyc["demo_source"]) == {"odometry"} and (cyc["demo_index"] >= 0).mean() > 0.5
