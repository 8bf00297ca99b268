"""The cart-pole twin as Gymnasium environments, and the project's policy tools.

Importing the package registers ``cartpole_ddqn/Twin-v0`` with Gymnasium (``gymnasium.make``
and ``gymnasium.make_vec``). ``load``, ``export`` and ``evaluate`` run the code the
``policy-export`` and ``host-sim`` commands run.
"""

import gymnasium

from .api import MAX_EPISODES, MAX_HORIZON, MAX_ROWS, Policy, evaluate, export, load, provenance, shipped
from .env import MAX_ENVS, TwinEnv, TwinVectorEnv

__all__ = [
    "MAX_ENVS",
    "MAX_EPISODES",
    "MAX_HORIZON",
    "MAX_ROWS",
    "Policy",
    "TwinEnv",
    "TwinVectorEnv",
    "evaluate",
    "export",
    "load",
    "provenance",
    "shipped",
]

ENV_ID = "cartpole_ddqn/Twin-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="cartpole_ddqn.env:TwinEnv",
        vector_entry_point="cartpole_ddqn.env:TwinVectorEnv",
        max_episode_steps=500,
    )
