"""DAgger in real SUMO at a tiny size: ``irlsim collect --driver`` (a learned reward drives, the expert
labels), the ``demo_source`` column, round seeds, aggregation and ``irlsim dagger`` end to end."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from irlsim.cli import main
from irlsim.config import load_config
from irlsim.data.collection import (
    MAX_DAGGER_ROUND,
    SPLITS,
    CollectConfig,
    EpisodeJob,
    collect_episode,
)
from irlsim.data.reader import open_dataset
from irlsim.drive.dagger import dagger_driver_factory
from irlsim.errors import IrlsimError
from irlsim.planner.expert import ExpertDriver
from irlsim.reward.predictor import RewardPredictor
from irlsim.rollout import ObserverBase
from irlsim.train.checkpoint import save_checkpoint
from irlsim.workflows.dagger_record import file_sha
from tests.pipelines.conftest import MODEL


@pytest.fixture(scope="module")
def dagger_run(tiny_dataset, learner, tmp_path_factory):
    """(out folder, stdout) of one tiny DAgger round: drive, label, aggregate, retrain."""
    collect_cfg, runs = learner
    out = tmp_path_factory.mktemp("dagger_rounds") / "dagger"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(
            [
                "dagger",
                "--config",
                "configs/dagger/tiny.toml",
                "--data",
                str(tiny_dataset),
                "--runs",
                str(runs),
            ]
            + ["--out", str(out), "--set", f"collect_config='{collect_cfg}'"]
        )
    assert rc == 0, buf.getvalue()[-3000:]
    return out, buf.getvalue()


def _cycles(folder: Path) -> pd.DataFrame:
    return pd.concat([pd.read_parquet(p) for p in sorted(folder.glob("*/*.cycles.parquet"))])


def test_dagger_round_end_to_end(tiny_dataset, learner, dagger_run):
    out, stdout = dagger_run
    data, runs = out / "round_1" / "data", out / "round_1" / "runs"
    manifest = json.loads((data / "manifest.json").read_text())
    assert manifest["complete"] and manifest["config"]["dagger_round"] == 1
    ckpt = learner[1] / "stage1" / MODEL / "checkpoint.pt"
    assert manifest["driver"]["model"] == MODEL
    assert manifest["driver"]["checkpoint"] == str(ckpt.resolve())
    import hashlib

    assert manifest["driver"]["sha256"] == hashlib.sha256(ckpt.read_bytes()).hexdigest()
    # labelled by the expert, never mixed up with the projected odometry of the expert's own data
    assert set(_cycles(data)["demo_source"]) == {"expert"}
    assert set(_cycles(tiny_dataset)["demo_source"]) == {"odometry"}
    # retrained on the aggregate of both folders: the checkpoint names both datasets
    new = runs / "stage1" / MODEL / "checkpoint.pt"
    assert new.is_file()
    summary = json.loads((runs / "stage1" / "summary.json").read_text())
    assert summary["data"] == [str(tiny_dataset), str(data)]
    record = json.loads((out / "round_1" / "round.json").read_text())
    assert record["trained_on"] == [str(tiny_dataset), str(data)]
    steps = record["steps_s"]  # where the round's time went: every step, within the round's wall time
    assert list(steps) == ["collect", "train stage 1"]
    # each time is rounded to 0.1 s, so the sum may pass the wall time by half a tenth per rounding
    slack = 0.05 * (len(steps) + 1)
    assert all(t >= 0 for t in steps.values()) and sum(steps.values()) <= record["wall_s"] + slack
    assert f"dagger: round 1 wrote {data}" in stdout
    took = f"dagger: round 1 took {record['wall_s']:.1f} s (collect {steps['collect']:.1f} s, train stage 1"
    assert took in stdout  # the same times, printed as the round ends
    # the training reader exposes demo_source: the aggregate's train split holds both kinds, in order
    from irlsim.data.aggregate import open_datasets

    agg = open_datasets([tiny_dataset, data])
    tr = agg.split_tensors("train")
    n_odo = open_dataset(tiny_dataset).split_tensors("train").n_cycles
    assert (tr.demo_source[:n_odo] == 0).all() and (tr.demo_source[n_odo:] == 1).all()
    assert tr.expert_labelled.sum() == tr.n_cycles - n_odo > 0
    assert len(set(tr.episode[:n_odo]) & set(tr.episode[n_odo:])) == 0  # histories never span folders
    # evaluated on the aggregate it was trained on (its test split is the expert data's)
    ev = out / "eval"
    assert (
        main(["evaluate", "--data", str(tiny_dataset), str(data), "--runs", str(runs), "--out", str(ev)]) == 0
    )
    assert (ev / "results.json").is_file()
    # finished rounds are skipped: nothing is collected or trained again
    mtime = new.stat().st_mtime_ns
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(
            ["dagger", "--config", "configs/dagger/tiny.toml", "--data", str(tiny_dataset), "--runs"]
            + [str(learner[1]), "--out", str(out), "--set", f"collect_config='{learner[0]}'"]
        )
    assert rc == 0 and "round 1 finished before" in buf.getvalue()
    assert new.stat().st_mtime_ns == mtime


def test_round_seeds_are_disjoint_from_the_expert_data(tiny_dataset, dagger_run):
    out, _ = dagger_run
    expert = json.loads((tiny_dataset / "manifest.json").read_text())["seeds"]
    dagger = json.loads((out / "round_1" / "data" / "manifest.json").read_text())["seeds"]
    used = {s for v in expert.values() for s in v}
    new = {s for v in dagger.values() for s in v}
    assert new and not (used & new)
    # the rule at its limits: any base seed, every round, the largest episode counts
    big = {f"{s}_episodes": 10_000 for s in SPLITS}
    seen: dict[int, tuple[int, int]] = {}
    for base in (0, 1):
        for r in (0, 1, 2, MAX_DAGGER_ROUND):
            cfg = CollectConfig(seed=base, dagger_round=r, **big)
            cfg.validate()
            for s in SPLITS:
                for _, seed in cfg.episodes(s):
                    assert seen.setdefault(seed, (base, r)) == (base, r), seed
    with pytest.raises(IrlsimError, match="dagger_round"):
        CollectConfig(dagger_round=MAX_DAGGER_ROUND + 1).validate()


class _Observations(ObserverBase):
    def __init__(self):
        self.obs = []

    def on_cycle(self, sim, cycle):
        self.obs.append(cycle.obs)


def test_labels_come_from_the_expert_at_the_learners_states(learner, road, tmp_path):
    collect_cfg, runs = learner
    cfg = load_config(CollectConfig, collect_cfg, {"dagger_round": 1})
    ckpt = str((runs / "stage1" / MODEL / "checkpoint.pt").resolve())
    seen = _Observations()
    job = EpisodeJob(str(tmp_path), "train", 0, 300_000, cfg, ckpt)
    stats = collect_episode(job, dagger_driver_factory(ckpt, cfg.planner.n_policies), observers=[seen])
    cyc = pd.read_parquet(tmp_path / "train" / "episode_00000.cycles.parquet")
    pol = pd.read_parquet(tmp_path / "train" / "episode_00000.policies.parquet")
    n = cfg.planner.n_policies
    assert len(cyc) == len(seen.obs) == stats["collect/cycles"] > 10
    feats = np.stack(pol["features"].to_numpy()).reshape(len(cyc), n, -1)
    dist = pol["distance"].to_numpy().reshape(len(cyc), n)
    # computed again, independently: a fresh expert and a fresh model on each recorded state
    expert = ExpertDriver(road, cfg.planner)
    model = RewardPredictor(ckpt)
    differs = 0
    for k, obs in enumerate(seen.obs):
        ps = expert.planner.plan(obs)
        np.testing.assert_allclose(feats[k], ps.features.astype(np.float32), rtol=1e-6)  # the same set
        theta, _ = model.predict(ps.features, ps.control_points, ps.actions)
        learned = int(np.argmax(ps.value(theta)))
        label = expert.select(ps, obs)
        assert cyc["executed_index"].iloc[k] == learned  # the learned reward drove
        assert cyc["demo_index"].iloc[k] == label  # the expert labelled, on the same set and state
        assert cyc["demo_distance"].iloc[k] == 0.0 and dist[k, label] == 0.0
        differs += int(label != learned)
        expert.follow(ps, learned)
        if k + 1 < len(seen.obs):  # the next state is where the learner's policy led, not the expert's
            st = expert.planner.trajectory(learned).state(cfg.scenario.steps_per_cycle)
            assert seen.obs[k + 1].ego.s == pytest.approx(st.s, abs=1e-6)
            assert cyc["ego_s"].iloc[k + 1] == pytest.approx(st.s, rel=1e-6)
    assert differs > 0  # else this test could not tell the labels from the executed policies
    assert set(cyc["demo_source"]) == {"expert"}
    assert stats["collect/expert_agreement"] == pytest.approx(1 - differs / len(cyc), abs=1e-4)


def test_dagger_collection_same_seed_same_bytes(learner, tmp_path):
    collect_cfg, runs = learner
    args = ["collect", "--config", str(collect_cfg), "--driver", MODEL, "--runs", str(runs)]
    args += ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]
    for name in ("a", "b"):
        assert main([*args, "--out", str(tmp_path / name)]) == 0
    for f in sorted((tmp_path / "a" / "train").glob("*.parquet")):
        assert f.read_bytes() == (tmp_path / "b" / "train" / f.name).read_bytes(), f.name


def test_dagger_collection_bad_input_is_one_line(learner, dagger_run, tmp_path, capsys):
    collect_cfg, runs = learner
    base = ["collect", "--config", str(collect_cfg), "--out", str(tmp_path / "x")]
    cases = [
        (["--round", "2"], "--driver"),
        (["--driver", "expert"], "trained model"),
        (["--driver", MODEL], "--runs"),
        (["--driver", MODEL, "--runs", str(runs), "--round", "0"], "--round must be >= 1"),
        (["--set", "dagger_round=1"], "needs a learned driver"),
    ]
    for extra, needle in cases:
        capsys.readouterr()
        assert main([*base, *extra]) == 2, extra
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err, err
    assert not (tmp_path / "x").exists()
    # resuming a round's folder with another driver is refused (its labels would be mixed); another by
    # content: other weights (a byte-identical copy elsewhere is the same driver, tests/reliability)
    other = tmp_path / "other" / MODEL
    other.mkdir(parents=True)
    ckpt = torch.load(runs / "stage1" / MODEL / "checkpoint.pt", weights_only=True)
    first = next(iter(ckpt["state_dict"]))
    ckpt["state_dict"][first] = ckpt["state_dict"][first] + 1e-3
    save_checkpoint(other / "checkpoint.pt", {k: v for k, v in ckpt.items() if k != "format"})
    out, _ = dagger_run
    data = out / "round_1" / "data"
    before = sorted(p.stat().st_mtime_ns for p in data.rglob("*.parquet"))
    rc = main(
        [
            "collect",
            "--config",
            str(collect_cfg),
            "--out",
            str(data),
            "--driver",
            str(other / "checkpoint.pt"),
        ]
        + ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "driver" in err, err
    assert sorted(p.stat().st_mtime_ns for p in data.rglob("*.parquet")) == before


def _dagger(argv: list[str], capsys) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = main(["dagger", "--config", "configs/dagger/tiny.toml", *argv])
    out, err = capsys.readouterr()
    return rc, out, err


def test_a_round_is_finished_only_as_it_was_asked_and_made(
    tiny_dataset, learner, dagger_run, tmp_path, capsys
):
    """A re-run with another input is one line (it was 'skipped' with exit 0); a round whose checkpoint
    was deleted runs again (it counted as finished); a copied DAgger folder is the same rounds."""
    collect_cfg, runs = learner
    out = tmp_path / "copy"
    shutil.copytree(dagger_run[0], out)  # by content: the copy is the same rounds
    base = ["--data", str(tiny_dataset), "--runs", str(runs), "--out", str(out)]
    base += ["--set", f"collect_config='{collect_cfg}'"]
    rc, stdout, err = _dagger(base, capsys)
    assert rc == 0 and "round 1 finished before" in stdout
    rc, _, err = _dagger([*base, "--set", "seed=5"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "was run with seed = None, now 5" in err
    # configs by their values: comments and layout edited is the same round, a value changed is not
    text = Path("configs/train/tiny_stage1.toml").read_text()
    edited, changed = tmp_path / "edited.toml", tmp_path / "changed.toml"
    edited.write_text("# a comment added since the round ran\n" + text.replace(" = ", "="))
    changed.write_text(text.replace("lr = 1e-2", "lr = 2e-2"))
    rc, stdout, err = _dagger([*base, "--set", f"stage1_config='{edited}'"], capsys)
    assert rc == 0 and "round 1 finished before" in stdout, err
    rc, _, err = _dagger([*base, "--set", f"stage1_config='{changed}'"], capsys)
    assert rc == 2 and err.count("\n") == 1 and f"another stage1_config than {changed}" in err
    record_file = out / "round_1" / "round.json"  # an older irlsim's record: the config by its bytes
    record = json.loads(record_file.read_text())
    record["inputs"]["configs"]["stage1_config"] = file_sha(Path("configs/train/tiny_stage1.toml"))
    record_file.write_text(json.dumps(record))
    rc, stdout, err = _dagger(base, capsys)
    assert rc == 0 and "round 1 finished before" in stdout, err
    rc, _, err = _dagger([*base, "--set", f"stage1_config='{edited}'"], capsys)  # bytes: cannot tell
    assert rc == 2 and "older irlsim recorded it by its bytes" in err
    ckpt = out / "round_1" / "runs" / "stage1" / MODEL / "checkpoint.pt"
    before = ckpt.read_bytes()
    ckpt.unlink()
    rc, stdout, err = _dagger(base, capsys)
    assert rc == 0 and "outputs are missing or changed" in stdout and "finished before" not in stdout
    assert ckpt.read_bytes() == before  # trained again to the same bytes


def test_dagger_checks_its_runs_against_its_data_before_any_work(
    tiny_dataset, learner, dagger_run, tmp_path, capsys
):
    collect_cfg, runs = learner
    other = dagger_run[0] / "round_1" / "data"  # a dataset the --runs model was not trained on
    out = tmp_path / "never"
    rc, _, err = _dagger(
        [
            "--data",
            str(other),
            "--runs",
            str(runs),
            "--out",
            str(out),
            "--set",
            f"collect_config='{collect_cfg}'",
        ],
        capsys,
    )
    assert rc == 2 and err.count("\n") == 1 and "was trained on another dataset than --data" in err
    wrong = tmp_path / "collect.toml"
    wrong.write_text(Path(collect_cfg).read_text().replace("n_policies = ", "n_policies = 1"))
    rc, _, err = _dagger(
        [
            "--data",
            str(tiny_dataset),
            "--runs",
            str(runs),
            "--out",
            str(out),
            "--set",
            f"collect_config='{wrong}'",
        ],
        capsys,
    )
    assert rc == 2 and err.count("\n") == 1 and "differs from the config --data" in err
    assert not out.exists()  # nothing written


def test_an_empty_validation_split_is_named_before_a_round_collects(learner, dagger_run):
    from irlsim.workflows.dagger import DaggerConfig, DaggerRun
    from irlsim.workflows.dagger_record import check_round_splits

    round_data = dagger_run[0] / "round_1" / "data"  # the learner's round alone: no validation episodes
    cfg = load_config(DaggerConfig, "configs/dagger/tiny.toml", {"validation_episodes": 0})
    with pytest.raises(IrlsimError, match="empty validation split"):
        check_round_splits(DaggerRun(cfg, round_data, learner[1], Path("unused")), 1)


def test_dagger_on_a_reward_trained_on_several_datasets(tiny_dataset, learner, dagger_run, capsys):
    """A reward trained on an aggregate (round 1's retraining: the expert data and round 1's data) is a
    DAgger driver when --data names the same folders in the same order; any other list is refused in one
    line before any work, and the round trains on every expert folder, then the round's data."""
    from irlsim.workflows.dagger import DaggerConfig, DaggerRun, round_plan
    from irlsim.workflows.dagger_record import check_driver_and_data

    collect_cfg, _ = learner
    out = dagger_run[0]
    agg_runs, r1 = out / "round_1" / "runs", out / "round_1" / "data"
    cfg = load_config(DaggerConfig, "configs/dagger/tiny.toml", {"collect_config": str(collect_cfg)})
    run = DaggerRun(cfg, tiny_dataset, agg_runs, out / "again", (r1,))
    check_driver_and_data(run)  # accepted: the folders and order it was trained on
    train = round_plan(run, 1).train[0]
    assert list(train.data) == [tiny_dataset, r1, out / "again" / "round_1" / "data"]
    for data in ([str(tiny_dataset)], [str(r1), str(tiny_dataset)]):
        rc, _, err = _dagger(
            ["--data", *data, "--runs", str(agg_runs), "--out", str(out / "never")]
            + ["--set", f"collect_config='{collect_cfg}'"],
            capsys,
        )
        assert rc == 2 and err.count("\n") == 1 and "trained on another dataset than --data" in err
    assert not (out / "never").exists()


