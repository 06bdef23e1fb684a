"""Simulated Khepera-like robot facing one object, as Gymnasium environments.

Two backends share one interface (:class:`KheperaEnv`): ``"mujoco"`` (the MJCF model in
``assets/khepera.xml``, contact physics) and ``"kinematic"`` (a fast unicycle with the
same motor lag and wheel mismatch).  Importing this package registers the gymnasium ids
``behavior_hmm/Khepera-v0`` (MuJoCo) and ``behavior_hmm/KheperaKinematic-v0``; the
Khepera with a gripper (:class:`KheperaGripperEnv`, ``assets/khepera_gripper.xml``) is
``behavior_hmm/KheperaGripper-v0``.

Examples
--------
>>> from behavior_hmm.sim import make_env
>>> env = make_env("kinematic")
>>> obs, info = env.reset(seed=0, options={"angle": 90.0, "distance": 0.3})
>>> [round(float(v), 6) for v in obs]
[0.3, 0.0, 90.0, 0.0]
"""

from __future__ import annotations

import gymnasium as _gymnasium

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
from behavior_hmm.sim._gripper import GRIPPER_ENV_ID, KheperaGripperEnv
from behavior_hmm.sim._husky import HuskyEnv, make_husky
from behavior_hmm.sim._mujoco import MODEL_XML
from behavior_hmm.sim._params import RobotParams
from behavior_hmm.sim._point_mass import POINT_MASS_ENV_ID, PointMassEnv

__all__ = [
    "BACKENDS",
    "COMMAND_CHANNELS",
    "CONTROL_PERIOD",
    "DEFAULT_START",
    "ENV_ID",
    "GRIPPER_ENV_ID",
    "KINEMATIC_ENV_ID",
    "MODEL_XML",
    "POINT_MASS_ENV_ID",
    "SENSOR_CHANNELS",
    "ChannelDict",
    "HuskyEnv",
    "KheperaEnv",
    "KheperaGripperEnv",
    "PointMassEnv",
    "RobotParams",
    "make_contract_env",
    "make_env",
    "make_husky",
    "wrap_degrees",
]

register_envs()
if POINT_MASS_ENV_ID not in _gymnasium.registry:  # the LASA robot (a 2-D point mass)
    _gymnasium.register(POINT_MASS_ENV_ID, "behavior_hmm.sim._point_mass:make_point_mass")
