r"""What a SUMO driver's demonstrations drive when taken exactly, every cycle: the projection oracle.

Every planning cycle the simulation is saved, SUMO's driver (the demonstrator's vType) drives the
planner's horizon from the ego's state and the state is loaded back (:mod:`irlsim.sim.branch`, DAgger's
SUMO labeller); the ego then executes the policy that odometry projects onto (the demonstration,
:meth:`~irlsim.data.demos.DemoProjector.project_window`; a lane change SUMO makes within one step by
:func:`~irlsim.data.demos.lane_jump_projection`; the nearest policy where none lies within the
projection's distance; the expert's choice where the look ahead is cut short, at the route's end). So
the ego drives as a reward would that had learned the driver perfectly and chose its demonstration
every cycle: the driver imitated cycle by cycle as the planner can, with no learning in between. It is
not a bound on the style distance (a reward may reach a figure, a mean speed, by other policies than
the demonstrations), but where the oracle lands nearer another driver than its own, what the
demonstrations teach, taken exactly, does not drive like the driver. ``--rules commit full-stop``: the
oracle chooses as a learned reward does under ``irlsim drive --commit --full-stop``
(:func:`irlsim.planner.expert.choose_index` with the nearness to the driver's odometry as the value: the
demonstration where the rules allow it, else the nearest policy they allow); the folders and the table
are then named ``-commit-stop``.

Reads a ``studies/styles.py`` run (the references of ``--demonstrators`` on ``--eval-base``'s episodes),
drives the oracle of ``--driver`` on the same episodes (each road's episode seeds, as the references'
collection) into ``<out>/oracle[-s<base>][-commit-stop]/<driver>/<road>/`` and writes the table (the
style distance as defined and pooled, ``studies/style_norms.py``'s, with the safety bounds; how each
cycle's policy was found; the chosen policy's progress against the look ahead's after the first cycle and
after 2 s, where the look ahead brakes, holds or accelerates) to
``<out>/style-oracle[-s<base>][-commit-stop]-<driver>.md`` and ``.json``:

    .venv/bin/python studies/style_oracle.py --out runs/styles --eval-base 2000 --episodes 30 \
        --demonstrators expert cautious assertive --driver assertive --workers 2 --rules commit full-stop
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import style_norms  # noqa: E402
import styles  # noqa: E402  (studies/styles.py: the study's folders, configs and commands)

from irlsim.config import load_config  # noqa: E402
from irlsim.data.collection import CollectConfig, EpisodeJob, collect_episode, demo_projector  # noqa: E402
from irlsim.data.demos import lane_jump_projection, look_ahead_odometry  # noqa: E402
from irlsim.errors import IrlsimError  # noqa: E402
from irlsim.planner.expert import THETA_EXPERT, ExpertDriver, choose_index, within_braking_curve  # noqa: E402
from irlsim.planner.policy_set import PolicySet  # noqa: E402
from irlsim.road import Road  # noqa: E402
from irlsim.road.scenario import Scenarios  # noqa: E402
from irlsim.rollout import EpisodeResult, ObserverBase  # noqa: E402
from irlsim.rollout.style import pool_styles, style_distances, style_spread  # noqa: E402
from irlsim.sim.collision import collision_line  # noqa: E402
from irlsim.sim.simulation import Simulation  # noqa: E402
from irlsim.sim.types import Observation, Trajectory  # noqa: E402

#: how a cycle's policy was found: the demonstration; the nearest policy the rules allow, the rules having
#: left the demonstration out or no policy lying within the projection's distance; the expert's choice
CYCLE_KINDS = ("demonstration", "ruled_out", "beyond", "expert")
#: [m/s^2] the look ahead's acceleration over the first cycle beyond which the cycle counts as braking or
#: accelerating (the chosen policy's progress against the look ahead's is summed by those kinds)
LEAD_ACCEL = 0.5
#: the steps (0.1 s) after which the progress is compared: the first cycle (driven) and 2 s
GAP_STEPS = (2, 20)
GAP_KINDS = ("braking", "steady", "accelerating")


class OracleDriver:
    """Executes, every cycle, SUMO's driver's look ahead projected onto the cycle's policy set (the
    module docstring); a :class:`~irlsim.data.recorder.LabelledDriver`, so collection records the same
    projection as the cycle's demonstration."""

    look_ahead_by: Any = None  # set by collect_episode: the simulation's look ahead at its lanes' centres
    lane_offset_by: Any = None  # and what it took off the look ahead's offsets

    def __init__(self, road: Road, cfg: CollectConfig, rules: tuple[str, ...] = ()):
        self.commit, self.full_stop = "commit" in rules, "full-stop" in rules
        self.heading: int | None = None  # as ThetaDriver: a lane change under way (commit)
        self.stopping = False  # the last policy chosen comes to a stand (commit)
        self.expert = ExpertDriver(road, cfg.planner)  # the fallback where the look ahead is cut short
        self.planner, self.road = self.expert.planner, road
        self.horizon_steps, self.step = cfg.scenario.horizon_steps, cfg.scenario.step  # the policies' grid
        self.projector = demo_projector(road, cfg)  # collection's, which records the same labels
        self.last_policy_set: PolicySet | None = None
        self.last_index, self.expert_index = -1, -1
        self.look_ahead: list[tuple[float, float, float, float]] | None = None
        self.look_ahead_offset = 0.0
        #: cycles driven by the demonstration itself, by the nearest policy the rules allow (the rules
        #: left the demonstration out; no policy within the projection's distance) and by the expert
        #: (the look ahead cut short)
        self.counts = dict.fromkeys(CYCLE_KINDS, 0)
        #: by what the look ahead does over the first cycle: cycles, and the chosen policy's progress minus
        #: the look ahead's [m] summed after each of GAP_STEPS
        self.gaps = {k: [0, 0.0, 0.0] for k in GAP_KINDS}

    def plan(self, obs: Observation) -> Trajectory:
        ps = self.planner.plan(obs)
        e, ahead = obs.ego, self.look_ahead_by(self.horizon_steps)
        off = self.lane_offset_by()  # what the look ahead took off, for the lane-jump projection
        seen = look_ahead_odometry(e, ahead)  # as DaggerDriver
        demo = self.projector.project_window(0, ps.t, (ps.s, ps.d, ps.yaw), seen)
        seen_d = np.array([r[2] for r in seen])
        demo = lane_jump_projection(demo, ps.d[:, -1], seen_d, self.road.lane_width, off)
        if not np.isfinite(demo.distances).any():
            idx, how = self.expert.select(ps, obs), "expert"
        else:
            idx = self.choose(ps, obs, demo.distances, demo.demo_index)
            found = demo.demo_index >= 0
            how = "demonstration" if idx == demo.demo_index else "ruled_out" if found else "beyond"
        self.counts[how] += 1
        if len(seen) > GAP_STEPS[1]:
            self._gap(ps, idx, seen, e.v)
        self.expert.follow(ps, idx)
        self.look_ahead, self.look_ahead_offset, self.last_policy_set, self.last_index = seen, off, ps, idx
        return self.planner.trajectory(idx)

    def _gap(self, ps: PolicySet, idx: int, seen: list[tuple[float, float, float, float]], v: float) -> None:
        """The chosen policy's progress against the look ahead's after GAP_STEPS, summed by what the look
        ahead does over the first cycle (its mean speed there against the ego's speed now)."""
        one = GAP_STEPS[0]
        a = ((seen[one][1] - seen[0][1]) / (one * self.step) - v) / (one * self.step / 2)
        gap = self.gaps["braking" if a < -LEAD_ACCEL else "accelerating" if a > LEAD_ACCEL else "steady"]
        gap[0] += 1
        for i, k in enumerate(GAP_STEPS, start=1):
            gap[i] += float(ps.s[idx, k] - ps.s[idx, 0]) - (seen[k][1] - seen[0][1])

    def choose(self, ps: PolicySet, obs: Observation, distances: np.ndarray, demo: int) -> int:
        """The demonstration, else the nearest policy, among those the rules allow (ThetaDriver's)."""
        value = -np.where(np.isfinite(distances), distances, 1e9)
        if demo >= 0:
            value[demo] = 1.0  # the label first, wherever it lies (a lane jump's)
        if self.heading is not None and int(ps.lane[0, 0]) == self.heading:
            self.heading = None  # arrived
        braking = within_braking_curve(ps, obs.stop_s, self.planner.cfg) if self.full_stop else None
        stopping = self.stopping or self.full_stop
        idx = choose_index(
            ps, THETA_EXPERT, heading=self.heading, stopping=stopping, braking=braking, value=value
        )
        if self.commit:
            start, end = int(ps.lane[idx, 0]), int(ps.lane[idx, -1])
            self.heading = end if end >= 0 and end != start else None
            self.stopping = bool(ps.v[idx].min() < self.planner.cfg.v_stopped)
        return idx


