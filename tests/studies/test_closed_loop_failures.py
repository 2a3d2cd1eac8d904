"""The failure study's bookkeeping (pure logic on hand-made per-cycle rows): which cycles a report keeps."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from irlsim import FEATURE_NAMES

_spec = importlib.util.spec_from_file_location(
    "closed_loop_failures", Path(__file__).parents[2] / "studies" / "closed_loop_failures.py"
)
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)  # type: ignore[union-attr]

N = len(FEATURE_NAMES)


def _row(k: int, **kw):
    """Cycle k at t = 0.5 k s; learner and expert agree, nothing happens, unless ``kw`` says otherwise."""
    r = {
        "t": 0.5 * k, "s": 10.0 * k, "v": 20.0, "lane": 1, "checkpoint": 0, "req_lane": 1,
        "remaining": 1000.0 - 10.0 * k, "situation": 0, "learner": 3, "expert": 3, "learner_away": 0,
        "expert_away": 0, "learner_lane_end": 1, "expert_lane_end": 1, "theta": np.ones(N),
        "f_learner": np.zeros(N), "f_expert": np.zeros(N), "coll_share": 0.0, "learner_coll": False,
        "expert_coll": False, "d": 0.0, "exit_share": 0.0, "learner_exit": False, "expert_exit": False,
        "exits": 0, "lead_gap": float("inf"), "lead_v": float("nan"), "collisions": 0, "cp_passed": 0,
        "cp_in_lane": 0, "stop_rel": float("inf"), "sl_passed": 0, "sl_compliant": 0,
        "learner_v_min": 20.0, "expert_v_min": 20.0,
    }  # fmt: skip
    r.update(kw)
    return r


def test_an_exit_is_reported_with_its_last_ten_seconds():
    f_exit = np.zeros(N)
    f_exit[study.PROG] = 5.0  # the learner's exit policy: less progress cost (the ramp's capped distance)
    f_stay = np.zeros(N)
    f_stay[study.PROG] = 9.0
    rows = [_row(k) for k in range(30)]
    for k in range(24, 30):  # the learner heads onto the ramp, the expert stays
        rows[k].update(
            learner=7, expert=3, learner_exit=True, exit_share=0.25, d=-0.5 * (k - 23),
            f_learner=f_exit, f_expert=f_stay,
        )  # fmt: skip
    rows[29]["exits"] = 1
    res = study.analyse({7: (rows, "exit")}, cycle_s=0.5)
    assert not res["collisions"] and not res["stops"] and not res["misses"]
    (ex,) = res["exits"]
    assert ex["seed"] == 7 and ex["t"] == 14.5 and ex["s"] == 290.0
    cyc = ex["cycles"]
    assert len(cyc) == 21  # 10 s at 0.5 s per cycle, and the exit cycle itself
    assert [c["t"] for c in cyc] == [0.5 * k for k in range(9, 30)]
    assert all(c["same_policy"] for c in cyc[:15]) and not any(c["same_policy"] for c in cyc[15:])
    assert cyc[-1]["exit"] == (True, False) and cyc[-1]["progress"] == (5.0, 9.0)
    assert cyc[-1]["d"] == -3.0 and cyc[-1]["theta"]["progress"] == 1.0
    # theta_progress (f_expert - f_learner) = +4 argued for the learner's exit
    assert cyc[-1]["terms"].startswith("progress +4.0")
    md = study.markdown(res, "PACNN+S", {7: "exit"})
    assert "## exit taken, seed 7 t = 14.5 s, s = 290 m" in md
    assert md.count("| 14.5 | 20.0 | -3.00 |") == 1


def test_exit_window_is_cut_at_the_episode_start():
    rows = [_row(k) for k in range(4)]
    rows[3]["exits"] = 1
    (ex,) = study.analyse({1: (rows, "exit")}, cycle_s=0.5)["exits"]
    assert len(ex["cycles"]) == 4
