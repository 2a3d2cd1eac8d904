"""``irlsim drive --model demonstrator``, with real SUMO: the config's demonstrator drives in closed loop
exactly as it drove while its data were collected (a SUMO driver on the same seed, a recorded car on its
recording: the same style figures), beside learned rewards for a style distance; the expert's config is
refused in one line before any work."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from irlsim.cli import main
from tests.data.test_demonstrator import BASE, IDM

ROOT = Path(__file__).resolve().parents[2]


def _styles(record: dict) -> dict[str, float]:
    return {k: v for k, v in record.items() if k.startswith("style/")}


def _drive(cfg: Path, out: Path, seed: int, cycles: int, *extra: str) -> dict:
    args = ["drive", "--model", "demonstrator", "--config", str(cfg), "--seed", str(seed), "--episodes", "1"]
    assert main([*args, "--max-cycles", str(cycles), "--frames", "0", "--out", str(out), *extra]) == 0
    return json.loads((out / "drive.json").read_text())


def test_a_sumo_demonstrator_drives_as_it_was_collected(tmp_path):
    cfg = tmp_path / "idm.toml"
    cfg.write_text(BASE + IDM)
    assert main(["collect", "--config", str(cfg), "--out", str(tmp_path / "data")]) == 0
    collected = json.loads((tmp_path / "data" / "train" / "episode_00000.stats.json").read_text())
    drive = _drive(cfg, tmp_path / "drive", collected["collect/seed"], 30)
    (episode,) = drive["episodes"]
    assert episode["drive/model"] == "demonstrator" and episode["drive/cycles"] == 30
    np.testing.assert_equal(_styles(episode), _styles(collected))  # exactly; a NaN (no leader) as NaN
    assert episode["style/km"] > 0.05 and len(_styles(episode)) >= 10
    assert not (tmp_path / "drive" / "demonstrator").exists()  # no policy executed: no pictures


def test_a_recorded_car_drives_as_recorded_beside_a_reward(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)  # the example's recording is a path from the repository's root
    data = tmp_path / "data"
    assert main(["collect", "--config", "examples/mydriver/collect.toml", "--out", str(data)]) == 0
    collected = json.loads((data / "train" / "episode_00000.stats.json").read_text())
    cfg = tmp_path / "car0.toml"
    cfg.write_text((ROOT / "examples/mydriver/drive.toml").read_text().replace('"car4"', '"car0"'))
    drive = _drive(cfg, tmp_path / "drive", 7, 40)
    np.testing.assert_equal(_styles(drive["episodes"][0]), _styles(collected))
    # with the expert beside it, three drivings: the expert, expert-theta and the recorded car
    out = tmp_path / "three"
    args = [
        "drive",
        "--model",
        "expert,expert-theta,demonstrator",
        "--config",
        str(cfg),
        "--max-cycles",
        "40",
    ]
    assert main([*args, "--frames", "0", "--out", str(out)]) == 0
    rows = {s["drive/model"]: s for s in json.loads((out / "drive.json").read_text())["summary"]}
    assert set(rows) == {"expert", "expert-theta", "demonstrator"}
    assert "the demonstrator: none, it drives as collected" in (out / "drive.md").read_text()
    np.testing.assert_equal(_styles(rows["demonstrator"]["style"]), _styles(collected))


def test_the_experts_config_is_refused_before_any_work(tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "drive"
    rc = main(["drive", "--model", "expert,demonstrator", "--max-cycles", "5", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert (
        "--model demonstrator drives the config's [demonstrator], and this config's is the expert" in err[0]
    )
    assert not out.exists()
