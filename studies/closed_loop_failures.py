"""Why a learned reward fails in closed loop: collisions, missed stops, checkpoints off lane.

A learned model drives exactly as ``irlsim drive`` without ``--safety`` does (argmax over the sampled set
of V = -theta^T f); every cycle the expert, planning from the same state on the same policy set, says what
it would have executed (DAgger's labeller, :class:`irlsim.drive.dagger.DaggerDriver`). Per cycle the
study keeps the state, the predicted theta, both policies' features and the lead vehicle, and then explains
every disagreement by feature: V(learner) - V(expert) = sum_i theta_i (f_expert,i - f_learner,i) >= 0,
so a feature with a positive term made the learner prefer its own policy, a negative one argued for the
expert's and lost.

Reports (``<out>/failures.md``, ``<out>/failures.json``, per-cycle ``<out>/cycles.npz``):

- agreement of learner and expert per situation (same lane plan; same policy);
- every collision: the last 5 s before it (speed, gap and speed of the vehicle ahead in the lane,
  learned theta's proximity weight against the expert's, the per-feature terms of the choice);
- every stop line crossed without a full stop: the last 10 s before it (speed, distance to the line, the
  slowest speed the learner's and the expert's policies plan, their stop_line features, the learned
  velocity / creep / stop_line / proximity weights, the terms of the choice);
- every checkpoint passed outside its lane: the cycles of its last 300 m in which the expert's label
  passes it in the required lane and the learner's policy does not, and the feature terms there;
- every exit taken (the ego left the course on an exit ramp): the last 10 s before it (speed, lateral
  offset, distance to the target checkpoint, the share of the set labelled exit, whether the learner's and
  the expert's policies are, their progress features, the learned progress / mission_lane / centerline /
  road_edge weights, the terms of the choice).

Run on development (validation) seeds only, never on the seeds a result is reported on:

    nice -n 5 .venv/bin/python studies/closed_loop_failures.py --runs runs/paper --model PACNN+S \\
        --config configs/collect/paper.toml --seeds 500 501 502 --laps 2 --out runs/paper/failures
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.data.situations import SITUATION_NAMES, situation_of
from irlsim.drive.dagger import DaggerDriver
from irlsim.planner import LABEL_NAMES
from irlsim.planner.expert import THETA_EXPERT, mission_lanes_away
from irlsim.reward import load_reward
from irlsim.road import load_road
from irlsim.road.scenario import Scenarios
from irlsim.rollout.runner import Cycle, EpisodeRunner, ObserverBase
from irlsim.sim.simulation import Simulation
from irlsim.utils import seed_everything

PROX = FEATURE_NAMES.index("proximity")
SL = FEATURE_NAMES.index("stop_line")
STOP_FEATURES = ("velocity", "creep", "stop_line", "proximity")
EXIT_FEATURES = ("progress", "mission_lane", "centerline", "road_edge")
PROG = FEATURE_NAMES.index("progress")
EXIT_LABEL = LABEL_NAMES.index("exit")


def lead_vehicle(obs: Any, lap: float, ego_width: float) -> tuple[float, float]:
    """(bumper gap [m], speed [m/s]) of the nearest vehicle ahead in the ego's lane (inf, nan if none)."""
    veh = obs.vehicles
    if veh.count == 0:
        return float("inf"), float("nan")
    ds = (veh.s - obs.ego.s % lap + lap / 2) % lap - lap / 2  # front bumpers, relative
    gap = ds - veh.length  # rear bumper minus the ego's front bumper (the ego's s is its front)
    same = np.abs(veh.d - obs.ego.d) < (veh.width + ego_width) / 2 + 0.3
    ok = same & (gap > -veh.length) & (gap < 200.0)
    if not ok.any():
        return float("inf"), float("nan")
    i = int(np.argmin(np.where(ok, gap, np.inf)))
    return float(gap[i]), float(veh.v[i])


