"""The style study end to end at toy sizes (studies/styles.py --smoke): every step runs as the real
irlsim command in SUMO (the recording made by the sumo binary on its own), and the table has one row per
learned reward and road, one finite cell per demonstrator."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from irlsim.rollout.style import style_spread


def _study(name: str):
    """The script studies/<name>.py as a module."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).parents[2] / "studies" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


study = _study("styles")


@pytest.mark.slow
def test_smoke_writes_the_style_table(tmp_path):
    demos = ["expert", "cautious", "assertive", "recording"]
    assert study.main(["--smoke", "--out", str(tmp_path), "--demonstrators", *demos]) == 0
    tables = json.loads((tmp_path / "styles.json").read_text())
    where = "oval, where the recording was made"
    assert list(tables) == ["oval", "motorway", where]
    # the recording made by SUMO on its own, imported, learned and driven on its held-out cars' routes
    assert sorted(r["model"] for r in tables[where]["rows"]) == ["LIRL", "PACNN+S"]
    assert list(tables[where]["demonstrators"]) == ["recording", "expert"]
    for r in tables[where]["rows"]:
        assert r["demonstrator"] == "recording" and list(r["cells"]) == ["recording", "expert"]
        assert all(math.isfinite(v) and v >= 0 for v in r["cells"].values())
    for table in (tables["oval"], tables["motorway"]):
        rows = table["rows"]
        # each demonstrator's own driving on the evaluation seeds, with its safety bounds
        assert list(table["demonstrators"]) == ["expert", "cautious", "assertive"]
        assert all(isinstance(b["safe"], bool) for b in table["demonstrators"].values())
        # 2 models x 3 demonstrators x 1 training seed
        assert sorted((r["model"], r["demonstrator"]) for r in rows) == sorted(
            (m, d) for m in ("PACNN+S", "LIRL") for d in ("expert", "cautious", "assertive")
        )
        for r in rows:
            assert list(r["cells"]) == ["expert", "cautious", "assertive"]
            assert all(math.isfinite(v) and v >= 0 for v in r["cells"].values())
            assert r["nearest"] == min(r["cells"], key=r["cells"].get)
            assert isinstance(r["safety"]["safe"], bool)
    assert "| learned reward | expert | cautious | assertive |" in (tmp_path / "styles.md").read_text()


def test_unknown_demonstrator_is_one_line(tmp_path):
    with pytest.raises(SystemExit) as e:
        study.main(["--demonstrators", "expert", "timid", "--out", str(tmp_path)])
    assert "unknown demonstrator timid" in str(e.value) and "\n" not in str(e.value)


def test_development_seeds_leave_the_recording_out_in_one_line(tmp_path):
    with pytest.raises(SystemExit) as e:
        study.main(["--eval-base", "2000", "--demonstrators", "expert", "recording", "--out", str(tmp_path)])
    assert "leave recording out of --rows" in str(e.value) and "\n" not in str(e.value)
    assert not any(tmp_path.iterdir())  # refused before any work


def test_safety_commit_and_full_stop_go_to_learned_drives_only(tmp_path, monkeypatch):
    ran = []
    monkeypatch.setattr(study, "run", ran.append)  # the command line only (pure logic)
    a = type("A", (), {"episodes": 2, "eval_base": 1000, "laps": 1, "max_cycles": 10, "workers": 1})()
    for flag in (False, True):
        a.safety = a.commit = a.full_stop = flag
        study.drive("c.toml", "oval", ["PACNN+S"], tmp_path / "runs", tmp_path / f"learned{flag}", a)
        study.drive("c.toml", "oval", ["expert"], None, tmp_path / f"expert{flag}", a)
        study.drive("r.toml", None, ["PACNN+S"], tmp_path / "runs", tmp_path / f"recording{flag}", a)
    assert ["--safety" in cmd for cmd in ran] == [False, False, False, True, False, True]
    assert ["--commit" in cmd for cmd in ran] == [False, False, False, True, False, False]  # not recordings
    assert ["--full-stop" in cmd for cmd in ran] == [False, False, False, True, False, False]


norms = _study("style_norms")


def _style(values: list[float], share: list[float]) -> dict:
    from irlsim.rollout.style import STYLE_FIGURES

    return {**dict(zip(STYLE_FIGURES, values, strict=True)), "style/lane_share": share}