class _FirstCollision(ObserverBase):
    """Keeps the episode's first collision (:func:`irlsim.sim.collision.first_collision`'s record)."""

    record: dict[str, Any] | None = None

    def on_end(self, sim: Simulation, result: EpisodeResult) -> None:
        self.record = sim.first_collision


def episode(job: EpisodeJob, rules: tuple[str, ...] = ()) -> dict[str, Any]:
    """One oracle episode (in a worker process); its figures, with how each cycle's policy was found
    and the first collision."""
    drivers: list[OracleDriver] = []

    def make(road: Road, cfg: CollectConfig) -> OracleDriver:
        drivers.append(OracleDriver(road, cfg, rules))
        return drivers[-1]

    first = _FirstCollision()
    stats = collect_episode(job, make_driver=make, observers=[first])
    counts = {f"oracle/{k}": v for k, v in drivers[0].counts.items()}
    return {**stats, **counts, "oracle/gaps": drivers[0].gaps, "oracle/first_collision": first.record}


def jobs(a: Any, road: str, folder: Path) -> list[EpisodeJob]:
    """The references' episodes of ``road`` (styles.py's reference collection: the same seeds)."""
    sets = {
        "seed": a.eval_base,
        "train_episodes": a.episodes,
        "validation_episodes": 0,
        "test_episodes": 0,
        "max_cycles": a.max_cycles,
        "scenario.laps": a.laps,
        "scenario.name": road,
        **a.planner_sets,
    }
    cfg = load_config(CollectConfig, styles.CONFIGS[a.driver], sets, scenarios=Scenarios())
    return [EpisodeJob(str(folder), "train", i, seed, cfg) for i, seed in cfg.episodes("train")]