class Recorder(ObserverBase):
    """Per-cycle record of the learner's and the expert's choice on the same set."""

    def __init__(self, driver: DaggerDriver, road: Any, ego_width: float):
        self.driver, self.road, self.ego_width = driver, road, ego_width
        self.rows: list[dict[str, Any]] = []

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None:
        ps, obs = cycle.policy_set, cycle.obs
        if ps is None:
            return
        li, ei = cycle.chosen, self.driver.expert_index
        theta = np.asarray(self.driver.decider.theta, dtype=np.float64)
        cp = self.road.checkpoints[obs.target_checkpoint]
        final = ps.lane[:, -1].astype(np.int64)
        away = mission_lanes_away(ps, obs.target_s, cp.lane, final)
        gap, v_lead = lead_vehicle(obs, self.road.lap_length, self.ego_width)
        self.rows.append(
            {
                "t": obs.ego.t,
                "s": obs.ego.s,
                "v": obs.ego.v,
                "lane": obs.ego.lane,
                "checkpoint": obs.target_checkpoint,
                "req_lane": cp.lane,
                "remaining": obs.target_s - obs.ego.s,
                "situation": situation_of(obs, self.road),
                "learner": li,
                "expert": ei,
                "learner_away": int(away[li]),
                "expert_away": int(away[ei]),
                "learner_lane_end": int(final[li]),
                "expert_lane_end": int(final[ei]),
                "theta": theta,
                "f_learner": ps.features[li].astype(np.float64),
                "f_expert": ps.features[ei].astype(np.float64),
                "coll_share": float(ps.labels[:, 0].mean()),
                "learner_coll": bool(ps.labels[li, 0]),
                "expert_coll": bool(ps.labels[ei, 0]),
                "d": obs.ego.d,
                "exit_share": float(ps.labels[:, EXIT_LABEL].mean()),
                "learner_exit": bool(ps.labels[li, EXIT_LABEL]),
                "expert_exit": bool(ps.labels[ei, EXIT_LABEL]),
                "exits": int(cycle.facts.get("exits") or 0),
                "lead_gap": gap,
                "lead_v": v_lead,
                "collisions": int(cycle.facts.get("collisions") or 0),
                "cp_passed": int(cycle.facts.get("checkpoints_passed") or 0),
                "cp_in_lane": int(cycle.facts.get("checkpoints_in_lane") or 0),
                "stop_rel": float(obs.stop_s - obs.ego.s) if np.isfinite(obs.stop_s) else float("inf"),
                "sl_passed": int(cycle.facts.get("stop_lines_passed") or 0),
                "sl_compliant": int(cycle.facts.get("stop_lines_compliant") or 0),
                "learner_v_min": float(ps.v[li].min()),
                "expert_v_min": float(ps.v[ei].min()),
            }
        )


def drive(model: Any, road: Any, cfg: CollectConfig, seed: int, laps: int) -> tuple[list[dict], str]:
    scenario = dataclasses.replace(cfg.scenario, laps=int(laps))
    seed_everything(seed)
    driver = DaggerDriver(model, road, cfg)
    rec = Recorder(driver, road, float(scenario.ego_width))
    with Simulation(road, scenario) as sim:
        result = EpisodeRunner(sim, observers=[rec]).run(driver, seed)
    return rec.rows, str(result.end_reason)


def terms(rows: list[dict]) -> np.ndarray:
    """[n, 15] theta_i (f_expert,i - f_learner,i): what each feature says for the learner's choice."""
    th = np.stack([r["theta"] for r in rows])
    return th * (np.stack([r["f_expert"] for r in rows]) - np.stack([r["f_learner"] for r in rows]))


def fmt_terms(t: np.ndarray, k: int = 4) -> str:
    order = np.argsort(-np.abs(t))[:k]
    return ", ".join(f"{FEATURE_NAMES[i]} {t[i]:+.1f}" for i in order)


def event(
    seed: int, rows: list[dict], i: int, back: int, fields: Any, terms_key: str = "terms", **head: Any
) -> dict[str, Any]:
    """The report of an event at cycle ``i``: its seed, time and ``head``, and per cycle of the ``back``
    cycles before it and itself ``fields(w)`` with the terms of the learner's choice under ``terms_key``."""
    window = rows[max(0, i - back) : i + 1]
    tm = terms(window)
    cycles = [fields(w) | {terms_key: fmt_terms(tm[j])} for j, w in enumerate(window)]
    return {"seed": seed, "t": rows[i]["t"], **head, "cycles": cycles}


def _weights(w: dict, names: tuple[str, ...]) -> dict[str, float]:
    return {n: float(w["theta"][FEATURE_NAMES.index(n)]) for n in names}


