"""A dataset over several scenarios (collect config ``[[scenarios]]``), collected by the expert in SUMO:
its manifest (names, digests, each episode's scenario), the Parquet record, the reader's per-cycle
scenario and selection, training and evaluation on a selection, the per-scenario breakdown of Table I,
and the one-line refusal of a changed scenario list on resume."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from irlsim.errors import IrlsimError
from tests.conftest import MULTI_TOML, one_line, refused


def test_manifest_records_every_scenario_and_episode(multi):
    from irlsim.data.schema import cycles_name, policies_name
    from irlsim.road.scenario import load_scenario

    _, data = multi
    m = json.loads((data / "manifest.json").read_text())
    assert m["complete"] is True
    assert m["scenarios"] == {"oval": load_scenario("oval").digest(), "ramp": load_scenario("ramp").digest()}
    assert all(d.startswith("sha256:") and len(d) == 71 for d in m["scenarios"].values())
    assert m["episode_scenarios"] == {
        "train": {"0": "oval", "1": "ramp"},
        "validation": {"0": "ramp"},
        "test": {"0": "oval", "1": "ramp"},
    }
    assert [e["name"] for e in m["config"]["scenarios"]] == ["oval", "ramp"]
    assert m["splits"] == {"train": [0, 1], "validation": [0], "test": [0, 1]}
    seeds = [s for split in m["seeds"].values() for s in split]
    assert len(seeds) == len(set(seeds)) == 5  # disjoint over scenarios and splits
    # each episode's files record its scenario beside seed and config
    for split, per in m["episode_scenarios"].items():
        for ep, name in per.items():
            for name_of in (cycles_name, policies_name):
                meta = pq.read_schema(data / split / name_of(int(ep))).metadata
                assert meta[b"irlsim.scenario"] == name.encode()


def test_reader_gives_every_cycle_its_scenario_and_selects(multi):
    from irlsim.data.reader import open_dataset

    _, data = multi
    ds = open_dataset(data)
    assert ds.scenarios == ["oval", "ramp"]
    names = ds.scenario_of_cycle("test")
    cycles = ds.read_cycles("test")
    assert len(names) == len(cycles) == ds.split_tensors("test").n_cycles
    assert (names[cycles["episode"].to_numpy() == 0] == "oval").all()
    assert (names[cycles["episode"].to_numpy() == 1] == "ramp").all()
    assert set(names) == {"oval", "ramp"}

    ramp = open_dataset(data, ("ramp",))
    assert ramp.episodes("test") == [1] and ramp.episodes("train") == [1]
    t = ramp.split_tensors("test")
    assert t.n_cycles == int((names == "ramp").sum()) and set(np.asarray(t.episode).tolist()) == {1}
    assert set(ramp.scenario_of_cycle("test")) == {"ramp"}
    # the whole dataset's cache is not overwritten by the selection's
    assert ds.split_tensors("test").n_cycles == len(names)
    assert ramp.identity != open_dataset(data, ("oval",)).identity

    from irlsim.data.info import dataset_info, format_info

    info = dataset_info(data)
    assert info["scenarios"] == {
        "oval": {"train": 1, "validation": 0, "test": 1},
        "ramp": {"train": 1, "validation": 1, "test": 1},
    }
    assert "scenarios (episodes): oval (train 1, validation 0, test 1); ramp (" in format_info(info)

    with pytest.raises(IrlsimError) as e:
        open_dataset(data, ("motorway",))
    assert "has no scenario 'motorway'" in one_line(e) and "oval, ramp" in one_line(e)


def test_resume_with_another_scenario_list_is_refused(multi, tmp_path, capsys):
    from irlsim.cli import main

    cfg, data = multi
    before = (data / "manifest.json").read_bytes()
    changed = tmp_path / "changed.toml"
    changed.write_text(MULTI_TOML.replace('name = "ramp"', 'name = "motorway"'))
    msg = refused(capsys, ["collect", "--config", str(changed), "--out", str(data)])
    assert "over the scenarios oval, ramp, this config lists oval, motorway" in msg and "--out" in msg
    fewer = tmp_path / "fewer.toml"
    fewer.write_text(MULTI_TOML.replace("validation_episodes = 1", "validation_episodes = 2"))
    assert "another [[scenarios]] list" in refused(
        capsys, ["collect", "--config", str(fewer), "--out", str(data)]
    )
    assert (data / "manifest.json").read_bytes() == before  # refused before any work
    # the same list resumes (nothing to do)
    assert main(["collect", "--config", str(cfg), "--out", str(data)]) == 0


def test_bad_scenario_lists_are_one_line(tmp_path, capsys):

    cases = {
        MULTI_TOML.replace(
            "seed = 0", "seed = 0\ntrain_episodes = 7"
        ): "train_episodes = 7 but [[scenarios]]",
        MULTI_TOML.replace('name = "ramp"', 'name = "oval"'): "lists 'oval' twice",
        MULTI_TOML.replace("n_vehicles = 4", 'n_vehicles = 4\nname = "ramp"'): "both name the road",
        MULTI_TOML.replace('name = "ramp"', 'name = "nowhere"'): "scenario 'nowhere' not found",
    }
    for i, (text, want) in enumerate(cases.items()):
        cfg = tmp_path / f"bad{i}.toml"
        cfg.write_text(text)
        assert want in refused(capsys, ["collect", "--config", str(cfg), "--out", str(tmp_path / f"d{i}")])
        assert not (tmp_path / f"d{i}" / "manifest.json").exists()


def test_training_on_a_selection(multi, ramp_runs, capsys):
    import torch

    from irlsim.data.reader import open_dataset

    _, data = multi
    summary = json.loads((ramp_runs / "stage1" / "summary.json").read_text())
    assert summary["scenarios"] == ["ramp"]
    ckpt = torch.load(ramp_runs / "stage1" / "LIRL" / "checkpoint.pt", weights_only=True)
    assert ckpt["dataset"] == open_dataset(data, ("ramp",)).identity
    # trained on the ramp's train episode only: its cycles are the ramp's
    train_cycles = open_dataset(data, ("ramp",)).split_tensors("train").n_cycles
    assert train_cycles < open_dataset(data).split_tensors("train").n_cycles
    # resuming on another selection is refused in one line
    args = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(data)]
    args += ["--out", str(ramp_runs), "--set", "models=['LIRL']", "--set", "epochs=2"]
    assert "trained on another dataset" in refused(capsys, [*args, "--scenario-select", "oval,ramp"])
    assert "empty name" in refused(capsys, [*args, "--scenario-select", "ramp,"])


def test_evaluate_breaks_table_one_down_by_scenario(multi, ramp_runs, tmp_path, capsys):
    from irlsim.cli import main

    _, data = multi
    out = tmp_path / "eval"
    assert main(["evaluate", "--data", str(data), "--runs", str(ramp_runs), "--out", str(out)]) == 0
    md = (out / "results.md").read_text()
    assert "## OPD / ED per scenario [m]" in md and "## OPD / ED per situation [m]" in md
    rows = json.loads((out / "results.json").read_text())["rows"]
    lirl = next(r for r in rows if r["model"] == "LIRL")
    assert list(lirl["scenarios"]) == ["oval", "ramp"]
    total = sum(v["cycles"] for v in lirl["scenarios"].values())
    assert total == sum(v["cycles"] for v in lirl["situations"].values()) > 0
    # the breakdown's cycles average back to the whole split's OPD
    opd = sum(v["opd"] * v["cycles"] for v in lirl["scenarios"].values() if v["cycles"]) / total
    assert opd == pytest.approx(lirl["opd"], rel=1e-6)

    only = tmp_path / "eval_oval"
    args = ["evaluate", "--data", str(data), "--runs", str(ramp_runs), "--out", str(only)]
    assert main([*args, "--scenario-select", "oval", "--no-references"]) == 0
    rows = json.loads((only / "results.json").read_text())["rows"]
    assert list(next(r for r in rows if r["model"] == "LIRL")["scenarios"]) == ["oval"]


def test_one_road_other_than_the_oval_records_it(tmp_path):
    """A dataset of one scenario other than the oval records ``scenarios`` alone (name and digest); one
    collected before manifests recorded roads keeps its manifest's bytes when collect runs again."""
    from irlsim.cli import main
    from irlsim.data.reader import open_dataset
    from irlsim.road.scenario import load_scenario

    out = tmp_path / "motorway"
    args = ["collect", "--config", "configs/collect/tiny.toml", "--scenario", "motorway", "--out", str(out)]
    tiny = ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]
    tiny += ["--set", "max_cycles=20", "--set", "planner.n_policies=120", "--set", "scenario.n_vehicles=3"]
    assert main([*args, *tiny]) == 0
    path = out / "manifest.json"
    m = json.loads(path.read_text())
    assert m["scenarios"] == {"motorway": load_scenario("motorway").digest()}
    assert "episode_scenarios" not in m
    assert set(open_dataset(out).scenario_of_cycle("train")) == {"motorway"}
    del m["scenarios"]  # as an older irlsim wrote it
    path.write_text(json.dumps(m, indent=2) + "\n")
    before = path.read_bytes()
    assert main([*args, *tiny]) == 0
    assert path.read_bytes() == before