def road_table(out: Path, road: str, stats: list[dict[str, Any]], a: Any) -> dict[str, Any]:
    eps = {d: style_norms.reference_episodes(out, d, road, a.at) for d in a.demonstrators}
    refs = {d: pool_styles(e) for d, e in eps.items()}
    n_lanes = max(len(r["style/lane_share"]) for r in refs.values())
    spread = style_spread([e for v in eps.values() for e in v], n_lanes)
    row = pool_styles([s for s in stats if s.get("style/time_s", 0) > 0])
    per_ep = style_norms.episode_distances(row, list(refs.values()), spread)
    pooled = style_distances([row, *refs.values()])[0, 1:]
    counts = {k: int(sum(s[f"oracle/{k}"] for s in stats)) for k in CYCLE_KINDS}
    sums = {k: np.sum([s["oracle/gaps"][k] for s in stats], axis=0) for k in GAP_KINDS}
    gaps = {
        k: {"cycles": int(g[0]), "first_cycle_m": g[1] / max(g[0], 1), "two_s_m": g[2] / max(g[0], 1)}
        for k, g in sums.items()
    }
    keys = ["mean_speed", "headway_median_s", "headway_p10_s", "lane_changes_per_km", "rms_accel", "rms_jerk"]
    figures = {n: {k: row[f"style/{k}"] for k in keys} for n, row in [("oracle", row), *refs.items()]}
    return {
        "as_defined": dict(zip(refs, map(float, pooled), strict=True)),
        "per_episode": dict(zip(refs, map(float, per_ep), strict=True)),
        "bounds": styles.collected_bounds(a.folder(road)),
        "cycles": counts,
        "gaps": gaps,
        "collisions": [s["oracle/first_collision"] for s in stats if s["oracle/first_collision"]],
        "figures": figures,
        "lane_share": {n: list(r["style/lane_share"]) for n, r in [("oracle", row), *refs.items()]},
    }


def markdown(tables: dict[str, dict[str, Any]], driver: str) -> str:
    lines: list[str] = []
    for road, t in tables.items():
        cols = list(t["as_defined"])
        head = ["road", *(f"{c} (pooled)" for c in cols), *(f"{c} (as defined)" for c in cols)]
        head += ["collisions", "stops", "cycles: demonstration / ruled out / beyond the distance / expert"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] if not lines else []
        cells = [road]
        for kind in ("as_defined", "per_episode"):
            near = min(t[kind], key=t[kind].get)
            cells += [f"**{v:.3f}**" if c == near else f"{v:.3f}" for c, v in t[kind].items()]
        b, c = t["bounds"], t["cycles"]
        cells += [str(b["collisions"]), f"{b['stops'][0]}/{b['stops'][1]}"]
        cells.append(" / ".join(str(c[k]) for k in CYCLE_KINDS))
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", f"Figures (the oracle of {driver} and the references, pooled):", ""]
    keys = list(next(iter(tables.values()))["figures"]["oracle"])
    lines += ["| road | driving | " + " | ".join(keys) + " | lane shares |", "|" + "---|" * (len(keys) + 3)]
    for road, t in tables.items():
        for n, f in t["figures"].items():
            shares = " / ".join(f"{x:.2f}" for x in t["lane_share"][n])
            lines.append(f"| {road} | {n} | " + " | ".join(f"{f[k]:.2f}" for k in keys) + f" | {shares} |")
    lines += [
        "",
        "The chosen policy's progress minus the look ahead's [m], after the first cycle / after 2 s, by "
        "what the look ahead does over the first cycle (cycles):",
        "",
    ]
    for road, t in tables.items():
        g = t["gaps"]
        cells = [
            f"{k} ({g[k]['cycles']}) {g[k]['first_cycle_m']:+.3f} / {g[k]['two_s_m']:+.2f}" for k in GAP_KINDS
        ]
        lines.append(f"- {road}: " + "; ".join(cells))
    return "\n".join(lines) + "\n"


