"""Simulated Khepera-like robot facing one object, as Gymnasium environments.

Two backends share one interface (:class:`KheperaEnv`): ``"mujoco"`` (the MJCF model in
``assets/khepera.xml``, contact physics) and ``"kinematic"`` (a fast unicycle with the
same motor lag and wheel mismatch).  Importing this package registers the gymnasium ids
``behavior_hmm/Khepera-v0`` (MuJoCo) and ``behavior_hmm/KheperaKinematic-v0``.

Examples
--------
>>> from behavior_hmm.sim import make_env
>>> env = make_env("kinematic")
>>> obs, info = env.reset(seed=0, options={"angle": 90.0, "distance": 0.3})
>>> [round(float(v), 6) for v in obs]
[0.3, 0.0, 90.0, 0.0]
"""

from __future__ import annotations

from behavior_hmm._envs import register_envs
from behavior_hmm.data._channels import COMMAND_CHANNELS, CONTROL_PERIOD, SENSOR_CHANNELS
from behavior_hmm.sim._env import (
    BACKENDS,
    DEFAULT_START,
    ENV_ID,
    KINEMATIC_ENV_ID,
    ChannelDict,
    KheperaEnv,
    make_contract_env,
    make_env,
    wrap_degrees,
)
from behavior_hmm.sim._husky import HuskyEnv, make_husky
from behavior_hmm.sim._mujoco import MODEL_XML
from behavior_hmm.sim._params import RobotParams

__all__ = [
    "BACKENDS",
    "COMMAND_CHANNELS",
    "CONTROL_PERIOD",
    "DEFAULT_START",
    "ENV_ID",
    "KINEMATIC_ENV_ID",
    "MODEL_XML",
    "SENSOR_CHANNELS",
    "ChannelDict",
    "HuskyEnv",
    "KheperaEnv",
    "RobotParams",
    "make_contract_env",
    "make_env",
    "make_husky",
    "wrap_degrees",
]

register_envs()
