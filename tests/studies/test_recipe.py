"""The recipe study's bookkeeping (pure logic): the closed-loop bar, the last DAgger round, the table."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("recipe", Path(__file__).parents[2] / "studies" / "recipe.py")
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)  # type: ignore[union-attr]


def _summary(**kw):
    s = {
        "drive/collisions": 0, "drive/exits": 0, "drive/stop_lines_compliant": 80,
        "drive/stop_lines_passed": 80, "drive/checkpoints_in_lane": 144, "drive/checkpoints_passed": 160,
        "drive/mean_speed_kmh": 45.0,
    }  # fmt: skip
    return {**s, **kw}


def test_the_bar_at_its_edges():
    assert study.meets_bar(_summary(), 50.0)  # 90 % of the checkpoints, 90 % of the speed: met
    assert not study.meets_bar(_summary(**{"drive/mean_speed_kmh": 44.9}), 50.0)
    assert not study.meets_bar(_summary(**{"drive/checkpoints_in_lane": 143}), 50.0)
    assert not study.meets_bar(_summary(**{"drive/collisions": 1}), 50.0)
    assert not study.meets_bar(_summary(**{"drive/exits": 1}), 50.0)
    assert not study.meets_bar(_summary(**{"drive/stop_lines_compliant": 79}), 50.0)  # 98.75 % < 99 %
    assert study.meets_bar(_summary(**{"drive/stop_lines_compliant": 0, "drive/stop_lines_passed": 0}), 50.0)


def test_the_recipe_rounds_and_their_time(tmp_path):
    assert study.recipe_rounds("old") == 2
    assert study.recipe_rounds("new3p") == 3 and study.recipe_rounds("new2p") == 2  # a variant's override
    for r, wall in ((1, 316.2), (2, 532.0)):
        (tmp_path / "dagger" / f"round_{r}").mkdir(parents=True)
        (tmp_path / "dagger" / f"round_{r}" / "round.json").write_text(json.dumps({"wall_s": wall}))
    (tmp_path / "dagger" / "round_3").mkdir()  # not finished: no round.json
    assert study.last_round(tmp_path, 2) == tmp_path / "dagger" / "round_2" / "runs"
    assert study.dagger_seconds(tmp_path, 1) == 316.2  # a folder run with more rounds than the recipe's
    assert study.dagger_seconds(tmp_path, 2) == 848.2
    with pytest.raises(SystemExit, match="round_3 has not finished"):
        study.last_round(tmp_path, 3)


def test_the_table_adds_up_the_times():
    row = {
        "recipe": "new", "seed": 1, "rounds": 2, "dagger_s": 480.0,
        "times": {"stage 1": 120.0, "DAgger": 490.0},
        "drive": {"expert": _summary(**{"drive/mean_speed_kmh": 50.0}), "PACNN+S": _summary(),
                  "PTACNN+S": _summary(**{"drive/collisions": 2})},
        "opd": {"PACNN+S": 0.41, "PTACNN+S": 0.4},
    }  # fmt: skip
    lines = study.table([row]).splitlines()
    assert lines[2].startswith(
        "| new | 1 | 2 | PACNN+S | 2.0 | 8.0 | 10.0 | 0 | 0 | 80/80 | 144/160 | 0.900 | 0.410 | yes | no |"
    )
    assert lines[3].endswith("| 2 | 0 | 80/80 | 144/160 | 0.900 | 0.400 | no | no |")
    row["drive"]["PACNN+S"] = _summary(**{"drive/checkpoints_in_lane": 152})  # 95 %: the recipe's own bar
    assert study.table([row]).splitlines()[2].endswith("| 152/160 | 0.900 | 0.410 | yes | yes |")


def test_a_recorded_step_is_not_run_again(tmp_path, capsys):
    times = tmp_path / "times.json"
    times.write_text('{"stage 1": 354.3}\n')
    study.run(["no-such-command"], times, "stage 1")  # would fail if it ran
    assert "finished before (354.3 s" in capsys.readouterr().out
    assert times.read_text() == '{"stage 1": 354.3}\n'


def test_the_spread_is_mean_and_range_over_seeds_with_the_ratio_to_old():
    def row(recipe, seed, stage1, dagger, lane):
        s = _summary(**{"drive/checkpoints_in_lane": lane})
        drive = {"expert": _summary(**{"drive/mean_speed_kmh": 50.0}), "PACNN+S": s, "PTACNN+S": s}
        return {
            "recipe": recipe,
            "seed": seed,
            "dagger_s": dagger,
            "times": {"stage 1": stage1},
            "drive": drive,
        }

    rows = [
        row("old", 1, 1200.0, 3000.0, 160),
        row("new", 1, 300.0, 600.0, 152),
        row("new", 2, 300.0, 900.0, 140),
    ]
    lines = study.spread(rows).splitlines()
    assert lines[0].startswith(
        "- old (1 training seeds): to a reward 70.0 (70.0-70.0) min; PACNN+S in lane 100.0"
    )
    assert lines[1].startswith("- new (2 training seeds): to a reward 17.5 (15.0-20.0) min, 4.00x faster")
    assert "PACNN+S in lane 91.2 (87.5-95.0) %, the bar met with 1 of 2" in lines[1]
