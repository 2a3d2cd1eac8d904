"""Closed-loop driving in headless SUMO: the expert, tiny trained models, the CLI and its errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from irlsim.drive import EPISODE_KEYS, PictureSpec, drive_episode
from irlsim.errors import IrlsimError
from irlsim.reward import load_reward
from tests.drive.conftest import TINY_POLICIES, tiny_config

TINY_TOML = f"""
max_cycles = 60
[scenario]
n_vehicles = 3
max_time = 200.0
[planner]
n_policies = {TINY_POLICIES}
"""


def test_short_expert_run_reports_every_figure(road, tmp_path):
    rec = drive_episode(
        "expert",
        road,
        tiny_config(),
        seed=100,
        laps=1,
        max_cycles=60,
        show_progress=False,
        pictures=PictureSpec(tmp_path, frames=3, stills=1),
    )
    assert set(EPISODE_KEYS) <= set(rec) and rec["drive/model"] == "expert"
    assert rec["drive/cycles"] == 60 and rec["drive/end_reason"] == "max_cycles"
    assert rec["drive/collisions"] == 0 and rec["drive/exits"] == 0
    missed = rec["drive/checkpoints_missed"]
    assert len(missed) == rec["drive/checkpoints_passed"] - rec["drive/checkpoints_in_lane"]
    assert rec["drive/time_s"] == pytest.approx(12.0) and rec["drive/distance_m"] > 50.0
    assert 0.0 < rec["drive/rms_jerk_lon"] < 10.0 and rec["drive/plan_ms_mean"] > 0.0
    assert len(rec["_inference_ms"]) == 60
    names = sorted(p.rsplit("/", 1)[1] for p in rec["drive/pictures"])
    assert len(names) == 4 and names.pop(1) == "episode.gif"
    # the segment is frozen shortly after the ego comes within 60 m of the first stop line (s = 206 m),
    # so its frames lie before the episode's last cycles; frames are taken every 2nd cycle
    cycle = int(names[0][len("cycle_") : -len(".png")])
    assert names[1:] == [f"radar_{cycle:04d}.png", f"temporal_{cycle:04d}.png"]
    assert cycle % 2 == 0 and cycle < 56
    # the scorecard: recorded on every simulation step (reset state included), the expert against itself
    t, s = rec["_progress"]
    assert len(t) == rec["sim/steps"] + 1 == 121
    assert s[-1] - s[0] == pytest.approx(rec["drive/distance_m"], abs=1e-3)
    assert rec["score/progress"] == 1.0 and rec["score/no_collision"] == 1.0
    assert 0.0 < rec["score/score"] <= 100.0 and 0.0 <= rec["score/comfort"] <= 1.0


def test_learned_models_drive_through_the_cli(tiny_runs, tmp_path, capsys):
    from pathlib import Path

    from irlsim.cli import main
    from irlsim.train.layout import find_checkpoint

    cfg = tmp_path / "tiny.toml"
    cfg.write_text(TINY_TOML)
    out = tmp_path / "drive"
    rc = main(
        [
            "drive",
            "--runs",
            str(tiny_runs),
            "--model",
            f"LIRL,PTACNN+S,{find_checkpoint(tiny_runs, 'LIRL')}",
            "--episodes",
            "1",
            "--laps",
            "1",
            "--seed",
            "7",
            "--config",
            str(cfg),
            "--max-cycles",
            "25",
            "--frames",
            "2",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    printed = capsys.readouterr().out
    assert "| PTACNN+S | 1 |" in printed and f"wrote {out}/drive.json" in printed
    doc = json.loads((out / "drive.json").read_text())
    path = str(find_checkpoint(tiny_runs, "LIRL"))
    # a checkpoint path is its own row and folder, never mixed up with the registry model of that name
    assert [s["drive/model"] for s in doc["summary"]] == ["LIRL", "PTACNN+S", path]
    assert [e["drive/model"] for e in doc["episodes"]] == ["LIRL", "PTACNN+S", path]
    (folder,) = out.glob("_".join(Path(path).parts[1:]) + "-*")  # the path, made unique by its hash
    assert {p.name for p in folder.iterdir()} >= {"episode.gif"}
    for ep in doc["episodes"]:
        assert set(EPISODE_KEYS) <= set(ep) and ep["drive/seed"] == 7 and ep["drive/cycles"] >= 1
        assert ep["drive/inference_ms_mean"] > 0.0 and "_inference_ms" not in ep
    assert "| LIRL | 1 |" in (out / "drive.md").read_text()
    for model in ("LIRL", "PTACNN+S"):
        files = {p.name for p in (out / model).iterdir()}
        # two frames (the pictures are most of this test's time): a still of each, of the three at most
        assert "episode.gif" in files and sum(f.startswith("radar_") for f in files) == 2


def test_ptacnn_keeps_an_online_history(tiny_runs):
    m = load_reward("PTACNN+S", tiny_runs, n_policies=TINY_POLICIES)
    rng = np.random.default_rng(0)
    f = rng.exponential(1.0, (TINY_POLICIES, 15)).astype(np.float32)
    cp = rng.normal(0.0, 1.0, (TINY_POLICIES, 10, 3)).astype(np.float32)
    ac = rng.normal(0.0, 1.0, (TINY_POLICIES, 10, 2)).astype(np.float32)
    theta, info = m.predictor.predict(f, cp, ac)
    assert theta.shape == (15,) and info["attention"].shape == (TINY_POLICIES,)
    assert info["temporal_weights"].shape == (4,) and np.isclose(info["temporal_weights"].sum(), 1.0)


def test_bad_models_fail_with_one_line(tiny_runs, tmp_path):
    with pytest.raises(IrlsimError, match="unknown model 'PACNN-X': choose from expert, expert-theta, LIRL"):
        load_reward("PACNN-X", tiny_runs)
    with pytest.raises(IrlsimError, match=r"run 'irlsim train --stage 2"):
        load_reward("PTACNN", tmp_path)
    with pytest.raises(IrlsimError, match="trained on 200 policies per cycle, but the planner samples 1000"):
        load_reward("PACNN+S", tiny_runs, n_policies=1000)
    with pytest.raises(IrlsimError, match="not found"):
        load_reward(str(tmp_path / "none" / "checkpoint.pt"))
    from irlsim.cli import main

    with pytest.raises(SystemExit) as e:  # refused when parsed (irlsim.config.int_in)
        main(["drive", "--model", "expert", "--episodes", "0"])
    assert e.value.code == 2


def test_expert_theta_drives_argmax_of_the_experts_theta(road):
    """'expert-theta': the expert's theta alone, argmax V every cycle, no model-based selection."""
    from irlsim.planner.expert import THETA_EXPERT

    model = load_reward("expert-theta")
    assert not model.is_expert and model.checkpoint is None
    rec = drive_episode(model, road, tiny_config(), seed=100, laps=1, max_cycles=40, show_progress=False)
    assert rec["drive/model"] == "expert-theta" and rec["drive/cycles"] == 40
    assert rec["drive/collisions"] == 0 and rec["drive/distance_m"] > 50.0
    theta, _ = model.predictor.predict(None, None, None)
    assert np.array_equal(theta, THETA_EXPERT)


