"""Episode bookkeeping over the ego's state sequence: laps, checkpoints, stop lines, exits, end.

Pure logic (no SUMO), so it is unit-testable with hand-made :class:`EgoState` sequences. Positions are
the ego's front bumper in the route frame; ``s`` is unwrapped (it keeps growing over laps).

A marker at wrapped position m (checkpoint, stop line) is *passed* when the front bumper gets strictly
beyond it: the count ``ceil((s - m) / lap)`` increases. A stop counts for a stop line when the ego's
speed is below ``stop_speed`` with its front bumper at most ``stop_zone`` metres before the line (the
line itself included); the line is *compliant* when such a stop happened since the ego last passed it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from irlsim.road import Road
from irlsim.sim.types import EgoState

#: why an episode ended, by priority when several happen in the same step
END_REASONS = ("collision", "exit", "laps", "route_end", "timeout")


@dataclass(frozen=True)
class CourseMarks:
    """What the bookkeeping needs from the road, as plain numbers (build with :meth:`from_road`)."""

    lap_length: float  # [m]
    checkpoint_s: tuple[float, ...]  # [m] wrapped
    checkpoint_lane: tuple[int, ...]  # required lane of each checkpoint
    stop_line_s: tuple[float, ...]  # [m] wrapped
    exit_zones: tuple[tuple[float, float], ...]  # [m] wrapped (start, end) of each exit's ramp zone
    half_road: float  # [m] |d| of the road's edges
    route_end_s: float = math.inf  # [m] an open route's end (wrapped); inf for a loop
    signal_s: tuple[float, ...] = ()  # [m] wrapped: the traffic lights' stop lines
    #: per checkpoint, the lanes that meet it where several do (the lanes the route goes on from)
    checkpoint_lanes: tuple[tuple[int, ...], ...] = ()
    yield_s: tuple[float, ...] = ()  # [m] wrapped: the yield points' lines (minor links)

    @staticmethod
    def from_road(road: Road) -> CourseMarks:
        return CourseMarks(
            lap_length=float(road.lap_length),
            checkpoint_s=tuple(float(c.s) for c in road.checkpoints),
            checkpoint_lane=tuple(int(c.lane) for c in road.checkpoints),
            stop_line_s=tuple(float(sl.s) for sl in road.stop_lines),
            exit_zones=tuple((float(e.ramp_s[0]), float(e.ramp_s[-1])) for e in road.exits),
            half_road=float(road.half_road),
            route_end_s=float(road.route_end_s),
            signal_s=tuple(float(g.s) for g in road.signals),
            checkpoint_lanes=tuple(c.lanes for c in road.checkpoints),
            yield_s=tuple(float(p.s) for p in road.yield_points),
        )

    def passes(self, s: float, m: float) -> int:
        """How many times a front bumper at unwrapped s has got strictly beyond marker m."""
        return math.ceil((s - m) / self.lap_length)

    def ahead(self, s: float, m: float) -> float:
        """Distance [m] from unwrapped s forward to the next occurrence of marker m, in [0, lap)."""
        return (m - s) % self.lap_length

    def in_exit_zone(self, s: float) -> bool:
        for a, b in self.exit_zones:
            if (s - a) % self.lap_length <= (b - a):
                return True
        return False


@dataclass
class Episode:
    """Bookkeeping of one episode; feed it every simulation step's ego state with :meth:`update`."""

    marks: CourseMarks
    laps: int
    max_time: float  # [s]
    stop_speed: float = 0.1  # [m/s]
    stop_zone: float = 15.0  # [m]
    exit_margin: float = 0.0  # [m]
    end_on_collision: bool = True
    start: EgoState | None = None
    last: EgoState | None = None
    done: bool = False
    end_reason: str | None = None
    counts: dict[str, int] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    _stopped: list[bool] = field(default_factory=list)
    _speed_sum: float = 0.0
    _steps: int = 0

    def __post_init__(self) -> None:
        self._stopped = [False] * len(self.marks.stop_line_s)
        for k in (
            "collisions",
            "sumo_collisions",
            "exits",
            "stop_lines_passed",
            "stop_lines_compliant",
            "checkpoints_passed",
            "checkpoints_in_lane",
            "teleports",
            "offroad_steps",
        ):
            self.counts.setdefault(k, 0)

    # ------------------------------------------------------------------ queries for the observation
    def target(self, s: float) -> tuple[int, float]:
        """(index, unwrapped position [m]) of the next checkpoint strictly ahead of s: the route target."""
        dist = [self.marks.ahead(s, m) or self.marks.lap_length for m in self.marks.checkpoint_s]
        i = int(np.argmin(dist))
        return i, s + dist[i]

    def stop_s(self, s: float) -> float:
        """Unwrapped position [m] of the next stop line at or ahead of s the ego has not stopped for yet
        (inf if it has stopped for all). A line the ego stands at (distance 0) is still ahead."""
        best = math.inf
        for i, m in enumerate(self.marks.stop_line_s):
            if not self._stopped[i]:
                best = min(best, s + self.marks.ahead(s, m))
        return best

    # ------------------------------------------------------------------ the update
    def update(
        self,
        ego: EgoState,
        *,
        collisions: int = 0,
        sumo_collisions: int = 0,
        teleports: int = 0,
        red: tuple[bool, ...] = (),
        yield_violations: int = 0,
    ) -> None:
        """Account for one step ending in state ``ego``; ``collisions`` = new ego collisions this step;
        ``red``: per traffic light, whether the route's link shows red (a crossing then is a failure);
        ``yield_violations``: conflict areas of minor links entered this step ahead of a foe with
        priority (:mod:`irlsim.sim.yielding`)."""
        if self.start is None:
            self.start = self.last = ego
            self._note_stop(ego)
            return
        if self.done:
            return
        prev = self.last
        assert prev is not None
        self._steps += 1
        self._speed_sum += ego.v
        c = self.counts
        c["teleports"] += teleports
        c["sumo_collisions"] += sumo_collisions
        for i, (m, lane) in enumerate(zip(self.marks.checkpoint_s, self.marks.checkpoint_lane, strict=False)):
            for _ in range(self.marks.passes(ego.s, m) - self.marks.passes(prev.s, m)):
                c["checkpoints_passed"] += 1
                lanes = self.marks.checkpoint_lanes[i] if i < len(self.marks.checkpoint_lanes) else ()
                met = ego.lane in lanes if lanes else (ego.lane == lane or lane < 0 <= ego.lane)
                c["checkpoints_in_lane"] += int(met)
                self.events.append(
                    {"t": ego.t, "kind": "checkpoint", "index": i, "lane": ego.lane, "required": lane}
                    | {"met": bool(met)}
                )
        for i, m in enumerate(self.marks.stop_line_s):
            for _ in range(self.marks.passes(ego.s, m) - self.marks.passes(prev.s, m)):
                c["stop_lines_passed"] += 1
                c["stop_lines_compliant"] += int(self._stopped[i])
                self.events.append({"t": ego.t, "kind": "stop_line", "index": i, "stopped": self._stopped[i]})
                self._stopped[i] = False
        for i, m in enumerate(self.marks.signal_s):
            for _ in range(self.marks.passes(ego.s, m) - self.marks.passes(prev.s, m)):
                c["signals_passed"] = c.get("signals_passed", 0) + 1
                on_red = bool(red[i]) if i < len(red) else False
                c["red_crossings"] = c.get("red_crossings", 0) + int(on_red)
                self.events.append({"t": ego.t, "kind": "signal", "index": i, "red": on_red})
        for m in self.marks.yield_s:
            c["yields_passed"] = (
                c.get("yields_passed", 0) + self.marks.passes(ego.s, m) - self.marks.passes(prev.s, m)
            )
        if yield_violations:
            c["yield_violations"] = c.get("yield_violations", 0) + yield_violations
            self.events.append({"t": ego.t, "kind": "yield_violation", "count": yield_violations})
        self._note_stop(ego)
        in_zone = self.marks.in_exit_zone(ego.s)
        took_exit = in_zone and ego.d < -(self.marks.half_road + self.exit_margin)
        if not in_zone and abs(ego.d) > self.marks.half_road:
            c["offroad_steps"] += 1
        if took_exit:
            c["exits"] += 1
            self.events.append({"t": ego.t, "kind": "exit", "s": ego.s})
        if collisions:
            c["collisions"] += collisions
            self.events.append({"t": ego.t, "kind": "collision", "count": collisions})
        self.last = ego
        reasons = {
            "collision": bool(collisions) and self.end_on_collision,
            "exit": took_exit,
            "laps": self.laps_completed >= self.laps,
            "route_end": ego.s >= self.marks.route_end_s,
            "timeout": ego.t - self.start.t >= self.max_time - 1e-9,
        }
        for r in END_REASONS:
            if reasons[r]:
                self.done, self.end_reason = True, r
                break

    def _note_stop(self, ego: EgoState) -> None:
        if ego.v >= self.stop_speed:
            return
        for i, m in enumerate(self.marks.stop_line_s):
            if self.marks.ahead(ego.s, m) <= self.stop_zone:
                self._stopped[i] = True

    # ------------------------------------------------------------------ figures
    @property
    def laps_completed(self) -> int:
        if self.start is None or self.last is None:
            return 0
        return int(math.floor((self.last.s - self.start.s) / self.marks.lap_length + 1e-9))

    @property
    def steps(self) -> int:
        return self._steps

    def stats(self) -> dict[str, Any]:
        """Figures of the episode so far; keys namespaced ``sim/`` (plus ``end_reason``)."""
        c = self.counts
        dist = 0.0 if self.start is None or self.last is None else self.last.s - self.start.s
        dur = 0.0 if self.start is None or self.last is None else self.last.t - self.start.t
        return (
            {
                "sim/laps": self.laps_completed,
                "sim/distance_m": round(dist, 3),
                "sim/time_s": round(dur, 3),
                "sim/steps": self._steps,
                "sim/collisions": c["collisions"],
                "sim/sumo_collisions": c["sumo_collisions"],
                "sim/exits": c["exits"],
                "sim/stop_lines_passed": c["stop_lines_passed"],
                "sim/stop_lines_compliant": c["stop_lines_compliant"],
                "sim/checkpoints_passed": c["checkpoints_passed"],
                "sim/checkpoints_in_lane": c["checkpoints_in_lane"],
                "sim/offroad_steps": c["offroad_steps"],
                "sim/mean_speed_kmh": round(3.6 * self._speed_sum / self._steps, 3) if self._steps else 0.0,
                # 0 by construction: SUMO runs with --time-to-teleport -1 (mandatory, or a standing ego is
                # teleported), so this only catches that option going missing; blocked background traffic
                # shows in sim/bg_stuck instead
                "sim/teleports": c["teleports"],
                "end_reason": self.end_reason,
            }
            | (  # only on roads with traffic lights: the oval's figures keep their bytes
                {
                    "sim/signals_passed": c.get("signals_passed", 0),
                    "sim/red_crossings": c.get("red_crossings", 0),
                }
                if self.marks.signal_s
                else {}
            )
            | (  # only on routes with yield points (minor links); the violations also at minor greens
                {"sim/yields_passed": c.get("yields_passed", 0)} if self.marks.yield_s else {}
            )
            | (
                {"sim/yield_violations": c.get("yield_violations", 0)}
                if self.marks.yield_s or self.marks.signal_s
                else {}
            )
        )
