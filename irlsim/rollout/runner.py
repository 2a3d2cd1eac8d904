"""The one episode loop: observe, plan, execute one planning cycle, tell the observers; until the end.

Every episode irlsim drives goes through :class:`EpisodeRunner`: ``irlsim sim`` (a built-in driver),
collection (the expert, recorded to Parquet by an observer) and closed-loop driving (a learned reward;
metrics and pictures are observers). It is used in two ways:

**(a) driven**: ``runner.run(driver, seed)`` drives a whole episode with a driver object
(``plan(obs) -> Trajectory``) and returns an :class:`EpisodeResult`::

    with Simulation(road, scenario) as sim:
        result = EpisodeRunner(sim, observers=[recorder]).run(driver, seed, max_cycles=0)

**(b) stepwise** from outside (a Gymnasium environment, an RL agent), with a planner that samples the
policy set each cycle::

    runner = EpisodeRunner(sim, planner=Planner(road, planner_cfg))
    obs, ps = runner.reset(seed)                  # first cycle's observation and policy set
    while True:
        r = runner.step(index)                    # a policy index into ps, or a Trajectory
        if r.terminated or r.truncated:
            break
        obs, ps = r.obs, r.policy_set

Contract:

- ``reset(seed)`` resets the :class:`~irlsim.sim.simulation.Simulation` (SUMO's seed and the traffic's
  Generator; the ego's start) and calls every observer's ``on_reset``. It does not seed global RNGs:
  callers that need them seeded call :func:`irlsim.utils.seed_everything` first (collection and driving do).
- One cycle executes states 1..k of the trajectory (k = ``scenario.cycle / scenario.step``, 2 by
  default), fewer when the episode ends inside the cycle (collision, exit, laps, time-out): ``Cycle.driven``
  says how many steps SUMO really simulated. Observers' ``on_cycle`` runs after the execution, in
  registration order, with the :class:`Cycle` (the observation at the cycle's start, the trajectory, the
  policy set and chosen index when known, the step's facts).
- The episode ends when the simulation is done (``end_reason`` collision / exit / laps: *terminated*;
  timeout: *truncated*) or after ``max_cycles`` cycles (> 0; *truncated*, ``end_reason`` 'max_cycles').
  Observers' ``on_end`` runs once, before :meth:`run` returns or when :meth:`step` ends the episode.
- Per-step facts (:attr:`StepResult.facts`, :attr:`Cycle.facts`): what changed in the cycle, from the
  simulator's bookkeeping: new ``collisions``, ``exits``, ``checkpoints_passed``, ``checkpoints_in_lane``,
  ``stop_lines_passed``, ``stop_lines_compliant``, ``offroad_steps``; ``progress_m`` (route-frame
  metres driven), ``steps`` (simulated), ``laps`` (completed so far), ``t`` [s], ``end_reason``.
- Stepwise mode plans only while the episode runs: the :class:`StepResult` that ends it has
  ``policy_set`` None. ``step`` after the end raises ``RuntimeError``; call ``reset`` again.
- No SUMO state outlives the :class:`Simulation` the runner was given; the runner holds nothing that
  needs pickling, so a worker process builds its own (one libsumo per process).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from irlsim.planner.planner import Planner
from irlsim.planner.policy_set import PolicySet
from irlsim.sim.drivers import Driver
from irlsim.sim.simulation import Simulation
from irlsim.sim.types import Observation, Trajectory

#: Episode counts reported per cycle as differences (see the module docstring)
FACT_COUNTS = (
    "collisions",
    "exits",
    "checkpoints_passed",
    "checkpoints_in_lane",
    "stop_lines_passed",
    "stop_lines_compliant",
    "offroad_steps",
)
#: end reasons that terminate an episode; the others ('timeout', 'max_cycles') truncate it
TERMINAL_REASONS = ("collision", "exit", "laps", "route_end")


@runtime_checkable
class PolicyDriver(Protocol):
    """A driver that chose its trajectory from a sampled policy set (the expert, a theta driver); the
    runner passes the set and the chosen index on to the observers."""

    last_policy_set: PolicySet | None
    last_index: int

    def plan(self, obs: Observation) -> Trajectory: ...


@dataclass(frozen=True)
class Cycle:
    """One executed planning cycle, as observers see it."""

    index: int
    """0-based cycle number in the episode"""
    obs: Observation
    """the observation the cycle was planned from (at its start)"""
    trajectory: Trajectory
    """what was executed (states 1..driven of it)"""
    policy_set: PolicySet | None
    """the cycle's sampled policy set, when the decision came from one"""
    chosen: int
    """index of the executed policy in ``policy_set`` (-1 without one)"""
    driven: int
    """simulation steps SUMO really simulated (fewer than a cycle when the episode ended inside it)"""
    decide_ms: float
    """wall time of the decision (the driver's ``plan``; 0 in stepwise mode) [ms]"""
    facts: dict[str, float | int | str | None] = field(default_factory=dict)
    """what changed in the cycle (see the module docstring)"""