def collision_cycle(w: dict) -> dict[str, Any]:
    return {
        "t": w["t"],
        "v": w["v"],
        "lead_gap": w["lead_gap"],
        "lead_v": w["lead_v"],
        "situation": SITUATION_NAMES[w["situation"]],
        "same_policy": w["learner"] == w["expert"],
        "theta_prox": float(w["theta"][PROX]),
        "coll_share": w["coll_share"],
        "learner_coll": w["learner_coll"],
        "prox_learner": float(w["f_learner"][PROX]),
        "prox_expert": float(w["f_expert"][PROX]),
    }


def stop_cycle(w: dict) -> dict[str, Any]:
    return {
        "t": w["t"],
        "v": w["v"],
        "stop_rel": w["stop_rel"],
        "lead_gap": w["lead_gap"],
        "lead_v": w["lead_v"],
        "same_policy": w["learner"] == w["expert"],
        "v_min": (w["learner_v_min"], w["expert_v_min"]),
        "stop_line": (float(w["f_learner"][SL]), float(w["f_expert"][SL])),
        "theta": _weights(w, STOP_FEATURES),
    }


def exit_cycle(w: dict) -> dict[str, Any]:
    return {
        "t": w["t"],
        "v": w["v"],
        "d": w["d"],
        "remaining": w["remaining"],
        "same_policy": w["learner"] == w["expert"],
        "exit_share": w["exit_share"],
        "exit": (w["learner_exit"], w["expert_exit"]),
        "progress": (float(w["f_learner"][PROG]), float(w["f_expert"][PROG])),
        "theta": _weights(w, EXIT_FEATURES),
    }


def analyse(episodes: dict[int, tuple[list[dict], str]], cycle_s: float) -> dict[str, Any]:
    out: dict[str, Any] = {"agreement": {}, "collisions": [], "misses": [], "stops": [], "exits": []}
    allrows = [r for rows, _ in episodes.values() for r in rows]
    sit = np.array([r["situation"] for r in allrows])
    same_policy = np.array([r["learner"] == r["expert"] for r in allrows])
    same_plan = np.array(
        [
            r["learner_lane_end"] == r["expert_lane_end"] and r["learner_away"] == r["expert_away"]
            for r in allrows
        ]
    )
    for k, name in enumerate(SITUATION_NAMES):
        m = sit == k
        if m.any():
            out["agreement"][name] = {
                "cycles": int(m.sum()),
                "same_policy": float(same_policy[m].mean()),
                "same_lane_plan": float(same_plan[m].mean()),
            }
    n_back = int(round(5.0 / cycle_s))
    for seed, (rows, _end) in episodes.items():
        for i, r in enumerate(rows):
            if r["collisions"]:
                situation = SITUATION_NAMES[r["situation"]]
                out["collisions"].append(
                    event(seed, rows, i, n_back, collision_cycle, "v_learner_end_terms", situation=situation)
                )
            if r["sl_passed"] > r["sl_compliant"]:
                out["stops"].append(event(seed, rows, i, 2 * n_back, stop_cycle))
            if r["exits"]:
                out["exits"].append(event(seed, rows, i, 2 * n_back, exit_cycle, s=r["s"]))
            if r["cp_passed"] and not r["cp_in_lane"]:
                cp = rows[max(i - 1, 0)]["checkpoint"]
                before = [w for w in rows[: i + 1] if w["checkpoint"] == cp and 0 <= w["remaining"] <= 300.0]
                dis = [w for w in before if w["expert_away"] == 0 and w["learner_away"] > 0]
                tm = terms(dis) if dis else np.zeros((0, len(FEATURE_NAMES)))
                out["misses"].append(
                    {
                        "seed": seed,
                        "t": r["t"],
                        "checkpoint": int(cp),
                        "req_lane": int(rows[max(i - 1, 0)]["req_lane"]),
                        "lane": int(r["lane"]),
                        "cycles_last_300m": len(before),
                        "expert_in_lane_learner_not": len(dis),
                        "mean_terms": {FEATURE_NAMES[j]: float(tm[:, j].mean()) for j in range(tm.shape[1])}
                        if len(dis)
                        else {},
                        "theta_mission_learner": float(np.mean([w["theta"][9] for w in before]))
                        if before
                        else float("nan"),
                        "situations": sorted({SITUATION_NAMES[w["situation"]] for w in dis}),
                    }
                )
    return out


