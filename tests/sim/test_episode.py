"""Episode bookkeeping on hand-made ego state sequences (no SUMO)."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim.drive.metrics import missed_by_checkpoint, missed_checkpoints
from irlsim.sim.episode import CourseMarks, Episode
from irlsim.sim.types import EgoState

MARKS = CourseMarks(
    lap_length=1000.0,
    checkpoint_s=(100.0, 600.0),
    checkpoint_lane=(2, 0),
    stop_line_s=(300.0, 800.0),
    exit_zones=((400.0, 500.0),),
    half_road=4.8,
)
DT = 0.1


def _drive(ep: Episode, s: np.ndarray, v: np.ndarray, d: float | np.ndarray = 0.0, lane: int = 1) -> None:
    d = np.broadcast_to(np.asarray(d, dtype=float), s.shape)
    for i, (si, vi, di) in enumerate(zip(s, v, d, strict=False)):
        ep.update(EgoState(i * DT, 0.0, 0.0, 0.0, float(vi), 0.0, float(si), float(di), 0.0, 0.0, lane))
        if ep.done:
            break


def _episode(**kw) -> Episode:
    return Episode(MARKS, laps=kw.pop("laps", 5), max_time=kw.pop("max_time", 1e4), stop_zone=15.0, **kw)


def test_stop_line_without_stop_is_not_compliant():
    ep = _episode()
    s = np.arange(200.0, 320.0, 1.0)
    _drive(ep, s, np.full(s.shape, 10.0))
    st = ep.stats()
    assert (st["sim/stop_lines_passed"], st["sim/stop_lines_compliant"]) == (1, 0)


def test_full_stop_before_line_is_compliant_and_moves_stop_s_on():
    ep = _episode()
    s = np.concatenate([np.arange(250.0, 295.0, 1.0), [295.0] * 5, np.arange(295.0, 310.0, 1.0)])
    v = np.where(np.diff(s, prepend=249.0) == 0, 0.0, 10.0)
    _drive(ep, s[:50], v[:50])
    assert ep.stop_s(295.0) == pytest.approx(800.0)  # stopped for 300: the next line is the target
    _drive(ep, s[50:], v[50:])
    st = ep.stats()
    assert (st["sim/stop_lines_passed"], st["sim/stop_lines_compliant"]) == (1, 1)


def test_stop_too_early_does_not_count():
    ep = _episode()
    assert ep.stop_s(250.0) == pytest.approx(300.0)
    s = np.concatenate([[250.0] * 3, np.arange(251.0, 310.0)])
    v = np.concatenate([[0.0] * 3, np.full(59, 10.0)])
    _drive(ep, s, v)
    assert ep.stats()["sim/stop_lines_compliant"] == 0


def test_laps_checkpoints_and_lane():
    ep = _episode(laps=2)
    s = np.arange(10.0, 2100.0, 2.0)
    _drive(ep, s, np.full(s.shape, 20.0), d=3.2, lane=2)
    st = ep.stats()
    assert ep.done and ep.end_reason == "laps" and st["sim/laps"] == 2
    assert st["sim/checkpoints_passed"] == 4 and st["sim/checkpoints_in_lane"] == 2  # lane 2 meets cp 0 only
    assert st["sim/mean_speed_kmh"] == pytest.approx(72.0)
    # the drive record's missed checkpoints: cp 1 (lane 0 required) in both laps, driven in lane 2
    missed = missed_checkpoints(ep.events)
    assert [(m["index"], m["lane"], m["required"]) for m in missed] == [(1, 2, 0), (1, 2, 0)]
    assert missed[0]["t"] < missed[1]["t"]
    assert missed_by_checkpoint([{"drive/checkpoints_missed": missed}] * 3) == {"1": 6}


def test_target_is_next_checkpoint_unwrapped():
    ep = _episode()
    assert ep.target(50.0) == (0, pytest.approx(100.0))
    assert ep.target(700.0) == (0, pytest.approx(1100.0))
    assert ep.target(1150.0) == (1, pytest.approx(1600.0))


def test_exit_in_ramp_zone_ends_episode_offroad_elsewhere_does_not():
    ep = _episode()
    s = np.arange(350.0, 460.0, 1.0)
    d = np.where(s > 430.0, -6.0, -3.2)
    _drive(ep, s, np.full(s.shape, 10.0), d=d, lane=0)
    assert ep.done and ep.end_reason == "exit" and ep.stats()["sim/exits"] == 1
    ep = _episode()
    s = np.arange(650.0, 700.0, 1.0)
    _drive(ep, s, np.full(s.shape, 10.0), d=-6.0, lane=-1)
    assert not ep.done and ep.stats()["sim/offroad_steps"] == len(s) - 1


def test_collision_and_timeout():
    ep = _episode()
    ep.update(EgoState(0.0, 0, 0, 0, 10.0, 0, 0.0, 0.0, 0, 0, 1))
    ep.update(EgoState(0.1, 0, 0, 0, 10.0, 0, 1.0, 0.0, 0, 0, 1), collisions=1)
    assert ep.done and ep.end_reason == "collision" and ep.stats()["sim/collisions"] == 1
    ep = _episode(max_time=1.0)
    s = np.arange(0.0, 30.0, 1.0)
    _drive(ep, s, np.full(s.shape, 10.0))
    assert ep.done and ep.end_reason == "timeout" and ep.stats()["sim/steps"] == 10


def test_laps_from_a_start_anywhere_on_the_loop():
    """Laps count from the start, not from s = 0: crossing the lap seam is no lap."""
    ep = _episode(laps=2)
    s = np.arange(900.0, 1950.0, 2.0)
    _drive(ep, s, np.full(s.shape, 20.0))
    assert ep.laps_completed == 1 and not ep.done  # 1048 m driven, the seam at 1000 crossed
    _drive(ep, np.arange(1950.0, 3000.0, 2.0), np.full(525, 20.0))
    st = ep.stats()
    assert ep.done and ep.end_reason == "laps" and st["sim/laps"] == 2
    assert st["sim/distance_m"] == pytest.approx(2000.0)  # ends at the first step with 2 laps: s = 2900
    assert st["sim/checkpoints_passed"] == 4 and st["sim/stop_lines_passed"] == 4