def test_a_fine_tuning_round_starts_from_the_reward_that_drove_it(tiny_dataset, learner, tmp_path, capsys):
    """fine_tune: the round's stage-1 model starts from the driver's weights (recorded as warm_start in
    its checkpoint); the command line it records sets init_from; switching fine_tune on a finished round
    is refused in one line."""
    collect_cfg, runs = learner
    out = tmp_path / "ft"
    base = ["--data", str(tiny_dataset), "--runs", str(runs), "--out", str(out)]
    base += ["--set", f"collect_config='{collect_cfg}'", "--set", "epochs=[1]"]
    rc, stdout, err = _dagger([*base, "--set", "fine_tune=true"], capsys)
    assert rc == 0, err
    driver = runs / "stage1" / MODEL / "checkpoint.pt"
    ckpt = torch.load(out / "round_1" / "runs" / "stage1" / MODEL / "checkpoint.pt", weights_only=False)
    assert ckpt["warm_start"]["path"] == str(driver)
    record = json.loads((out / "round_1" / "round.json").read_text())
    assert any(f"init_from='{driver}'" in part for cmd in record["commands"] for part in cmd)
    assert record["inputs"]["fine_tune"] is True
    rc, _, err = _dagger(base, capsys)
    assert rc == 2 and err.count("\n") == 1 and "fine_tune" in err