def test_per_episode_normaliser_against_a_closed_form_and_units():
    eps = [_style([10.0 + i, 2.0, 1.0, 3.0 + 2 * i, 1.0, 0.5, 0.9], [0.5, 0.5]) for i in range(4)]
    spread = style_spread(eps, 2)
    assert spread[0] == pytest.approx(np.std([10, 11, 12, 13])) and spread[1] == 0.0  # no spread: left out
    ref = _style([11.0, 2.0, 1.0, 5.0, 1.0, 0.5, 0.9], [0.5, 0.5])
    row = {**ref, "style/mean_speed": 11.0 + 2 * spread[0]}  # two spreads faster, all else the same
    # two figures have a spread (speed, lane changes; the lane shares none): the RMS of (2, 0)
    d = norms.episode_distances(row, [ref, row], spread)
    assert d == pytest.approx([np.sqrt(4 / 2), 0.0])
    # km/h for m/s in every record, the episodes too: the same distances
    kmh = [{**e, "style/mean_speed": 3.6 * e["style/mean_speed"]} for e in (row, ref, *eps)]
    d_kmh = norms.episode_distances(kmh[0], [kmh[1], kmh[0]], style_spread(kmh[2:], 2))
    assert d_kmh == pytest.approx(d)
    # the per-figure gaps are the distance's terms: +2 on speed, 0 on lane changes, the rest left out
    gaps = norms.figure_gaps(row, ref, spread)
    assert gaps[0] == pytest.approx(2.0) and gaps[3] == 0.0 and np.isnan(gaps[1])
    assert np.sqrt(np.nanmean(gaps**2)) == pytest.approx(d[0])


def test_open_loop_chain_against_closed_form():
    """Three policies whose only cost is proximity 0 / 1 / 2 under theta_proximity = ln 2: the
    maximum-entropy distribution is (4, 2, 1) / 7, so the expected proximity is 4/7 and the expected
    progress (4 * 10 + 2 * 20 + 30) / 7; the choice is the first policy."""
    openloop = _study("style_openloop")
    feats = np.zeros((3, len(openloop.FEATURE_NAMES)), np.float32)
    feats[:, openloop.IDX["proximity"]] = [0, 1, 2]
    theta = np.zeros(len(openloop.FEATURE_NAMES))
    theta[openloop.IDX["proximity"]] = math.log(2)
    points = np.zeros((3, 4, 3), np.float32)
    points[1:, -1, 0] = 3.2  # policies 1 and 2 end a lane to the left
    progress = np.array([10.0, 20.0, 30.0])
    points[:, :, 2] = np.outer(progress, np.arange(1, 5) / 4)  # progress profiles ending at progress
    x = openloop.cycle_figures(feats, points, progress, theta, demo=2, ruled=-1)
    side, prox = 1, 2
    assert x.shape == (len(openloop.WHICH), 2 + len(openloop.COSTS))
    assert x[0, prox] == 2 and x[0, 0] == 30  # the demonstration
    assert np.isnan(x[1]).all()  # dropped by the rules
    assert x[2, prox] == pytest.approx(4 / 7) and x[2, 0] == pytest.approx(110 / 7)
    assert x[2, side] == pytest.approx(3 / 7)
    assert x[3, prox] == 0 and x[3, 0] == 10  # the choice: argmax of -theta^T f
    # the expected choice: keeping the lane has mass 4/7 against 3/7; a bias above 4/3 changes lanes
    assert x[4, side] == 0 and x[4, prox] == 0
    y = openloop.cycle_figures(feats, points, progress, theta, demo=2, ruled=-1, bias=1.5)
    assert y[4, side] == 1 and y[4, prox] == 1  # within it p is 2:1, the expected end 70/3: nearest 20


def test_open_loop_refuses_a_missing_folder_in_one_line(tmp_path):
    openloop = _study("style_openloop")
    with pytest.raises(SystemExit) as e:
        openloop.main(["--data", str(tmp_path / "no-data"), "--runs", str(tmp_path)])
    assert "no-data is not a folder" in str(e.value) and "\n" not in str(e.value)
    (tmp_path / "data" / "test").mkdir(parents=True)
    with pytest.raises(SystemExit) as e:  # a run folder without the model: irlsim's one line, not a traceback
        openloop.main(["--data", str(tmp_path / "data"), "--runs", str(tmp_path)])
    assert str(e.value).startswith("style_openloop: ") and "\n" not in str(e.value)


