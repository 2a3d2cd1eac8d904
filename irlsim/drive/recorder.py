"""The scorecard's observer: records the ego's and the other vehicles' states at every simulation step.

:class:`ScorecardObserver` follows the episode runner's observer protocol (``on_reset``, ``on_cycle``,
``on_end``) and registers itself on the simulation's per-step listeners, so the time to collision is
computed on every 0.1 s step, not only at the 0.2 s planning cycles. After the episode,
:meth:`ScorecardObserver.scorecard` turns the recording into the ``score/`` record
(:mod:`irlsim.drive.scorecard`); :meth:`ScorecardObserver.cycle_facts` gives one cycle's per-step facts
(the Gymnasium environment's ``info``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.drive import scorecard as sc
from irlsim.rollout.runner import StepListener


class ScorecardObserver(StepListener):
    """Per-step recorder of what the scorecard needs (see the module docstring)."""

    def __init__(self) -> None:
        self.sim: Any = None
        self.ego: list[tuple[float, ...]] = []  # (t, x, y, yaw, v, s, d) per step
        self.vehicles: list[np.ndarray] = []  # [m_k, 6] (x, y, yaw, v, length, width) per step
        self.exempt: list[bool] = []  # step inside an exit's ramp zone
        self._cycle_start = 0

    # ------------------------------------------------------------------ observer protocol
    def start(self, sim: Any) -> None:
        self.sim = sim
        self.ego, self.vehicles, self.exempt = [], [], []
        self._cycle_start = 0

    def on_step(self, sim: Any) -> None:
        e, veh = sim.ego, sim.vehicles
        self.ego.append((e.t, e.x, e.y, e.yaw, e.v, e.s, e.d))
        self.vehicles.append(
            np.stack([veh.x, veh.y, veh.yaw, veh.v, veh.length, veh.width], axis=1)
            if veh.count
            else np.zeros((0, 6))
        )
        self.exempt.append(sim.marks.in_exit_zone(e.s))

    # ------------------------------------------------------------------ results
    def arrays(self, start: int = 0) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Ego arrays [S] (t, x, y, yaw, v, s, d) and vehicles [S, M, 6] (NaN-padded) from step ``start``."""
        ego = np.asarray(self.ego[start:], dtype=np.float64).reshape(-1, 7)
        rows = self.vehicles[start:]
        m = max((len(r) for r in rows), default=0)
        veh = np.full((len(rows), m, 6), np.nan)
        for k, r in enumerate(rows):  # one copy per step of a ragged list; the math is vectorised
            veh[k, : len(r)] = r
        names = ("t", "x", "y", "yaw", "v", "s", "d")
        return {n: ego[:, i] for i, n in enumerate(names)}, veh

    def progress_curve(self) -> tuple[list[float], list[float]]:
        """(t, s) per step: what another model's progress against this episode needs."""
        return [r[0] for r in self.ego], [r[5] for r in self.ego]

    def scorecard(self, stats: dict[str, Any], expert: tuple[Any, Any] | None = None) -> dict[str, Any]:
        """The episode's ``score/`` record from the recording and the simulator's ``sim/`` counts."""
        ego, veh = self.arrays()
        cfg = self.sim.cfg
        return sc.episode_scorecard(
            t=ego["t"],
            x=ego["x"],
            y=ego["y"],
            yaw=ego["yaw"],
            v=ego["v"],
            s=ego["s"],
            d=ego["d"],
            vehicles=veh,
            ego_size=(cfg.ego_length, cfg.ego_width),
            half_road=float(self.sim.road.half_road),
            exempt=np.asarray(self.exempt, dtype=bool),
            collisions=int(stats["sim/collisions"]),
            exits=int(stats["sim/exits"]),
            stop_lines_passed=int(stats["sim/stop_lines_passed"]),
            stop_lines_compliant=int(stats["sim/stop_lines_compliant"]),
            checkpoints_passed=int(stats["sim/checkpoints_passed"]),
            checkpoints_in_lane=int(stats["sim/checkpoints_in_lane"]),
            expert=None if expert is None else (np.asarray(expert[0]), np.asarray(expert[1])),
            speed_limit=self.sim.road.max_speed_limit,
            red_crossings=int(stats["sim/red_crossings"]) if "sim/red_crossings" in stats else None,
            yield_violations=(
                int(stats["sim/yield_violations"]) if "sim/yield_violations" in stats else None
            ),
        )

    def cycle_facts(self, steps: int) -> dict[str, float]:
        """Per-step facts of the last ``steps`` simulation steps (one cycle): ``ttc_min`` [s] (inf: none
        within the horizon), ``ttc_ok`` (share of those steps with TTC >= 0.95 s), ``overspeed`` [m/s] (max),
        ``intrusion_m`` (max box intrusion beyond the loop's edge, exit ramps exempt), ``comfort_ok`` (share
        of those steps within all comfort bounds; derivatives over the last steps recorded)."""
        steps = max(int(steps), 1)
        start = max(len(self.ego) - steps, 0)
        ego, veh = self.arrays(start)
        cfg = self.sim.cfg
        ttc = sc.time_to_collision(
            np.stack([ego["x"], ego["y"], ego["yaw"], ego["v"]], axis=1), (cfg.ego_length, cfg.ego_width), veh
        )
        win, _ = self.arrays(max(len(self.ego) - steps - 4, 0))  # a few steps before, for the derivatives
        within = sc.comfort_within(sc.comfort_series(win["t"], win["v"], win["yaw"]))[-len(ttc) :]
        exempt = np.asarray(self.exempt[start:], dtype=bool)
        return {
            "ttc_min": float(ttc.min()) if len(ttc) else float("inf"),
            "ttc_ok": float(np.mean(ttc >= sc.TTC_BOUND)) if len(ttc) else 1.0,
            "overspeed": float(np.max(np.maximum(ego["v"] - self.sim.road.max_speed_limit, 0.0)))
            if len(ttc)
            else 0.0,
            "intrusion_m": sc.drivable_intrusion(
                ego["d"], cfg.ego_width, float(self.sim.road.half_road), exempt
            ),
            "comfort_ok": float(np.mean(within)) if len(within) else 1.0,
        }