class Observer(Protocol):
    """Recording, metrics, pictures: called by the runner at the episode's start, after every cycle,
    and once at its end."""

    def on_reset(self, sim: Simulation, obs: Observation) -> None: ...

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None: ...

    def on_end(self, sim: Simulation, result: EpisodeResult) -> None: ...


class ObserverBase:
    """No-op :class:`Observer`; subclass and override what you need."""

    def on_reset(self, sim: Simulation, obs: Observation) -> None:
        pass

    def on_cycle(self, sim: Simulation, cycle: Cycle) -> None:
        pass

    def on_end(self, sim: Simulation, result: EpisodeResult) -> None:
        pass


class StepListener(ObserverBase):
    """An observer of every simulation step, not only every cycle: from an episode's reset to its end
    ``on_step(sim)`` is one of the simulation's ``step_listeners`` (called once at the reset state too);
    ``start(sim)`` clears what the last episode recorded."""

    def start(self, sim: Simulation) -> None:
        pass

    def on_step(self, sim: Simulation) -> None:
        raise NotImplementedError

    def on_reset(self, sim: Simulation, obs: Observation | None = None) -> None:
        self.start(sim)
        if self.on_step not in sim.step_listeners:
            sim.step_listeners.append(self.on_step)
        self.on_step(sim)  # the reset state (odometry[0])

    def on_end(self, sim: Simulation, result: EpisodeResult | None = None) -> None:
        if self.on_step in sim.step_listeners:
            sim.step_listeners.remove(self.on_step)


@dataclass
class EpisodeResult:
    """How an episode ended: the simulator's figures (``sim/...`` keys, ``end_reason``, ``seed``) plus
    the cycles driven and the decision time."""

    seed: int
    cycles: int
    end_reason: str | None
    """collision / exit / laps / timeout (from the simulator) or max_cycles"""
    stats: dict[str, float | int | str | None]
    """``Simulation.stats`` at the end (end_reason None when stopped by max_cycles)"""
    decide_s: float
    """total wall time of the driver's decisions [s]"""

    @property
    def terminated(self) -> bool:
        return self.end_reason in TERMINAL_REASONS

    @property
    def truncated(self) -> bool:
        return self.end_reason is not None and not self.terminated


@dataclass(frozen=True)
class StepResult:
    """What :meth:`EpisodeRunner.step` returns (Gymnasium's step, plus the policy set to choose from)."""

    obs: Observation
    """the next cycle's observation (the last one when the episode ended)"""
    policy_set: PolicySet | None
    """the next cycle's sampled policy set; None when the episode ended"""
    terminated: bool
    """collision, exit or laps done"""
    truncated: bool
    """time-out or max_cycles"""
    facts: dict[str, float | int | str | None]
    cycle: Cycle
    """the executed cycle"""