def test_overlapped_and_last_only_rounds_give_the_same_bytes(tiny_dataset, learner, tmp_path, capsys):
    """overlap: round 2's learner episodes are collected while round 1 trains PTACNN+S; its data and every
    checkpoint are the bytes of the rounds run one step after the other. stage2_every_round = false: round
    1 trains no PTACNN+S, and every file it does make is the same bytes. A run's rounds that trained more
    are finished for a run that asks for less. Without stage-2 models, or with them in the last round
    only, there is nothing to overlap with: refused in one line."""
    collect_cfg, runs = learner
    common = ["--data", str(tiny_dataset), "--runs", str(runs), "--set", f"collect_config='{collect_cfg}'"]
    common += ["--set", "rounds=2", "--set", "episodes=1", "--set", "epochs=[1, 1]"]
    common += ["--set", "stage2_models=['PTACNN+S']", "--set", "fine_tune=true"]
    variants = {"seq": ["overlap=false"], "ovl": ["overlap=true"], "last": ["stage2_every_round=false"]}
    for name, sets in variants.items():
        rc, stdout, err = _dagger([*common, "--out", str(tmp_path / name), "--set", *sets], capsys)
        assert rc == 0, err
        if name == "ovl":
            assert "round 2's learner episodes are collected meanwhile" in stdout
    ovl = json.loads((tmp_path / "ovl" / "round_1" / "round.json").read_text())["steps_s"]
    assert list(ovl) == ["collect", "train stage 1", "train stage 2", "waiting for round 2's collection"]
    last = json.loads((tmp_path / "last" / "round_1" / "round.json").read_text())["steps_s"]
    assert list(last) == ["collect", "train stage 1"]
    files = sorted(p.relative_to(tmp_path / "seq") for p in (tmp_path / "seq").glob("round_*/**/*"))
    compared = [f for f in files if f.suffix in (".parquet", ".pt")]
    assert any("round_2/data" in str(f) for f in compared) and any(f.suffix == ".pt" for f in compared)
    for other in ("ovl", "last"):
        for f in compared:  # checkpoints record their folder's path (init_from): their weights and metrics
            a, b = tmp_path / "seq" / f, tmp_path / other / f
            if other == "last" and f.parts[:3] == ("round_1", "runs", "stage2"):
                assert not b.exists(), f  # round 1 trains no stage-2 model
                continue
            if f.suffix == ".parquet":
                assert a.read_bytes() == b.read_bytes(), (other, f)
                continue
            a, b = torch.load(a, weights_only=False), torch.load(b, weights_only=False)
            assert a["state_dict"].keys() == b["state_dict"].keys() and a["metrics"] == b["metrics"], f
            assert all(torch.equal(a["state_dict"][k], b["state_dict"][k]) for k in a["state_dict"]), f
    assert (tmp_path / "last" / "round_2" / "runs" / "stage2" / "PTACNN+S" / "checkpoint.pt").is_file()
    rc, stdout, err = _dagger([*common, "--out", str(tmp_path / "seq"), "--set", *variants["last"]], capsys)
    assert rc == 0 and stdout.count("finished before") == 2, err
    rc, _, err = _dagger(
        [*common[:-4], "--out", str(tmp_path / "bad"), "--set", "overlap=true", "--set", "rounds=2"], capsys
    )
    assert rc == 2 and err.count("\n") == 1 and "overlap needs" in err
    rc, _, err = _dagger(
        [*common, "--out", str(tmp_path / "bad"), "--set", "overlap=true", "--set", *variants["last"]], capsys
    )
    assert rc == 2 and err.count("\n") == 1 and "overlap needs stage2_every_round" in err
