r"""Where a driver's lane changes come from: how many return to the lane they left, and how soon.

For each dataset given (its episodes' cycles, every 0.2 s: the lane the ego was in): the lane changes per
km; the returning visits (a visit to a lane between two visits of the same other lane), how long they
last; the lane changes per km with returning visits of at most 1 s and at most 5 s not counted
(:func:`irlsim.rollout.style.lane_changes`); and the same driving cut to whole-second rows (every 5th
cycle, averaged over the five phases): how much of the count depends on the rate it is read at. Then, by
situation label (:mod:`irlsim.data.situations`), the share of cycles and the share of them whose lane 5 s
later is another. And the longitudinal jerk over 1 s (the style's base, from the cycles' speeds) within 2 s of
a lane change and elsewhere: how much of a driver's jerk its lane changes carry. Reads datasets only:

    .venv/bin/python studies/style_lane_returns.py runs/styles-dev/reference-s2000/assertive/oval \
        runs/styles-dev/reference-s2000/cautious/oval runs/styles-dev/data/expert/oval

``--probe CONFIG --seed S``: drive one episode of CONFIG's SUMO demonstrator and print, for its first
lane changes, SUMO's own lane and its reason for the change (``getLaneChangeStatePretty``) beside
irlsim's lane (from the ego's offset to its route), step by step:

    .venv/bin/python studies/style_lane_returns.py --probe configs/collect/styles/assertive.toml \
        --seed 2000000000 --cycles 150

With ``--episodes K`` the probe drives K episodes (seeds from ``--seed`` on) and counts, over them, the
lane changes and quick returns that follow an insertion or removal of a vehicle by irlsim's spawner within
1 s, against the share of the steps such windows cover: are the returns the spawner's?
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

from irlsim.data.situations import SITUATION_NAMES
from irlsim.rollout.style import lane_changes, lane_visits

CYCLE = 0.2  # [s] a planning cycle: the cycles table's row spacing
EVERY_SECOND = 5  # cycles per second
AHEAD = 25  # cycles: 5 s
NEAR = 10  # cycles: 2 s
SECOND_STEPS = 10  # simulation steps (0.1 s): 1 s


def figures(folder: Path) -> dict[str, Any]:
    """The dataset's lane-change figures (see the module docstring)."""
    km, counts, returns = 0.0, {"every": 0, "1 s": 0, "5 s": 0, "every, 1 s rows": 0.0}, []
    pairs: list[tuple[int, int]] = []
    for f in sorted(folder.glob("*/episode_*.cycles.parquet")):
        t = pq.read_table(f, columns=["ego_lane", "ego_v"]).to_pandas()
        lane, v = t["ego_lane"].to_numpy(), t["ego_v"].to_numpy()
        km += float(v.sum()) * CYCLE / 1000.0
        counts["every"] += lane_changes(lane, CYCLE)
        counts["1 s"] += lane_changes(lane, CYCLE, 1.0)
        counts["5 s"] += lane_changes(lane, CYCLE, 5.0)
        counts["every, 1 s rows"] += np.mean([lane_changes(lane[p::EVERY_SECOND], 1.0) for p in range(5)])
        which, length = lane_visits(lane)
        back = np.flatnonzero(which[:-2] == which[2:]) + 1
        returns += (length[back] * CYCLE).tolist()
        pairs += [tuple(sorted((int(which[i - 1]), int(which[i])))) for i in back.tolist()]
    if km <= 0:
        sys.exit(f"style_lane_returns: {folder} has no driven cycles (give a dataset folder)")
    r = np.array(returns)
    top = max(set(pairs), key=pairs.count) if pairs else None
    return {
        "lanes": f"{top[0]}-{top[1]} ({pairs.count(top) / len(pairs):.2f})" if top else "-",
        "per km": {k: n / km for k, n in counts.items()},
        "returns": len(r),
        "return s (10/50/90 %)": np.percentile(r, [10, 50, 90]) if len(r) else np.full(3, np.nan),
        "returns <= 1 s": float(np.mean(r <= 1.0)) if len(r) else 0.0,
        "km": km,
    }


def by_situation(folder: Path) -> dict[str, tuple[float, float]]:
    """Per situation label: (share of the cycles, share of them whose lane 5 s later is another)."""
    sit, moved = [], []
    for f in sorted(folder.glob("*/episode_*.cycles.parquet")):
        t = pq.read_table(f, columns=["ego_lane", "situation"]).to_pandas()
        lane = t["ego_lane"].to_numpy()
        if len(lane) > AHEAD:
            sit.append(t["situation"].to_numpy()[:-AHEAD])
            moved.append(lane[AHEAD:] != lane[:-AHEAD])
    s, m = np.concatenate(sit), np.concatenate(moved)
    return {
        name: (float(np.mean(s == code)), float(np.mean(m[s == code])))
        for code, name in enumerate(SITUATION_NAMES)
        if np.any(s == code)
    }