def table_paths(out: Path, tag: str, driver: str) -> tuple[Path, Path]:
    """(json, md) of an oracle's table: its seeds', rules' and --planner fields' ``tag``, then the driver.
    The suffix is appended, never put with ``with_suffix``: a --planner value's dot is not a suffix."""
    name = f"style-oracle{tag}-{driver}"
    return out / f"{name}.json", out / f"{name}.md"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run's folder")
    p.add_argument("--roads", nargs="+", default=[styles.DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument("--driver", default="assertive", help="the SUMO driver the oracle follows")
    p.add_argument("--episodes", type=int, default=20, help="episodes per road (the references')")
    p.add_argument("--eval-base", type=int, default=styles.EVAL_BASE, help="the episodes' seed base")
    p.add_argument("--laps", type=int, default=2)
    p.add_argument("--max-cycles", type=int, default=800)
    p.add_argument("--workers", type=int, default=1, help="episodes driven in parallel")
    p.add_argument(
        "--rules", nargs="*", choices=["commit", "full-stop"], default=[], help="the planner's rules"
    )
    p.add_argument(
        "--planner",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="the oracle's planner fields instead of the driver's config's (lon_split=1.0): a policy set "
        "tried before any dataset uses it; named in the outputs' names",
    )
    a = p.parse_args(argv)
    try:
        a.planner_sets = {f"planner.{k}": float(v) for k, v in (f.split("=", 1) for f in a.planner)}
    except ValueError:
        sys.exit(f"style_oracle: --planner takes FIELD=NUMBER pairs, got {' '.join(a.planner)}")
    if len(set(a.demonstrators)) < len(a.demonstrators):
        sys.exit(f"style_oracle: --demonstrators names a driver twice: {' '.join(a.demonstrators)}")
    if a.driver not in a.demonstrators or a.driver not in styles.CONFIGS or a.driver == "expert":
        sys.exit(f"style_oracle: --driver must be a SUMO driver among --demonstrators, got {a.driver}")
    try:  # a bad --planner field in one line, before any episode
        load_config(CollectConfig, styles.CONFIGS[a.driver], a.planner_sets, scenarios=Scenarios())
    except IrlsimError as e:
        sys.exit(f"style_oracle: {e}")
    out = Path(a.out)
    a.at = "" if a.eval_base == styles.EVAL_BASE else f"-s{a.eval_base}"
    tag = styles.drive_tag(commit="commit" in a.rules, stop="full-stop" in a.rules)
    tag += "".join(f"-{f}" for f in a.planner)
    a.folder = lambda road: out / f"oracle{a.at}{tag}" / a.driver / road
    missing = [r for r in a.roads if not (out / f"drive{a.at}" / r / "expert" / "drive.json").is_file()]
    if missing:
        sys.exit(f"style_oracle: no references in {out} on {missing[0]} for these seeds: run styles.py first")
    tables = {}
    with ProcessPoolExecutor(a.workers, mp_context=get_context("spawn")) as pool:
        for road in a.roads:
            todo = jobs(a, road, a.folder(road))
            stats = []
            for k, s in enumerate(pool.map(episode, todo, [tuple(a.rules)] * len(todo))):
                n, hit = s["collect/cycles"], s["oracle/first_collision"]
                what = f", {collision_line(hit)}" if hit else ""
                print(f"{road} episode {k}: {n} cycles{what}", flush=True)
                stats.append(s)
            tables[road] = road_table(out, road, stats, a)
    js, md = table_paths(out, a.at + tag, a.driver)
    js.write_text(json.dumps(tables, indent=1) + "\n")
    md.write_text(markdown(tables, a.driver))
    print(markdown(tables, a.driver) + f"wrote {md} and {js}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
