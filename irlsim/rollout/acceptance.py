"""Does the expert drive a scenario? It and SUMO's own driver model drive the same seeds (the same
route, start and traffic draws) and the bar is checked: no collision, no exit off the route, no
crossing on red, a full stop at every stop sign, most of the mission in lane, and a mean speed near
the one SUMO's driver reaches (``irlsim scenario check``, the scenario tests)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.road import load_road
from irlsim.road.scenario import Scenario, Scenarios
from irlsim.rollout.drivers import make_driver
from irlsim.rollout.runner import EpisodeRunner
from irlsim.sim.config import EpisodeConfig, scenario_config
from irlsim.sim.simulation import Simulation

#: the bar (shares of all episodes' events)
MISSION_MIN = 0.95  # checkpoints passed in the required lane
SPEED_TOLERANCE = 0.15  # |expert mean speed / SUMO driver's - 1|


@dataclass(frozen=True)
class Acceptance:
    """Both drivers' figures over the same seeds, and whether the expert meets the bar."""

    scenario: str
    seeds: tuple[int, ...]
    expert: dict[str, float]
    sumo: dict[str, float]

    @property
    def speed_ratio(self) -> float:
        return self.expert["mean_speed_kmh"] / max(self.sumo["mean_speed_kmh"], 1e-9)

    @property
    def failures(self) -> list[str]:
        """What of the bar the expert misses (empty: it meets every bound)."""
        e = self.expert
        out = [f"{k} {int(e[k])}" for k in FAILURE_COUNTS if e[k] > 0]
        if e["stops_compliant"] < e["stops_passed"]:
            out.append(f"stops {int(e['stops_compliant'])}/{int(e['stops_passed'])}")
        if e["checkpoints_passed"] and e["checkpoints_in_lane"] < MISSION_MIN * e["checkpoints_passed"]:
            out.append(f"mission {int(e['checkpoints_in_lane'])}/{int(e['checkpoints_passed'])}")
        if abs(self.speed_ratio - 1.0) > SPEED_TOLERANCE:
            out.append(f"speed {self.speed_ratio:.2f} of SUMO's driver")
        return out

    def row(self) -> str:
        e, s = self.expert, self.sumo
        verdict = "meets the bar" if not self.failures else "MISSES: " + ", ".join(self.failures)
        return (
            f"{self.scenario:10s} {len(self.seeds):3d} {int(e['collisions']):4d} {int(e['exits']):4d} "
            f"{int(e['red_crossings']):4d} {int(e['yield_violations']):5d} "
            f"{int(e['stops_compliant']):3d}/{int(e['stops_passed']):<3d} "
            f"{int(e['checkpoints_in_lane']):3d}/{int(e['checkpoints_passed']):<3d} "
            f"{e['mean_speed_kmh']:6.1f} {s['mean_speed_kmh']:6.1f} {self.speed_ratio:5.2f}  {verdict}"
        )


#: the expert's counts of which any is a failure
FAILURE_COUNTS = ("collisions", "exits", "red_crossings", "yield_violations")
HEADER = "scenario  eps coll exit  red yield stops  mission  km/h  sumo  ratio"


def drive_seeds(
    scenario: str | Path | Scenario,
    driver: str,
    seeds: tuple[int, ...],
    cfg: EpisodeConfig,
    on_episode: Callable[[], None] | None = None,
) -> dict[str, float]:
    """Sums over ``seeds`` of one driver's episodes on ``scenario`` (a loaded Scenario, a shipped name or
    a path; mean speed over all of them); ``on_episode`` is called after each episode (a progress bar)."""
    road = load_road(scenario=scenario)
    totals = dict.fromkeys(
        (
            "collisions",
            "exits",
            "red_crossings",
            "yield_violations",
            "stops_passed",
            "stops_compliant",
            "checkpoints_passed",
            "checkpoints_in_lane",
        ),
        0.0,
    )
    speed, steps = 0.0, 0
    with Simulation(road, cfg) as sim:
        runner = EpisodeRunner(sim)
        drv = make_driver(driver, road, cfg)
        for seed in seeds:
            st: dict[str, Any] = runner.run(drv, seed).stats
            for key, stat in (
                ("collisions", "sim/collisions"),
                ("exits", "sim/exits"),
                ("red_crossings", "sim/red_crossings"),
                ("yield_violations", "sim/yield_violations"),
                ("stops_passed", "sim/stop_lines_passed"),
                ("stops_compliant", "sim/stop_lines_compliant"),
                ("checkpoints_passed", "sim/checkpoints_passed"),
                ("checkpoints_in_lane", "sim/checkpoints_in_lane"),
            ):
                totals[key] += float(st.get(stat, 0))
            speed += float(st["sim/mean_speed_kmh"]) * int(st["sim/steps"])
            steps += int(st["sim/steps"])
            if on_episode is not None:
                on_episode()
    totals["mean_speed_kmh"] = speed / max(steps, 1)
    return totals


def check_scenario(
    scenario: str,
    seeds: tuple[int, ...],
    cfg: EpisodeConfig | None = None,
    on_episode: Callable[[], None] | None = None,
    road: Scenario | None = None,
) -> Acceptance:
    """The expert and SUMO's driver on ``seeds`` of ``scenario`` (a loop: 2 laps each); ``on_episode``
    is called after each of the 2 x len(seeds) episodes. ``road``: the scenario as the command read it
    (None: read here, once)."""
    scenarios = Scenarios(*([road] if road is not None else []))
    found = scenarios(scenario)
    base = cfg or scenario_config(scenario, scenarios)
    cfg = dataclasses.replace(base, name=scenario, laps=min(base.laps, 2))
    return Acceptance(
        scenario,
        tuple(seeds),
        drive_seeds(found, "expert", seeds, cfg, on_episode),
        drive_seeds(found, "sumo", seeds, cfg, on_episode),
    )