def test_table_one_of_a_reward_on_data_it_never_saw(multi, ramp_runs, tiny_dataset, tmp_path, capsys):
    """Transfer: models trained on the ramp's episodes are refused on the oval's dataset unless the
    evaluation is asked for held-out data; then Table I has every trained model and results.json says it
    was held out and on what the models were trained. The data they were trained on is not held out:
    --held-out is refused there in one line, and accepted on the same folder's other scenario."""
    from irlsim.cli import main

    args = ["evaluate", "--data", str(tiny_dataset), "--runs", str(ramp_runs), "--no-references"]
    assert "trained on another dataset" in refused(capsys, [*args, "--out", str(tmp_path / "refused")])
    assert not (tmp_path / "refused" / "results.json").exists()
    assert main([*args, "--out", str(tmp_path / "held_out"), "--held-out"]) == 0
    rows = json.loads((tmp_path / "held_out" / "results.json").read_text())
    assert rows["evaluated_on"]["held_out"] is True and rows["evaluated_on"]["data"] == [str(tiny_dataset)]
    assert rows["trained_on"]["stage1/PACNN"]["dataset"].startswith("sha256:")
    text = json.dumps(rows)
    assert "LIRL" in text and "PACNN" in text
    _, data = multi
    own = ["evaluate", "--data", str(data), "--runs", str(ramp_runs), "--no-references"]
    own += ["--scenario-select", "ramp", "--out"]
    assert main([*own, str(tmp_path / "own")]) == 0
    line = refused(capsys, [*own, str(tmp_path / "own_flag"), "--held-out"])
    assert "error: --held-out: " in line and "so it is not held out: evaluate without --held-out" in line
    assert not (tmp_path / "own_flag").exists()
    record = json.loads((tmp_path / "own" / "results.json").read_text())
    assert record["evaluated_on"]["held_out"] is False
    assert "Held out: no." in (tmp_path / "own" / "results.md").read_text()
    oval = [*own[:-3], "--scenario-select", "oval", "--out", str(tmp_path / "oval"), "--held-out"]
    assert main(oval) == 0
    record = json.loads((tmp_path / "oval" / "results.json").read_text())
    assert record["evaluated_on"] == {
        "data": [str(data)],
        "dataset": record["evaluated_on"]["dataset"],
        "scenarios": ["oval"],
        "held_out": True,
    }
    assert record["trained_on"]["stage1/LIRL"]["data"] == str(data)
    assert (
        f"Held out: yes. Evaluated on {data}; the models were trained on {data}."
        in (tmp_path / "oval" / "results.md").read_text()
    )