def test_expert_lap_meets_the_expert_figures(road):
    """The expert driven by 'irlsim drive' meets the expert's acceptance figures on a lap:
    no collision or exit, a full stop at every stop line, every checkpoint in its lane, >= 50 km/h."""
    # the demo's configuration (configs/collect/default.toml: 500 policies, 15 vehicles) and seed
    from pathlib import Path

    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig

    cfg = load_config(
        CollectConfig, Path(__file__).resolve().parents[2] / "configs" / "collect" / "default.toml"
    )
    rec = drive_episode("expert", road, cfg, seed=100, laps=1, show_progress=False)
    assert rec["drive/end_reason"] == "laps" and rec["drive/laps"] == 1
    assert rec["drive/collisions"] == 0 and rec["drive/exits"] == 0
    assert rec["drive/stop_lines_passed"] == 2 and rec["drive/stop_compliance"] == 1.0
    assert rec["drive/checkpoints_passed"] == 4 and rec["drive/checkpoint_compliance"] == 1.0
    assert rec["drive/mean_speed_kmh"] >= 50.0


def test_the_choice_options_drive_through_the_cli_and_are_recorded(tiny_runs, tiny_dataset, tmp_path):
    from irlsim.cli import main
    from irlsim.reward.choice import lane_change_bias

    reward = load_reward("PACNN+S", tiny_runs, n_policies=TINY_POLICIES)
    bias = lane_change_bias(reward, [tiny_dataset])
    assert bias >= 1.0 and np.isfinite(bias) and lane_change_bias(reward, [tiny_dataset]) == bias
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(TINY_TOML)
    common = ["drive", "--runs", str(tiny_runs), "--model", "PACNN+S", "--seed", "7", "--config", str(cfg)]
    common += ["--max-cycles", "10", "--frames", "0"]
    assert (
        main([*common, "--choice", "expected", "--lane-change-bias", f"{bias}", "--out", str(tmp_path / "e")])
        == 0
    )
    assert main([*common, "--out", str(tmp_path / "a")]) == 0
    expected = json.loads((tmp_path / "e" / "drive.json").read_text())
    argmax = json.loads((tmp_path / "a" / "drive.json").read_text())
    assert expected["config"]["choice"] == "expected" and expected["config"]["lane_change_bias"] == bias
    assert "choice" not in argmax["config"]  # the default's record is as before
    assert "choosing the expected policy" in (tmp_path / "e" / "drive.md").read_text()
    rules = ["--commit", "--full-stop", "--keep-distance"]
    assert main([*common, *rules, "--out", str(tmp_path / "c")]) == 0  # every rule
    committed = json.loads((tmp_path / "c" / "drive.json").read_text())
    assert committed["config"]["commit"] is True and "commit" not in argmax["config"]
    assert committed["config"]["full_stop"] is True and "full_stop" not in argmax["config"]
    assert committed["config"]["keep_distance"] == 0.8 and "keep_distance" not in argmax["config"]
    words = "maneuvers committed, a full stop at every stop line, a safe distance to the vehicle ahead (0.8 s"
    assert words in (tmp_path / "c" / "drive.md").read_text()
    own = [*common, "--keep-distance", "0.5", "--in-lane", "--out", str(tmp_path / "k")]
    assert main(own) == 0  # a headway of its own, in the reward's lane
    kept = json.loads((tmp_path / "k" / "drive.json").read_text())["config"]
    assert kept["keep_distance"] == 0.5 and kept["in_lane"] is True and "in_lane" not in committed["config"]
    assert "(0.5 s headway), in the lane the reward chooses" in (tmp_path / "k" / "drive.md").read_text()
    for bad in (["--choice", "expected", "--lane-change-bias", "0.5"], ["--keep-distance", "-1"]):
        with pytest.raises(SystemExit) as e:  # a bias below 1, a negative headway: refused when parsed
            main([*common, *bad])
        assert e.value.code == 2
    # the library refuses the same in one line, before any work
    from dataclasses import replace

    from irlsim.workflows.drive import DriveRun, drive_models

    run = DriveRun(("PACNN+S",), tiny_runs, config_file=cfg, out=tmp_path / "x", choice="mode")
    with pytest.raises(IrlsimError, match="--choice 'mode' is not one of argmax, expected"):
        drive_models(run)
    with pytest.raises(IrlsimError, match="--lane-change-bias must be a finite number >= 1, got 0.5"):
        drive_models(replace(run, choice="expected", lane_change_bias=0.5))
    with pytest.raises(IrlsimError, match="--keep-distance must be a finite headway >= 0 s, got -1.0"):
        drive_models(replace(run, choice="argmax", keep_distance=-1.0))
    with pytest.raises(IrlsimError, match="--in-lane keeps the following distance in the reward's lane: add"):
        drive_models(replace(run, choice="argmax", in_lane=True))
    assert not (tmp_path / "x").exists()


def test_drive_sets_config_fields_as_the_collection_did(tmp_path, capsys):
    """``--set KEY=VALUE`` overrides a field of --config (a collection made with --set drives with the
    same); it is recorded, and a key the config lacks is one line before any work."""
    from irlsim.cli import main

    common = ["drive", "--model", "expert", "--max-cycles", "5", "--frames", "0"]
    assert main([*common, "--set", "planner.n_policies=120", "--out", str(tmp_path / "s")]) == 0
    config = json.loads((tmp_path / "s" / "drive.json").read_text())["config"]
    assert config["n_policies"] == 120 and config["set"] == ["planner.n_policies=120"]
    assert main([*common, "--set", "planner.n_polices=120", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("irlsim: error: config: --set planner.n_polices: unknown key 'planner.n_polices'")
    assert not (tmp_path / "bad").exists()
