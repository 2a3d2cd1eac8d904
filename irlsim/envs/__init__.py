"""The oval course as a Gymnasium environment (the optional extra ``gym``: ``pip install -e '.[gym]'``).

Importing this package registers

    irlsim/Oval-v0             Discrete(n_policies): the index of one of the cycle's sampled policies
    irlsim/OvalContinuous-v0   Box(2): (target acceleration [m/s^2], lateral target [m]) -> nearest policy

so ``gymnasium.make("irlsim/Oval-v0")`` works after ``import irlsim.envs`` (or in one step:
``gymnasium.make("irlsim.envs:irlsim/Oval-v0")``). See :class:`irlsim.envs.oval.OvalEnv`.
"""

from __future__ import annotations

from irlsim.errors import IrlsimError

try:
    import gymnasium
except ImportError:  # pragma: no cover - the extra is installed by make setup
    raise IrlsimError(
        "irlsim.envs needs gymnasium: install the extra with pip install -e '.[gym]' (make setup does)"
    ) from None

from irlsim.envs.oval import OvalEnv, continuous_to_index, normalised_value  # noqa: E402

ENV_ID = "irlsim/Oval-v0"
CONTINUOUS_ENV_ID = "irlsim/OvalContinuous-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(ENV_ID, entry_point="irlsim.envs.oval:OvalEnv", disable_env_checker=True)
if CONTINUOUS_ENV_ID not in gymnasium.registry:
    gymnasium.register(
        CONTINUOUS_ENV_ID,
        entry_point="irlsim.envs.oval:OvalEnv",
        kwargs={"continuous": True},
        disable_env_checker=True,
    )

__all__ = ["ENV_ID", "CONTINUOUS_ENV_ID", "OvalEnv", "continuous_to_index", "normalised_value"]
