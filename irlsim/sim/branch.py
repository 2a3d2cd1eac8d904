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
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from irlsim.sim.simulation import EGO, Simulation
from irlsim.sim.sumo_ego import sumo_step, take_over
from irlsim.sim.types import EgoState
from irlsim.sim.vtype import DEMO_TYPE

#: SUMO's options of a simulation that branches: states saved to the last bit
BRANCH_OPTIONS = ("--save-state.precision", "17")


class BranchingSimulation(Simulation):
    """A :class:`~irlsim.sim.simulation.Simulation` that can look ahead with SUMO's driver and come back."""

    _branch_dir: tempfile.TemporaryDirectory[str] | None = None

    def command(self, seed: int) -> list[str]:
        return [*super().command(seed), *BRANCH_OPTIONS]

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
        api.simulation.saveState(state)
        try:
            take_over(api, EGO, self.cfg.ego_target_speed, DEMO_TYPE if self.demo_type else None)
            driven, st = [], self.ego
            for _ in range(int(n_steps)):
                st = sumo_step(api, EGO, self.road, st)
                driven.append(st)
        finally:
            api.simulation.loadState(state)
            api.vehicle.setSpeedMode(EGO, 0)  # placed by moveToXY again, as Simulation.reset left it
        return driven

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
