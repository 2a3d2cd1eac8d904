r"""Trace a recording drive's side collision step by step: where the ego and the other car were, in the
route frame and in SUMO's lanes, in the seconds before it.

Drives one held-out car of a studies/style_recording.py sample again (``--sumo-seed``'s recording, or
``--cars FIRST LAST`` of the study's own; car index ``--episode`` of its drive config), the recording's
PACNN+S reward of ``--seed`` with the same rules (``--full-stop --keep-distance H``, with ``--in-lane``
in the reward's lane; the others driven by SUMO), and prints every 0.2 s of the last
``--seconds`` before the first collision: the ego's lateral offset d [m] (lane centres at -3.2, 0 and
3.2), speed and SUMO lane; the other car's SUMO lane, lane position, speed and lane-change state:

    .venv/bin/python studies/style_side_collision.py --out runs/styles --sumo-seed 3 --seed 1 \
        --episode 13 --other car34 --headway 0.3
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.drive.closed_loop import _simulation
from irlsim.reward import RewardDriver, load_reward
from irlsim.road import load_road
from irlsim.rollout.runner import EpisodeRunner

EVAL_SEED = 1_000_000_000  # studies/styles.py's evaluation base: episode i has seed EVAL_SEED + i


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run with the recording")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--sumo-seed", type=int, help="the recording sample's SUMO seed")
    which.add_argument("--cars", type=int, nargs=2, metavar=("FIRST", "LAST"), help="the study's own cars")
    p.add_argument("--seed", type=int, required=True, help="the reward's training seed")
    p.add_argument("--episode", type=int, required=True, help="the held-out car's index in the sample")
    p.add_argument("--other", required=True, help="the other car's recorded id, e.g. car34")
    p.add_argument("--headway", type=float, default=0.8, help="--keep-distance's headway [s]")
    p.add_argument("--in-lane", action="store_true", help="--keep-distance in the reward's lane")
    p.add_argument("--seconds", type=float, default=3.0, help="how long before the collision to print")
    a = p.parse_args(argv)
    out = Path(a.out)
    config = (
        out / f"recording-s{a.sumo_seed}" / "drive.toml"
        if a.sumo_seed is not None
        else out / "recording" / f"drive-c{a.cars[0]}-{a.cars[1]}.toml"
    )
    runs = out / "runs" / f"recording-seed{a.seed}"
    if not config.is_file() or not runs.is_dir():
        sys.exit(f"style_side_collision: {config} or {runs} is missing: run studies/style_recording.py first")
    cfg = load_config(CollectConfig, config)
    road, _, sim = _simulation(cfg, load_road(scenario=cfg.scenario.name), 2, a.episode, True)
    reward = load_reward("PACNN+S", runs, n_policies=cfg.planner.n_policies)
    rules = {"full_stop": True, "keep_distance": a.headway, "in_lane": a.in_lane}
    driver = RewardDriver(reward, road, cfg.planner, choice="argmax", **rules)
    rows: list[dict[str, Any]] = []
    other = "rec/" + a.other

    def on_step(s: Any) -> None:
        api = s._api.vehicle
        here = set(api.getIDList())
        row = {
            "t": s.ego.t,
            "d": s.ego.d,
            "v": s.ego.v,
            "lane": api.getLaneIndex("ego") if "ego" in here else -1,
        }
        if other in here:
            row |= {"o_lane": api.getLaneIndex(other), "o_pos": api.getLanePosition(other)}
            row |= {"o_v": api.getSpeed(other), "o_change": api.getLaneChangeState(other, 1)[0]}
            row["pos"] = api.getLanePosition("ego") if "ego" in here else float("nan")
        rows.append(row)

    sim.step_listeners.append(on_step)
    with sim:
        result = EpisodeRunner(sim, observers=[], max_cycles=800).run(driver, EVAL_SEED + a.episode)
    hit = sim.first_collision
    print(f"end: {result.end_reason}; first collision: {hit}")
    t_end = hit["t"] if hit else rows[-1]["t"]
    for r in rows:
        if t_end - a.seconds <= r["t"] <= t_end + 1e-6 and round(r["t"] * 10) % 2 == 0:
            ego = f"t {r['t']:5.1f} s  ego: d {r['d']:+5.2f} m, {r['v']:5.2f} m/s, SUMO lane {r['lane']}"
            o = r.get("o_lane")
            print(
                ego
                + (
                    f"  {a.other}: SUMO lane {o}, {r['o_pos'] - r['pos']:+6.2f} m from the ego, "
                    f"{r['o_v']:5.2f} m/s, lane-change state {r['o_change']}"
                    if o is not None
                    else ""
                )
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