def situations_table(folders: list[Path]) -> str:
    lines = ["| dataset | " + " | ".join(SITUATION_NAMES) + " |", "|---" * (len(SITUATION_NAMES) + 1) + "|"]
    for folder in folders:
        got = by_situation(folder)
        cells = [f"{got[n][0]:.3f}: {got[n][1]:.2f}" if n in got else "-" for n in SITUATION_NAMES]
        lines.append(f"| {folder} | " + " | ".join(cells) + " |")
    return "share of the cycles: share of them in another lane 5 s later\n" + "\n".join(lines)


def jerk_near_changes(folder: Path) -> dict[str, float]:
    """The share of the time within ``NEAR`` cycles of a lane change, the share of the squared jerk
    (over 1 s) there, and the RMS jerk there and elsewhere [m/s^3]."""
    near_j, far_j = [], []
    for f in sorted(folder.glob("*/episode_*.cycles.parquet")):
        t = pq.read_table(f, columns=["ego_lane", "ego_v"]).to_pandas()
        lane, v = t["ego_lane"].to_numpy(), t["ego_v"].to_numpy()
        if len(v) <= 4 * EVERY_SECOND:
            continue
        acc = v[EVERY_SECOND:] - v[:-EVERY_SECOND]  # [m/s^2]: the mean over each second
        jerk = acc[EVERY_SECOND:] - acc[:-EVERY_SECOND]  # [m/s^3]: its change over a second
        changes = np.flatnonzero(lane[1:] != lane[:-1]) + 1
        near = np.zeros(len(v), dtype=np.int64)  # a window of +-NEAR cycles around every change
        np.add.at(near, np.clip(changes - NEAR, 0, len(v) - 1), 1)
        np.add.at(near, np.clip(changes + NEAR, 0, len(v) - 1), -1)
        mask = np.cumsum(near)[EVERY_SECOND : len(v) - EVERY_SECOND] > 0  # centred on each jerk's span
        near_j.append(jerk[mask])
        far_j.append(jerk[~mask])
    jn, jf = np.concatenate(near_j), np.concatenate(far_j)
    total = float(np.sum(jn**2) + np.sum(jf**2))
    rms = lambda j: float(np.sqrt(np.mean(j**2))) if len(j) else float("nan")  # noqa: E731
    return {
        "time": len(jn) / max(len(jn) + len(jf), 1),
        "jerk^2": float(np.sum(jn**2)) / total if total > 0 else 0.0,
        "near": rms(jn),
        "elsewhere": rms(jf),
    }


def jerk_table(folders: list[Path]) -> str:
    lines = [
        "| dataset | time within 2 s of a lane change | its share of the squared jerk | RMS jerk there / "
        "elsewhere [m/s^3] |",
        "|---|---|---|---|",
    ]
    for folder in folders:
        j = jerk_near_changes(folder)
        lines.append(
            f"| {folder} | {j['time']:.2f} | {j['jerk^2']:.2f} | {j['near']:.2f} / {j['elsewhere']:.2f} |"
        )
    return "\n".join(lines)