class EpisodeRunner:
    """Drives episodes of ``sim`` (see the module docstring for the contract).

    ``planner``: needed for the stepwise mode (it samples the policy set each cycle); ``observers``: called
    at reset, after each cycle and at the end; ``max_cycles`` > 0 stops an episode after that many cycles.
    """

    def __init__(
        self,
        sim: Simulation,
        *,
        planner: Planner | None = None,
        observers: Sequence[Observer] = (),
        max_cycles: int = 0,
    ):
        if max_cycles < 0:
            raise ValueError(f"max_cycles must be >= 0, got {max_cycles}")
        self.sim = sim
        self.planner = planner
        self.observers = list(observers)
        self.max_cycles = int(max_cycles)
        self.cycles = 0
        self.obs: Observation | None = None
        self.policy_set: PolicySet | None = None
        self.result: EpisodeResult | None = None
        self._decide_s = 0.0

    # ------------------------------------------------------------------ shared
    @property
    def running(self) -> bool:
        """An episode has been reset and has not ended."""
        return self.obs is not None and self.result is None

    def _begin(self, seed: int) -> Observation:
        self.cycles, self._decide_s, self.result, self.policy_set = 0, 0.0, None, None
        self.obs = obs = self.sim.reset(seed)
        for o in self.observers:
            o.on_reset(self.sim, obs)
        self._check_end()
        return obs

    def _execute(
        self, traj: Trajectory, policy_set: PolicySet | None, chosen: int, decide_ms: float
    ) -> Cycle:
        """Execute one cycle of ``traj``, tell the observers, end the episode when it is over."""
        sim, obs = self.sim, self.obs
        assert obs is not None and sim.episode is not None
        ep = sim.episode
        before = dict(ep.counts)
        s0, n0 = obs.ego.s, len(sim.odometry)
        sim.execute(traj)
        ego = sim.ego
        assert ego is not None
        facts: dict[str, float | int | str | None] = {k: ep.counts[k] - before[k] for k in FACT_COUNTS}
        facts.update(
            progress_m=ego.s - s0,
            steps=len(sim.odometry) - n0,
            laps=ep.laps_completed,
            t=ego.t,
            end_reason=ep.end_reason,
        )
        cycle = Cycle(self.cycles, obs, traj, policy_set, chosen, len(sim.odometry) - n0, decide_ms, facts)
        self.cycles += 1
        for o in self.observers:
            o.on_cycle(sim, cycle)
        self.obs = sim.observe()
        self._check_end()
        if self.result is not None:
            facts["end_reason"] = self.result.end_reason
        return cycle

    def _check_end(self) -> None:
        sim = self.sim
        stop = self.max_cycles > 0 and self.cycles >= self.max_cycles
        if not (sim.done or stop):
            return
        stats = dict(sim.stats)
        end = sim.episode.end_reason if sim.episode is not None else None
        self.result = EpisodeResult(
            seed=int(sim.seed or 0),
            cycles=self.cycles,
            end_reason=end if end is not None else "max_cycles",
            stats=stats,
            decide_s=self._decide_s,
        )
        for o in self.observers:
            o.on_end(sim, self.result)

    # ------------------------------------------------------------------ (a) driven
    def run(self, driver: Driver, seed: int) -> EpisodeResult:
        """Drive one whole episode with ``driver`` and return how it ended."""
        obs = self._begin(seed)
        while self.result is None:
            t0 = time.perf_counter()
            traj = driver.plan(obs)
            dt = time.perf_counter() - t0
            self._decide_s += dt
            ps, chosen = None, -1
            if isinstance(driver, PolicyDriver):
                ps, chosen = driver.last_policy_set, driver.last_index
            self._execute(traj, ps, chosen, 1e3 * dt)
            assert self.obs is not None
            obs = self.obs
        return self.result

    # ------------------------------------------------------------------ (b) stepwise
    def reset(self, seed: int) -> tuple[Observation, PolicySet | None]:
        """Start an episode; returns its first observation and (with a planner) its sampled policy set."""
        obs = self._begin(seed)
        self.policy_set = self._propose(obs)
        return obs, self.policy_set

    def step(self, action: int | Trajectory) -> StepResult:
        """Execute one planning cycle: ``action`` is an index into the current policy set (needs the
        planner) or a :class:`Trajectory` starting at the current observation's ego state."""
        if not self.running:
            raise RuntimeError("no episode running: call reset(seed) first (the last one has ended)")
        if isinstance(action, Trajectory):
            traj, ps, chosen = action, None, -1
        else:
            if self.planner is None or self.policy_set is None:
                raise RuntimeError("a policy index needs a planner: EpisodeRunner(sim, planner=Planner(...))")
            ps, chosen = self.policy_set, int(action)
            if not 0 <= chosen < ps.n_policies:
                raise IndexError(f"policy index {chosen} outside 0..{ps.n_policies - 1}")
            traj = self.planner.trajectory(chosen)
        cycle = self._execute(traj, ps, chosen, 0.0)
        assert self.obs is not None
        self.policy_set = self._propose(self.obs) if self.result is None else None
        res = self.result
        return StepResult(
            obs=self.obs,
            policy_set=self.policy_set,
            terminated=res is not None and res.terminated,
            truncated=res is not None and res.truncated,
            facts=cycle.facts,
            cycle=cycle,
        )

    def _propose(self, obs: Observation) -> PolicySet | None:
        if self.planner is None or self.result is not None:
            return None
        return self.planner.plan(obs)
