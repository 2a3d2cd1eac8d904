"""The recording observer of collection (:class:`CycleRecorder`): every planning cycle's policy set, the
executed policy and the demonstration go to the episode's writer; and what a DAgger driver must carry
for its labels (:class:`LabelledDriver`)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from irlsim.data.demos import DemoProjector, expert_projection, lane_jump_projection
from irlsim.data.situations import situation_of
from irlsim.data.writer import EpisodeWriter
from irlsim.planner.policy_set import PolicySet
from irlsim.rollout import Cycle, EpisodeResult, ObserverBase
from irlsim.sim.simulation import Simulation
from irlsim.sim.types import Observation, Trajectory


@runtime_checkable
class LabelledDriver(Protocol):
    """A driver whose every cycle also carries a label on the very policy set it chose from (DAgger):
    ``last_policy_set`` / ``last_index`` describe what was executed; the label is the expert's choice in
    that set (``expert_index``) or, with a SUMO demonstrator, what SUMO's driver drove from the cycle's
    state (``look_ahead``: its odometry (t, s, d, yaw) over the horizon, projected as a demonstrator's;
    None otherwise). Built in ``irlsim.drive.dagger`` (the learned driver lives above the data layer);
    collection only records it."""

    last_policy_set: PolicySet | None
    last_index: int
    expert_index: int
    look_ahead: list[tuple[float, float, float, float]] | None
    #: [m] with ``look_ahead``: the placed ego's offset from the centre of its SUMO lane, at which the look
    #: ahead is read after the ego's own state (:func:`~irlsim.data.demos.lane_jump_projection`)
    look_ahead_offset: float

    def plan(self, obs: Observation) -> Trajectory: ...


class CycleRecorder(ObserverBase):
    """The recording observer of collection: every cycle's policy set and executed index go to the
    ``EpisodeWriter``. The demonstration is either the odometry of what was actually driven, projected by
    the ``DemoProjector`` once each cycle's horizon has been driven (``labeller`` None), or, with a
    ``labeller`` (a :class:`LabelledDriver`), at once: the expert's own selection in the same policy set
    (:func:`irlsim.data.demos.expert_projection`), or SUMO's driver's look ahead projected
    (:meth:`~irlsim.data.demos.DemoProjector.project_window`, a lane change within one step by
    :func:`~irlsim.data.demos.lane_jump_projection`)."""

    def __init__(
        self,
        writer: EpisodeWriter,
        projector: DemoProjector,
        labeller: LabelledDriver | None = None,
    ):
        self.writer, self.projector, self.labeller = writer, projector, labeller
        self.agree = 0  # cycles whose executed policy is the label (DAgger: the expert's or SUMO's)

    def on_reset(self, sim: Simulation, obs: Observation) -> None:
        e = obs.ego
        self.projector.push_odometry(e.t, e.s, e.d, e.yaw)

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None:
        ps, obs, traj = cycle.policy_set, cycle.obs, cycle.trajectory
        assert ps is not None, "collection records drivers that choose from a policy set"
        e = obs.ego
        ego = {"x": e.x, "y": e.y, "yaw": e.yaw, "v": e.v, "s": e.s, "d": e.d, "lane": e.lane}
        self.writer.add_cycle(
            cycle.index,
            ps,
            ego,
            executed_index=cycle.chosen,
            target_checkpoint=obs.target_checkpoint,
            situation=situation_of(obs, sim.road),
        )
        if self.labeller is not None:
            assert self.labeller.last_policy_set is ps, "the label belongs to the executed policy set"
            p, seen = self.projector, self.labeller.look_ahead
            if seen is not None:  # SUMO's driver from this state: its odometry projected
                demo = p.project_window(cycle.index, ps.t, (ps.s, ps.d, ps.yaw), seen)
                seen_d = np.array([r[2] for r in seen])
                off = self.labeller.look_ahead_offset
                demo = lane_jump_projection(demo, ps.d[:, -1], seen_d, sim.road.lane_width, off)
            else:
                k = self.labeller.expert_index
                demo = expert_projection(
                    cycle.index, ps.s, ps.d, ps.yaw, k, alpha=p.alpha, w_yaw=p.w_yaw, lap_length=p.lap_length
                )
            self.agree += int(demo.demo_index == cycle.chosen)
            self.writer.add_demo(demo)
            return
        self.projector.push_cycle(cycle.index, ps.t, ps.s, ps.d, ps.yaw)
        # only the steps SUMO actually simulated: an episode that ends mid-cycle (collision, exit,
        # time-out) must not complete a demonstration window with states that were never driven; where
        # SUMO drove (a SUMO demonstrator) the states are the simulation's odometry
        driven = sim.odometry[len(sim.odometry) - cycle.driven :] if traj.by_sumo else None
        for j in range(1, cycle.driven + 1):
            st = traj.state(j) if driven is None else driven[j - 1]
            self.projector.push_odometry(st.t, st.s, st.d, st.yaw)
        self.writer.add_demos(self.projector.pop_ready())

    def on_end(self, sim: Simulation, result: EpisodeResult) -> None:
        if self.labeller is None:
            self.writer.add_demos(self.projector.finish())