def table(folders: list[Path]) -> str:
    lines = [
        "| dataset | km | lane changes per km: every / returns <= 1 s not counted / <= 5 s not counted "
        "| every, from 1 s rows | returning visits | their length 10/50/90 % [s] | <= 1 s "
        "| the lanes most returned between (share) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for folder in folders:
        f = figures(folder)
        pk, q = f["per km"], f["return s (10/50/90 %)"]
        lines.append(
            f"| {folder} | {f['km']:.1f} | {pk['every']:.2f} / {pk['1 s']:.2f} / {pk['5 s']:.2f} "
            f"| {pk['every, 1 s rows']:.2f} | {f['returns']} | {q[0]:.1f} / {q[1]:.1f} / {q[2]:.1f} "
            f"| {f['returns <= 1 s']:.2f} | {f['lanes']} |"
        )
    return "\n".join(lines)


def probe(config: str, seed: int, cycles: int, shown: int, episodes: int = 1) -> None:
    """``episodes`` episodes of the config's SUMO demonstrator from ``seed`` on; the first one's first
    ``shown`` lane changes step by step, then over all of them how many quick returns (back to the lane
    left within 1 s) follow an insertion or removal of a vehicle by irlsim's spawner within 1 s."""
    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig
    from irlsim.data.demonstrator import SUMO, SumoDemonstrator, demonstrator_simulation
    from irlsim.road import load_road
    from irlsim.rollout import EpisodeRunner
    from irlsim.rollout.runner import StepListener
    from irlsim.sim.simulation import EGO
    from irlsim.utils import seed_everything

    cfg = load_config(CollectConfig, config)
    if cfg.demonstrator.kind != SUMO:
        sys.exit(f"style_lane_returns: --probe needs a config with a SUMO demonstrator, not {config}")

    class Probe(StepListener):
        def __init__(self, rows: list[tuple[Any, ...]]) -> None:
            self.rows = rows

        def on_step(self, sim: Any) -> None:
            api = sim._api  # the simulation's libsumo: SUMO's own view of the ego
            left, right = (api.vehicle.getLaneChangeStatePretty(EGO, side)[0] for side in (1, -1))
            lane_id, ids = api.vehicle.getLaneID(EGO), frozenset(api.vehicle.getIDList())
            self.rows.append(
                (sim.ego.t, sim.ego.lane, api.vehicle.getLaneIndex(EGO), lane_id, left, right, ids)
            )

    road = load_road(scenario=cfg.scenario.name)
    counts = np.zeros(5, dtype=np.int64)  # lane changes, after an event; quick returns, after one; steps
    covered = 0
    for ep in range(episodes):
        rows: list[tuple[Any, ...]] = []
        seed_everything(seed + ep)
        driver = SumoDemonstrator(road, cfg.planner, cfg.scenario)
        with demonstrator_simulation(road, cfg.scenario, cfg.demonstrator) as sim:
            EpisodeRunner(sim, observers=[Probe(rows)], max_cycles=cycles).run(driver, seed + ep)
        ours = np.array([r[1] for r in rows])
        sumo = np.array([r[2] for r in rows])
        if ep == 0:
            print(
                f"{len(rows)} steps: irlsim's lane changes {lane_changes(ours, 0.1)}, SUMO's lane index "
                f"changes {lane_changes(sumo, 0.1)}, steps where they differ {int(np.sum(ours != sumo))}"
            )
            for k in (np.flatnonzero(ours[1:] != ours[:-1]) + 1)[:shown]:
                for t, lane, index, lane_id, left, right, _ in rows[k - 1 : k + 1]:
                    print(
                        f"  t {t:6.1f} s  irlsim lane {lane}  SUMO {lane_id} ({index})  to the left: "
                        f"{','.join(left) or '-'}  to the right: {','.join(right) or '-'}"
                    )
                print("  --")
        event = np.array([False] + [rows[k][6] != rows[k - 1][6] for k in range(1, len(rows))])
        recent = np.convolve(event, np.ones(SECOND_STEPS + 1))[: len(event)] > 0  # one within the last 1 s
        ch = np.flatnonzero(sumo[1:] != sumo[:-1]) + 1
        quick = [
            a
            for a, b in zip(ch[:-1], ch[1:], strict=True)
            if b - a <= SECOND_STEPS and sumo[b] == sumo[a - 1]
        ]
        counts += [
            len(ch),
            int(recent[ch - 1].sum()),
            len(quick),
            int(sum(recent[a - 1] for a in quick)),
            len(sumo),
        ]
        covered += int(recent.sum())
    n, n_ev, q, q_ev, steps = counts.tolist()
    print(
        f"{episodes} episode(s): {n} lane changes, {n_ev / max(n, 1):.2f} of them within 1 s after the "
        f"spawner inserted or removed a vehicle; {q} quick returns (to the lane left within 1 s), "
        f"{q_ev / max(q, 1):.2f} of them after such an event; such 1 s windows cover "
        f"{covered / max(steps, 1):.2f} of the steps"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("data", nargs="*", type=Path, help="dataset folders (irlsim collect --out)")
    p.add_argument("--probe", help="a collect config with a SUMO demonstrator: drive one episode")
    p.add_argument("--seed", type=int, default=2_000_000_000, help="the probe's episode seed")
    p.add_argument("--cycles", type=int, default=150, help="the probe's planning cycles")
    p.add_argument("--shown", type=int, default=10, help="lane changes the probe prints")
    p.add_argument("--episodes", type=int, default=1, help="the probe's episodes (seeds from --seed on)")
    a = p.parse_args(argv)
    if not a.data and not a.probe:
        p.error("give dataset folders, or --probe CONFIG")
    if a.data:
        print(table(a.data))
        print(situations_table(a.data))
        print(jerk_table(a.data))
    if a.probe:
        probe(a.probe, a.seed, a.cycles, a.shown, a.episodes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
