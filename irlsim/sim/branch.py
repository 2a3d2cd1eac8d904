"""A look ahead with SUMO's driver at the ego's wheel: DAgger's SUMO labeller (``irlsim collect --driver``
with a ``sumo`` demonstrator).

Every planning cycle a learned reward drives; to label the state it drove into, the simulation is saved,
SUMO's driver model (the demonstrator's vehicle type) drives the ego for the planner's horizon, and the
saved state is loaded back: what SUMO's driver would have done from the learner's own state, whose
odometry projected onto the cycle's policy set is the demonstration (:meth:`BranchingSimulation.branch`).

Measured with libsumo 1.28 (``tests/sim/test_branch.py``): SUMO writes a state's positions and speeds with
two decimals unless told otherwise, which moved every vehicle after a load by up to 5 mm and 0.005 m/s;
``--save-state.precision 17`` writes them to the last bit. SUMO's random streams are not part of a saved
state by default, so the traffic after a branch dawdles (Krauss's ``sigma``) otherwise than it would have
without one: a labelled episode is its own sample of traffic, the same for the same seed. Restoring the
streams as well (``--save-state.rng``) made the set of vehicles differ a few cycles after a load (not traced
further), so it is not used. Cost: a save and a load of the oval with 15 vehicles take about 3 ms, the
horizon's 50 steps about 6 ms more (2-core Intel Xeon). SUMO's lane-based drivers have no lateral
position of their own: a placed ego's lateral offset from its lane's centre (``moveToXY`` places it
exactly) is kept through the whole look ahead and across a lane change, which moves it a lane width
(measured: a car 1.49 m off its lane's centre stayed there for all 50 steps; one 0.81 m off changed lanes at
once and sat 0.81 m off the new lane's centre, at 4.01 m);
:meth:`BranchingSimulation.lane_offset` reads it, so a labeller can read SUMO's lanes, not that offset.

Lane changes that take time (``--lanechange.duration``, a demonstrator's ``lane_change_duration``) are
otherwise (measured with libsumo 1.28, LC2013): SUMO's maneuver starts from the placed ego's lateral
position and ends at the target lane's centre, with no offset kept; and a SUMO driver straddling a lane
line is always in a maneuver it completes, which a look ahead from a placed ego does not know (SUMO keeps
it straddling: on the oval look aheads from an ego 0.75-1.4 m into a lane change an earlier look ahead had
started kept it there for the whole horizon, and the oracle's ego went back and forth between the two
lanes for 35 s). So where the placed ego's body crosses its lane's line and moves on outward, the look
ahead asks SUMO's driver to complete that change (``vehicle.changeLane``), and a look ahead that changes
lanes is read as driven: :meth:`BranchingSimulation.look_ahead_offset` is then 0.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from irlsim.sim.inputs import reports_sumo_errors
from irlsim.sim.simulation import EGO, Simulation
from irlsim.sim.sumo_ego import lane_of, sumo_step, take_over
from irlsim.sim.types import EgoState
from irlsim.sim.vtype import DEMO_TYPE

#: SUMO's lane-change mode of a look ahead that completes a lane change under way: SUMO's default (1621)
#: with a TraCI request that does not wait for the gaps of others (bits 8-9: 0 instead of 2). With 1, "avoid
#: immediate collisions", SUMO refused 29 of 119 such requests in an oval episode of the sporty driver's
#: oracle and kept the ego straddling; with 0, none of 106
COMPLETE_MODE = 0b10001010101

#: SUMO's options of a simulation that branches: states saved to the last bit
BRANCH_OPTIONS = ("--save-state.precision", "17")


class BranchingSimulation(Simulation):
    """A :class:`~irlsim.sim.simulation.Simulation` that can look ahead with SUMO's driver and come back."""

    _branch_dir: tempfile.TemporaryDirectory[str] | None = None
    _look_ahead_offset = 0.0

    def command(self, seed: int) -> list[str]:
        return [*super().command(seed), *BRANCH_OPTIONS]

    @reports_sumo_errors
    def branch(self, n_steps: int) -> list[EgoState]:
        """SUMO's driver (the demonstrator's type; without one SUMO's own, as ``SumoDriver``) drives the ego
        ``n_steps`` steps from the current state; then the simulation is loaded back to that state and the
        ego is placed by the next trajectory again. Returns the states driven (route frame, as the
        odometry of a SUMO demonstrator; fewer where SUMO took the ego off at its route's end: the
        route's end repeated). Nothing of the episode's books (collisions, stops, odometry) sees the
        branch."""
        self._require_episode()
        assert self.ego is not None
        if self._ego_by_sumo:
            raise RuntimeError("SUMO drives the ego already: a branch looks ahead from a placed ego")
        if self._branch_dir is None:
            shm = "/dev/shm" if os.path.isdir("/dev/shm") else None  # a state file per cycle: in memory
            self._branch_dir = tempfile.TemporaryDirectory(prefix="irlsim-branch-", dir=shm)
        state = str(Path(self._branch_dir.name) / "state.xml")
        api = self._api
        off = self._look_ahead_offset = self.lane_offset()
        api.simulation.saveState(state)
        try:
            take_over(api, EGO, self.cfg.ego_target_speed, DEMO_TYPE if self.demo_type else None)
            if self.lane_change_duration:
                self._complete_lane_change(off, n_steps)
            driven, st = [], self.ego
            for _ in range(int(n_steps)):
                st = sumo_step(api, EGO, self.road, st)
                driven.append(st)
        finally:
            api.simulation.loadState(state)
            api.vehicle.setSpeedMode(EGO, 0)  # placed by moveToXY again, as Simulation.reset left it
        return driven

    def look_ahead(self, n_steps: int) -> list[EgoState]:
        """A :meth:`branch` read at SUMO's lanes' centres, the look ahead a labeller projects: the placed
        ego's offset, which SUMO keeps, taken off every state; where a lane change that takes time ends
        the look ahead in another lane, the states as driven (SUMO's maneuver starts where the ego is),
        not past that lane's centre (SUMO's maneuver crosses a whole lane width from the ego's offset and
        then snaps to the centre). :meth:`look_ahead_offset` says which."""
        driven = self.branch(n_steps)
        assert self.ego is not None
        off = self._look_ahead_offset
        if self.lane_change_duration and driven:
            start, end = (int(k) for k in self.road.lane_of_d(np.array([self.ego.d - off, driven[-1].d])))
            if start != end:
                self._look_ahead_offset = 0.0
                c, side = float(self.road.lane_center(end)), 1.0 if end > start else -1.0
                return [dataclasses.replace(x, d=c + side * min(side * (x.d - c), 0.0)) for x in driven]
        return [dataclasses.replace(x, d=x.d - off) for x in driven]

    def _complete_lane_change(self, off: float, n_steps: int) -> None:
        """Where the placed ego's body crosses its lane's line (``off`` [m] from the lane's centre) and moves
        on outward, SUMO's driver is asked to complete that lane change (the module docstring)."""
        api, w = self._api, self.road.lane_width
        straddles = abs(off) > 0.5 * (w - float(api.vehicle.getWidth(EGO)))
        assert self.ego is not None
        if not (straddles and off * self.ego.d_dot > 0.0):
            return
        edge, lane = lane_of(api, EGO)
        k = lane + int(math.copysign(1, off))
        if edge and 0 <= k < int(api.edge.getLaneNumber(edge)):
            # a maneuver under way is completed whatever the gaps SUMO asks of a change it has yet to start
            # (the ego already straddles the line; the mode comes back with the saved state)
            api.vehicle.setLaneChangeMode(EGO, COMPLETE_MODE)
            api.vehicle.changeLane(EGO, k, n_steps * self.cfg.step)

    def look_ahead_offset(self) -> float:
        """[m] What :meth:`look_ahead` took off the last look ahead's lateral offsets: the placed ego's
        :meth:`lane_offset`, or 0 where it read a lane change that takes time as driven (the module
        docstring); a labeller's :func:`irlsim.data.demos.lane_jump_projection` takes it."""
        return self._look_ahead_offset

    def lane_offset(self) -> float:
        """[m] The placed ego's lateral offset from the centre of the lane SUMO has it in (positive to the
        left), which a branch keeps unchanged (module docstring): subtracted from a branch's ``d``, the
        look ahead is SUMO's driver at its lanes' centres."""
        self._require_episode()
        return float(self._api.vehicle.getLateralLanePosition(EGO))

    def close(self) -> None:
        super().close()
        if self._branch_dir is not None:
            self._branch_dir.cleanup()
            self._branch_dir = None