def markdown(res: dict[str, Any], model: str, ends: dict[int, str]) -> str:
    lines = [
        f"# Closed-loop failures of {model}",
        "",
        "episodes: " + ", ".join(f"{s} {e}" for s, e in ends.items()),
    ]
    lines += ["", "| situation | cycles | same policy | same lane plan |", "|---|---|---|---|"]
    for name, a in res["agreement"].items():
        lines.append(f"| {name} | {a['cycles']} | {a['same_policy']:.2f} | {a['same_lane_plan']:.2f} |")
    for c in res["collisions"]:
        lines += ["", f"## collision seed {c['seed']} t = {c['t']:.1f} s ({c['situation']})", ""]
        lines += [
            "| t | v | lead gap | lead v | situation | same | share of set labelled collision | "
            "learner's labelled | theta_prox (expert 30) | prox learner / expert | "
            "terms for the learner's choice |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for w in c["cycles"]:
            lines.append(
                f"| {w['t']:.1f} | {w['v']:.1f} | {w['lead_gap']:.1f} | {w['lead_v']:.1f} | "
                f"{w['situation']} | {'y' if w['same_policy'] else 'n'} | {w['coll_share']:.2f} | "
                f"{'y' if w['learner_coll'] else 'n'} | "
                f"{w['theta_prox']:.2f} | {w['prox_learner']:.2f} / "
                f"{w['prox_expert']:.2f} | {w['v_learner_end_terms']} |"
            )
    for c in res["stops"]:
        lines += ["", f"## stop line crossed without a full stop, seed {c['seed']} t = {c['t']:.1f} s", ""]
        lines += [
            "| t | v | to line | lead gap | lead v | same | min v over horizon learner / expert | "
            "stop_line f learner / expert | theta velocity, creep, stop_line, proximity | terms |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for w in c["cycles"]:
            th = w["theta"]
            lines.append(
                f"| {w['t']:.1f} | {w['v']:.2f} | {w['stop_rel']:.1f} | {w['lead_gap']:.1f} | "
                f"{w['lead_v']:.1f} | "
                f"{'y' if w['same_policy'] else 'n'} | {w['v_min'][0]:.2f} / {w['v_min'][1]:.2f} | "
                f"{w['stop_line'][0]:.2f} / {w['stop_line'][1]:.2f} | "
                + ", ".join(f"{th[n]:.2f}" for n in STOP_FEATURES)
                + f" | {w['terms']} |"
            )
    for c in res["exits"]:
        lines += ["", f"## exit taken, seed {c['seed']} t = {c['t']:.1f} s, s = {c['s']:.0f} m", ""]
        lines += [
            "| t | v | d | to checkpoint | same | share of set labelled exit | exit learner / expert | "
            "progress f learner / expert | theta " + ", ".join(EXIT_FEATURES) + " | terms |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for w in c["cycles"]:
            th = w["theta"]
            lines.append(
                f"| {w['t']:.1f} | {w['v']:.1f} | {w['d']:.2f} | {w['remaining']:.0f} | "
                f"{'y' if w['same_policy'] else 'n'} | {w['exit_share']:.2f} | "
                + " / ".join("y" if e else "n" for e in w["exit"])
                + f" | {w['progress'][0]:.0f} / {w['progress'][1]:.0f} | "
                + ", ".join(f"{th[n]:.3g}" for n in EXIT_FEATURES)
                + f" | {w['terms']} |"
            )
    if res["misses"]:
        lines += ["", "## checkpoints missed in their lane", ""]
        lines += [
            "| seed | t | cp | lane / required | cycles last 300 m | expert in lane, learner not | "
            "mean terms (top 4) | learner theta mission (expert 10) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for m in res["misses"]:
            mt = np.array([m["mean_terms"].get(n, 0.0) for n in FEATURE_NAMES])
            lines.append(
                f"| {m['seed']} | {m['t']:.1f} | {m['checkpoint']} | {m['lane']} / {m['req_lane']} | "
                f"{m['cycles_last_300m']} | {m['expert_in_lane_learner_not']} | "
                f"{fmt_terms(mt) if m['mean_terms'] else '-'} | {m['theta_mission_learner']:.2f} |"
            )
    return "\n".join(lines) + "\n"


def data_side(data: str, split: str, model: Any, shares: tuple[float, ...], max_theta: int) -> str:
    """How often the training data shows states like the collision states: cycles by the share of their
    policy set labelled collision (a vehicle so close that most policies hit it) and by situation, with
    the demonstrations there and the model's theta_prox on (up to ``max_theta`` of) them."""
    from irlsim.data.reader import open_dataset

    ds = open_dataset(data)
    t = ds.split_tensors(split)
    cyc = ds.read_cycles(split)
    assert len(cyc) == t.n_cycles
    share = np.asarray(t.labels[:, :, 0]).mean(axis=1)
    sit = cyc["situation"].to_numpy()
    demo = t.has_demo
    lines = [
        f"## The {split} split of {data}: {t.n_cycles} cycles, {int(demo.sum())} with a demonstration",
        "",
        "| share of the set labelled collision | cycles | with a demo | by situation (demo cycles) | "
        "demo labelled collision | ego v [m/s] (mean) | theta_prox (mean, min) |",
        "|---|---|---|---|---|---|---|",
    ]
    edges = (0.0, *shares, 1.01)
    rng = np.random.default_rng(0)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        m = (share >= lo) & (share < hi) if lo > 0 else share < hi
        md = m & demo
        idx = np.flatnonzero(md)
        by = ", ".join(
            f"{SITUATION_NAMES[k]} {int((sit[md] == k).sum())}"
            for k in range(len(SITUATION_NAMES))
            if (sit[md] == k).any()
        )
        dcol = int(np.asarray(t.labels[idx, t.demo_index[idx], 0]).sum()) if len(idx) else 0
        v = cyc["ego_v"].to_numpy()[md]
        pick = idx if len(idx) <= max_theta else np.sort(rng.choice(idx, max_theta, replace=False))
        th = (
            np.array([model.predict(t.features[i], t.control_points[i], t.actions[i])[PROX] for i in pick])
            if len(pick)
            else np.zeros(0)
        )
        lines.append(
            f"| [{lo:.2f}, {min(hi, 1.0):.2f}) | {int(m.sum())} | {int(md.sum())} | {by or '-'} | {dcol} | "
            f"{v.mean() if len(v) else float('nan'):.1f} | "
            + (f"{th.mean():.2f}, {th.min():.2f} (n={len(th)})" if len(th) else "-")
            + " |"
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", required=True)
    p.add_argument("--model", required=True)
    p.add_argument("--config", required=True, help="the collect TOML the model was trained with")
    p.add_argument("--seeds", type=int, nargs="+", required=True, help="development seeds (never test seeds)")
    p.add_argument("--laps", type=int, default=2)
    p.add_argument("--out", required=True)
    p.add_argument("--data", help="also count collision-like states in this dataset's --split")
    p.add_argument("--split", default="train")
    p.add_argument("--max-theta", type=int, default=300, help="cycles per bucket the model predicts theta on")
    args = p.parse_args()
    scenarios = Scenarios()  # the config's road (the oval unless it names another), its file read once
    cfg = load_config(CollectConfig, args.config, scenarios=scenarios)
    road = load_road(scenario=scenarios(cfg.scenario.name))
    model = load_reward(args.model, args.runs, n_policies=cfg.planner.n_policies)
    episodes: dict[int, tuple[list[dict], str]] = {}
    for seed in args.seeds:
        rows, end = drive(model, road, cfg, seed, args.laps)
        episodes[seed] = (rows, end)
        print(f"seed {seed}: {len(rows)} cycles, end {end}", flush=True)
    res = analyse(episodes, float(cfg.scenario.cycle))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ends = {s: e for s, (_, e) in episodes.items()}
    (out / "failures.json").write_text(
        json.dumps({"model": args.model, "ends": ends, **res}, indent=1, default=float)
    )
    (out / "failures.md").write_text(markdown(res, args.model, ends))
    allrows = [dict(r, seed=s) for s, (rows, _) in episodes.items() for r in rows]
    np.savez_compressed(
        out / "cycles.npz",
        **{k: np.array([r[k] for r in allrows]) for k in allrows[0] if k not in ()},
        theta_expert=THETA_EXPERT,
    )
    if args.data:
        text = data_side(args.data, args.split, model, (0.25, 0.5, 0.75, 0.9), args.max_theta)
        (out / "data.md").write_text(text)
        print(text)
    print(f"wrote {out}/failures.md, failures.json, cycles.npz" + (", data.md" if args.data else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