def _refusal(main, argv: list[str]) -> str:
    """The one line a study's ``main`` exits with on ``argv``."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert "\n" not in str(e.value)
    return str(e.value)


def test_style_choice_refuses_a_missing_study_in_one_line(tmp_path):
    choice = _study("style_choice")
    assert "is missing: run studies/styles.py" in _refusal(choice.main, ["--out", str(tmp_path)])
    out = ["--out", str(tmp_path)]
    assert "unknown demonstrator timid" in _refusal(choice.main, [*out, "--rows", "timid"])
    assert "data/expert/oval is missing" in _refusal(choice.main, [*out, "--rows", "expert"])  # a row too
    dagger = ["--out", str(tmp_path), "--dagger-rounds", "1"]
    assert "is missing: run studies/style_dagger.py" in _refusal(choice.main, dagger)
    assert "leave --rule at default" in _refusal(choice.main, [*dagger, "--rule", "kept"])
    assert not list(tmp_path.iterdir())  # nothing written


def test_style_oracle_refuses_what_it_cannot_follow_in_one_line(tmp_path):
    oracle = _study("style_oracle")
    out = ["--out", str(tmp_path)]
    assert "--driver must be a SUMO driver" in _refusal(oracle.main, [*out, "--driver", "expert"])
    assert "--driver must be a SUMO driver" in _refusal(oracle.main, [*out, "--driver", "timid"])
    assert "no references in" in _refusal(oracle.main, out)
    twice = ["--demonstrators", "expert", "cautious", "cautious", "--driver", "cautious"]
    assert "names a driver twice" in _refusal(oracle.main, [*out, *twice])
    planner = ["--driver", "assertive", "--planner"]
    assert "FIELD=NUMBER" in _refusal(oracle.main, [*out, *planner, "lon_split=early"])
    assert "unknown key 'planner.bogus'" in _refusal(oracle.main, [*out, *planner, "bogus=1"])
    assert "lon_split must be 0" in _refusal(oracle.main, [*out, *planner, "lon_split=9"])
    assert not list(tmp_path.iterdir())


def test_style_states_refuses_a_missing_folder_in_one_line(tmp_path):
    states = _study("style_states")
    with pytest.raises(SystemExit) as e:
        states.main(["--runs", str(tmp_path / "r"), "--data", str(tmp_path), "--calibrate-on", str(tmp_path)])
    assert "r is not a folder" in str(e.value) and "\n" not in str(e.value)


def test_style_recording_refuses_what_it_cannot_drive_in_one_line(tmp_path):
    rec = _study("style_recording")
    cases = [
        (["--sumo-seed", "1"], "SUMO seed 1 is the study's own recording"),
        (["--cars", "10", "20"], "--cars must lie within 22..59"),
        (["--cars", "42", "60"], "--cars must lie within 22..59"),
        (["--cars", "42", "59"], "holds no trained recording: run studies/styles.py"),
        (["--cars", "42", "59", "--headway", "0"], "--headway must be a time headway > 0 s, got 0.0"),
        (["--cars", "42", "59", "--choice", "expected"], "--choice expected calibrates one model's bias"),
    ]
    for args, words in cases:
        with pytest.raises(SystemExit) as e:
            rec.main(["--out", str(tmp_path), *args])
        assert words in str(e.value) and "\n" not in str(e.value)
    assert not list(tmp_path.iterdir())  # nothing written


def test_style_recording_swaps_the_egos_and_their_count(tmp_path):
    rec = _study("style_recording")
    src = tmp_path / "reference.toml"
    src.write_text(
        'train_episodes = 20\nmax_cycles = 800\n[demonstrator]\nkind = "recording"\nego = "car22,car23"\n'
    )
    text = Path(rec.with_egos(src, tmp_path / "out.toml", ["car42", "car43", "car44"])).read_text()
    assert (
        'ego = "car42,car43,car44"' in text and "train_episodes = 3\n" in text and "max_cycles = 800" in text
    )


def test_style_side_collision_refuses_a_missing_sample_in_one_line(tmp_path):
    trace = _study("style_side_collision")
    with pytest.raises(SystemExit) as e:
        trace.main(
            ["--out", str(tmp_path), "--sumo-seed", "3", "--seed", "1", "--episode", "0", "--other", "car1"]
        )
    assert "is missing: run studies/style_recording.py first" in str(e.value) and "\n" not in str(e.value)


def test_style_dagger_rounds_and_refusals(tmp_path, monkeypatch):
    dagger = _study("style_dagger")
    assert "no dataset of assertive" in _refusal(dagger.main, ["--out", str(tmp_path)])
    assert "the expert labels its own rounds" in _refusal(
        dagger.main, ["--out", str(tmp_path), "--rows", "expert"]
    )
    ran = []
    monkeypatch.setattr(dagger.styles, "run", ran.append)  # the command lines only (pure logic)
    a = type("A", (), {"roads": ["oval", "motorway"], "round_episodes": 3, "workers": 2})()
    folders = dagger.dagger_round("assertive", 1, tmp_path, a)
    assert folders == [tmp_path / "dagger" / "assertive-seed1" / r for r in a.roads]
    for k, cmd in enumerate(ran):  # the study's reward drives round 1 on each road's own base seed
        i = cmd.index("--runs")
        assert (
            cmd[i + 1] == str(tmp_path / "runs" / "assertive-seed1")
            and cmd[cmd.index("--driver") + 1] == "PACNN+S"
        )
        assert cmd[cmd.index("--round") + 1] == "1" and f"seed={k}" in cmd and "train_episodes=3" in cmd
    assert len(ran) == 2


def test_style_floor_refuses_what_it_cannot_read_in_one_line(tmp_path):
    floor = _study("style_floor")
    assert "is not one of --demonstrators" in _refusal(
        floor.main, ["--out", str(tmp_path), "--rows", "r", "--driver", "x"]
    )
    assert "is missing: drive those rows first" in _refusal(
        floor.main, ["--out", str(tmp_path), "--rows", "r"]
    )


def test_the_oracle_executes_its_own_labels(tmp_path):
    """Real SUMO: without rules the projection oracle drives the demonstration wherever the look ahead has
    one, and collection records that same projection as the cycle's label."""
    import pandas as pd

    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig, EpisodeJob

    oracle = _study("style_oracle")
    sets = {"max_cycles": 25, "planner.n_policies": 60, "scenario.n_vehicles": 4, "train_episodes": 1}
    cfg = load_config(CollectConfig, "configs/collect/styles/assertive.toml", sets)
    stats = oracle.episode(EpisodeJob(str(tmp_path), "train", 0, 2_000_000_000, cfg))
    cyc = pd.read_parquet(next((tmp_path / "train").glob("*.cycles.parquet")))
    has = cyc["demo_index"].to_numpy() >= 0
    assert has.sum() == stats["oracle/demonstration"] > 0 and stats["oracle/expert"] == 0
    # no rules, nothing ruled out: every other cycle had no policy within the projection's distance
    assert stats["oracle/ruled_out"] == 0 and stats["oracle/beyond"] == (~has).sum()
    gaps = stats["oracle/gaps"]  # every cycle with 2 s of look ahead, of one kind
    assert set(gaps) == {"braking", "steady", "accelerating"}
    assert 0 < sum(g[0] for g in gaps.values()) <= len(cyc)
    assert (cyc["executed_index"].to_numpy()[has] == cyc["demo_index"].to_numpy()[has]).all()


