"""The cart-pole twin as Gymnasium environments, and the project's policy tools.

Importing the package registers ``cartpole_ddqn/Twin-v0`` with Gymnasium (``gymnasium.make``
and ``gymnasium.make_vec``), and ``cartpole_ddqn/SwingUp-v0``. ``load``, ``export`` and ``evaluate`` run the code the
``policy-export`` and ``host-sim`` commands run.
"""

import gymnasium

from .api import MAX_EPISODES, MAX_HORIZON, MAX_ROWS, Policy, evaluate, export, load, provenance, shipped
from .env import MAX_ENVS, SwingUpEnv, TwinEnv, TwinVectorEnv

__all__ = [
    "MAX_ENVS",
    "MAX_EPISODES",
    "MAX_HORIZON",
    "MAX_ROWS",
    "Policy",
    "SwingUpEnv",
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

SWING_UP_ID = "cartpole_ddqn/SwingUp-v0"

if SWING_UP_ID not in gymnasium.registry:
    # 20 s at Gymnasium's 50 Hz: a swing-up and the balance after it.
    gymnasium.register(id=SWING_UP_ID, entry_point="cartpole_ddqn.env:SwingUpEnv", max_episode_steps=1000)
