"""The one episode loop (:class:`EpisodeRunner`) with its observers' protocol, and drivers by name.

Above the simulator and the planner, below the dataset, training and closed-loop driving that use it."""

from irlsim.rollout.drivers import DRIVERS, make_driver
from irlsim.rollout.runner import (
    FACT_COUNTS,
    TERMINAL_REASONS,
    Cycle,
    EpisodeResult,
    EpisodeRunner,
    Observer,
    ObserverBase,
    PolicyDriver,
    StepResult,
)

__all__ = [
    "DRIVERS",
    "FACT_COUNTS",
    "TERMINAL_REASONS",
    "Cycle",
    "EpisodeResult",
    "EpisodeRunner",
    "Observer",
    "ObserverBase",
    "PolicyDriver",
    "StepResult",
    "make_driver",
]