def test_style_oracle_names_its_table_by_every_planner_field_whole(tmp_path):
    oracle = _study("style_oracle")
    js, md = oracle.table_paths(tmp_path, "-s2000-commit-stop-lon_split=1.0-accel_ramp=0.5", "assertive")
    assert md.name == "style-oracle-s2000-commit-stop-lon_split=1.0-accel_ramp=0.5-assertive.md"
    assert js.parent == md.parent == tmp_path and js.name == md.name[:-3] + ".json"
    other, _ = oracle.table_paths(tmp_path, "-s2000-commit-stop-lon_split=1.0-accel_ramp=0.7", "assertive")
    assert other != js  # a field's decimals tell two tables apart


def test_counterfactual_sets_one_group_to_the_own_demonstrators():
    """A row that is its own demonstrator's driving but for its speed: with the speed set to the
    demonstrator's it is that driving (distance 0 as defined); with any other group set, the speed still
    keeps it away; a lane-share group moves the whole share vector."""
    own = _style([15.0, 2.4, 1.0, 6.0, 1.4, 1.0, 0.1], [0.1, 0.4, 0.5])
    other = _style([14.0, 3.0, 1.5, 4.5, 1.1, 0.4, 0.1], [0.4, 0.3, 0.3])
    third = _style([10.0, 5.0, 2.5, 1.0, 0.7, 0.3, 0.2], [0.5, 0.3, 0.2])
    refs = {"own": own, "other": other, "third": third}
    row = {**own, "style/mean_speed": 18.0}
    spread = style_spread([own, other, third])  # the normaliser: the references' episodes, one each here
    cf = norms.counterfactual(row, refs, "own", spread)
    assert list(cf) == list(norms.GROUPS)
    assert cf["speed"]["own"] == 0.0 and cf["speed"]["other"] > 0
    assert all(cf[g]["own"] > 0 for g in norms.GROUPS if g != "speed")
    # the lanes: a row with the other's shares, moved back to its own's, is its own driving again
    lanes = norms.counterfactual({**own, "style/lane_share": other["style/lane_share"]}, refs, "own", spread)
    assert lanes["lane shares"]["own"] == 0.0 and lanes["speed"]["own"] > 0
