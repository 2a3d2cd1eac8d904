"""Driving a road by choosing among the planner's sampled policies, as a Gymnasium environment (the
optional extra ``gym``: ``pip install -e '.[gym]'``), on any scenario (default the oval).

Importing this package registers

    irlsim/Planning-v0             Discrete(n_policies): the index of one of the cycle's sampled policies
    irlsim/PlanningContinuous-v0   Box(2): (target acceleration [m/s^2], lateral target [m]) -> nearest policy

and, as aliases of the same environments under the names they had when the oval was the only road,
``irlsim/Oval-v0`` and ``irlsim/OvalContinuous-v0``. So ``gymnasium.make("irlsim/Planning-v0")`` works
after ``import irlsim.envs`` (or in one step: ``gymnasium.make("irlsim.envs:irlsim/Planning-v0")``). See
:class:`irlsim.envs.planning.PlanningEnv`.
"""

from __future__ import annotations

from irlsim.errors import IrlsimError

try:
    import gymnasium
except ImportError:  # pragma: no cover - the extra is installed by make setup
    raise IrlsimError(
        "irlsim.envs needs gymnasium: install the extra with pip install -e '.[gym]' (make setup does)"
    ) from None

from irlsim.envs.planning import PlanningEnv, continuous_to_index, normalised_value  # noqa: E402

ENV_ID = "irlsim/Planning-v0"
CONTINUOUS_ENV_ID = "irlsim/PlanningContinuous-v0"
#: the ids of before, kept: the same environments
ALIASES = {"irlsim/Oval-v0": ENV_ID, "irlsim/OvalContinuous-v0": CONTINUOUS_ENV_ID}
#: the class's name of before, kept
OvalEnv = PlanningEnv

_ENTRY = "irlsim.envs.planning:PlanningEnv"
for _id, _kwargs in ((ENV_ID, {}), (CONTINUOUS_ENV_ID, {"continuous": True})):
    for _name in (_id, *(old for old, new in ALIASES.items() if new == _id)):
        if _name not in gymnasium.registry:
            gymnasium.register(_name, entry_point=_ENTRY, kwargs=_kwargs, disable_env_checker=True)

__all__ = [
    "ALIASES",
    "CONTINUOUS_ENV_ID",
    "ENV_ID",
    "OvalEnv",
    "PlanningEnv",
    "continuous_to_index",
    "normalised_value",
]
