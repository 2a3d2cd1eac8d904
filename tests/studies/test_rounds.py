"""The round-size study's bookkeeping (pure logic): schedules, the rounds a schedule shares with the
recipe's own, the DAgger time of a schedule, and the rule that picks one."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("rounds", Path(__file__).parents[2] / "studies" / "rounds.py")
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)  # type: ignore[union-attr]


def test_schedules_parse_or_exit_with_one_line():
    assert study.parse_schedule("6,20") == (6, 20)
    assert study.parse_schedule("6") == (6,)
    for bad in ("6,x", "", "0,5", "6,-1"):
        with pytest.raises(SystemExit) as e:
            study.parse_schedule(bad)
        assert "\n" not in str(e.value)


def test_shared_rounds_are_the_leading_equal_ones():
    assert study.shared_rounds((6, 20), (6, 20)) == 2
    assert study.shared_rounds((6, 10), (6, 20)) == 1
    assert study.shared_rounds((6,), (6, 20)) == 1
    assert study.shared_rounds((10, 20), (6, 20)) == 0  # round 2 differs too: its driver is another


def test_the_own_schedule_is_the_rounds_the_run_made(tmp_path):
    for r, episodes in ((1, 6), (2, 20), (10, 3)):
        (tmp_path / "dagger" / f"round_{r}").mkdir(parents=True)
        record = {"round": r, "inputs": {"episodes": episodes}}
        (tmp_path / "dagger" / f"round_{r}" / "round.json").write_text(json.dumps(record))
    assert study.own_schedule(tmp_path) == (6, 20, 3)


def test_dagger_time_is_the_linked_rounds_and_the_steps_run(tmp_path):
    (tmp_path / "round_1").mkdir()  # linked: the recipe's own round 1
    (tmp_path / "round_1" / "round.json").write_text(json.dumps({"round": 1, "wall_s": 316.2}))
    assert study.dagger_seconds(tmp_path) == 316.2
    steps = {"round 2 collect": 61.5, "round 2 train stage 1": 200.0, "round 2 train stage 2": 70.3}
    (tmp_path / "times.json").write_text(json.dumps({**steps, "development drive dev10": 160.0}))
    assert study.dagger_seconds(tmp_path) == 648.0  # the drive is not DAgger time


def _row(schedule, seed, model, bar):
    return {"schedule": schedule, "seed": seed, "model": model, "bar": bar}


def test_the_rule_takes_the_fewest_episodes_that_pass_everywhere():
    rows = [_row(s, seed, m, True) for s in ("6", "6,10", "6,20") for seed in (0, 1) for m in ("a", "b")]
    assert study.choose(rows) == "6"
    rows[1]["bar"] = False  # one model of one seed fails with one round: the schedule fails
    assert study.choose(rows) == "6,10"
    assert study.choose([r | {"bar": False} for r in rows]) is None


def test_with_stage2_last_a_linked_earlier_round_counts_without_its_stage2(tmp_path):
    (tmp_path / "round_1").mkdir()  # linked: the recipe's own round 1, which trained PTACNN+S too
    steps_1 = {"collect": 53.2, "train stage 1": 110.7, "train stage 2": 118.4}
    record = {"round": 1, "wall_s": 282.4, "steps_s": steps_1}
    (tmp_path / "round_1" / "round.json").write_text(json.dumps(record))
    (tmp_path / "round_2").mkdir()  # run here: its steps in times.json
    steps = {"round 2 collect": 55.0, "round 2 train stage 1": 130.0, "round 2 train stage 2": 200.0}
    (tmp_path / "times.json").write_text(json.dumps(steps))
    assert study.dagger_seconds(tmp_path) == 667.4
    assert study.dagger_seconds(tmp_path, stage2_last=True) == 549.0  # without round 1's 118.4


def test_development_samples_stay_in_the_development_seeds_and_apart():
    study.check_dev_seeds([2000], 20)
    study.check_dev_seeds([2020, 2000], 20)  # two samples of 20: 2000-2039
    for starts in ([1990], [2990], [3000], [2000, 2010]):  # evaluation seeds, past 2999, overlapping
        with pytest.raises(SystemExit) as e:
            study.check_dev_seeds(starts, 20)
        assert "\n" not in str(e.value)


_tq = importlib.util.spec_from_file_location(
    "time_quality", Path(__file__).parents[2] / "studies" / "time_quality.py"
)
time_quality = importlib.util.module_from_spec(_tq)
_tq.loader.exec_module(time_quality)  # type: ignore[union-attr]


def test_time_quality_takes_every_schedule_that_drove_the_first_development_sample(tmp_path):
    for folder in ("accept-round2-s2000-e20", "rounds-6-10-10-s2last/dev20", "rounds-6-20-10/dev20"):
        (tmp_path / folder).mkdir(parents=True)
        (tmp_path / folder / "drive.json").write_text("{}")
    (tmp_path / "rounds-6-6-6-s2last").mkdir()  # no drive: not a point
    (tmp_path / "rounds-6-10" / "dev20-s2020").mkdir(parents=True)  # another sample only: not a point
    (tmp_path / "rounds-6-10" / "dev20-s2020" / "drive.json").write_text("{}")
    labels = [label for label, _, _ in time_quality.schedule_folders(tmp_path)]
    assert labels == [time_quality.OWN, "6,10,10", "6,20,10"]


def test_points_round_trip_through_their_csv_and_a_foreign_csv_is_refused(tmp_path):
    s = {"drive/collisions": 0, "drive/exits": 1, "drive/stop_lines_compliant": 79}
    s |= {"drive/stop_lines_passed": 80, "drive/checkpoints_in_lane": 150, "drive/checkpoints_passed": 160}
    s["score/score"] = 93.25
    rows = [time_quality.row("new3p", 26, "PACNN+S", 17.654, "evaluation", s)]
    unscored = {"seed": 27, "model": "PTACNN+S", "score/score": None}  # published without a score
    rows.append({**rows[0], **unscored})
    time_quality.write_points(rows, tmp_path / "p.csv")
    back = time_quality.read_points(tmp_path / "p.csv")
    assert back == rows
    assert time_quality.events(back[0]) == 2 and time_quality.in_lane(back[0]) == 150 / 160
    assert "| - |" in time_quality.table(back).splitlines()[-1]
    again = {**rows[0], "score/score": 50.0}
    assert time_quality.merge([*back, again]) == [again, rows[1]]
    (tmp_path / "other.csv").write_text("vehicle,time,x,y\n0,0.0,1.0,2.0\n")
    with pytest.raises(SystemExit) as e:
        time_quality.read_points(tmp_path / "other.csv")
    assert "not a points file" in str(e.value) and "\n" not in str(e.value)
    short = (tmp_path / "p.csv").read_text().splitlines()[:2]
    (tmp_path / "short.csv").write_text(short[0] + "\n" + short[1].rsplit(",", 3)[0] + "\n")  # cut short
    with pytest.raises(SystemExit) as e:
        time_quality.read_points(tmp_path / "short.csv")
    assert "a row that is not a point" in str(e.value) and "\n" not in str(e.value)
