"""``irlsim bench --growth``: the quick run writes every curve with a finite slope; bad arguments are one
line before any work; the fit reads slopes right. No timing is asserted (the machine may be loaded)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from irlsim.bench.growth import planner_observations, straight_road
from irlsim.bench.growth_report import fit_curve, growth_word
from irlsim.cli import main

CURVES = {
    "planner_policies",
    "planner_vehicles",
    "planner_lanes",
    "collect_workers",
    "collect_workers_started",
    "disk_parquet",
    "disk_cache",
    "train_cycles",
    "train_policies",
    "memory_cycles",
    "memory_policies",
    "infer_policies",
}


def test_quick_growth_writes_every_curve_with_a_finite_slope(tmp_path, capsys):
    out = tmp_path / "growth"
    assert main(["bench", "--growth", "--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "growth [1/" in printed and f"wrote {out / 'growth.json'}" in printed  # progress, then where

    result = json.loads((out / "growth.json").read_text())
    assert set(result["curves"]) == CURVES
    for name, curve in result["curves"].items():
        assert len(curve["x"]) == len(curve["y"]) >= 2, name
        assert all(math.isfinite(y) and y > 0 for y in curve["y"]), (name, curve["y"])
        assert math.isfinite(curve["fit"]["loglog_slope"]), (name, curve["fit"])
        assert curve["fit"]["growth"] != "unknown"

    table = (out / "growth.md").read_text()
    rows = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line][1:]
    assert len(rows) == len(CURVES)
    for row in rows:
        slope = row.split("|")[4].strip()
        assert math.isfinite(float(slope)), row
    assert (out / "growth.png").stat().st_size > 0
    assert all((out / f"growth_{name}.png").is_file() for name in CURVES)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--quick"], "--quick goes with --growth"),
        (["--growth", "--planner"], "drop --planner"),
        (["--growth", "--quick", "--scenario", "nowhere"], "scenario 'nowhere' not found"),
        (["--growth", "--quick", "--out", "{file}"], "is a file"),
    ],
)
def test_bad_arguments_are_one_line_before_any_work(tmp_path, capsys, argv, needle):
    (tmp_path / "afile").write_text("x")
    argv = [a.replace("{file}", str(tmp_path / "afile")) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["bench", *argv]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert "growth [" not in captured.out  # no point was measured
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_bad_seed_is_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as e:
        main(["bench", "--growth", "--quick", "--seed", "-1"])
    assert e.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_the_fit_reads_linear_quadratic_and_affine_growth():
    x = [100.0, 200.0, 400.0, 800.0]
    linear = fit_curve(x, [2 * v for v in x])
    assert linear["loglog_slope"] == pytest.approx(1.0) and linear["growth"] == "linear"
    assert linear["per_unit"] == pytest.approx(2.0) and linear["affine_r2"] == pytest.approx(1.0)
    square = fit_curve(x, [v * v for v in x])
    assert square["loglog_slope"] == pytest.approx(2.0) and square["growth"] == "super-linear"
    # a large fixed part: sub-linear over the range, the last step closer to 1
    affine = fit_curve(x, [1000 + v for v in x])
    assert affine["growth"] == "sub-linear"
    assert affine["loglog_slope"] < affine["last_step_slope"] < 1.0
    assert affine["fixed"] == pytest.approx(1000.0)
    # a size of 0 is left out of the log-log fit, kept in the affine one
    with_zero = fit_curve([0.0, *x], [5.0, *[5.0 + v for v in x]])
    assert math.isfinite(with_zero["loglog_slope"]) and with_zero["fixed"] == pytest.approx(5.0)
    assert growth_word(0.0) == "flat" and growth_word(-1.0) == "falls" and growth_word(math.nan) == "unknown"


def test_generated_roads_have_their_lane_count_and_cycles_any_vehicle_count(tmp_path):
    from irlsim.road import load_road

    for lanes in (1, 4):
        path = straight_road(tmp_path / f"l{lanes}", lanes)
        assert load_road(scenario=path).n_lanes == lanes
    for m in (0, 60):
        obs = planner_observations(0, n_obs=2, n_vehicles=m)
        assert all(len(o.vehicles.s) == m for o in obs)
        assert np.isfinite(obs[0].vehicles.s).all()
