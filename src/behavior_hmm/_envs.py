"""Our Gymnasium ids, registered when ``behavior_hmm`` is imported (no simulator loaded)."""

from __future__ import annotations

from typing import Final

#: Gymnasium id of the MuJoCo-backed environment (robot contract: Dict observations).
ENV_ID: Final[str] = "behavior_hmm/Khepera-v0"
#: Gymnasium id of the kinematic environment.
KINEMATIC_ENV_ID: Final[str] = "behavior_hmm/KheperaKinematic-v0"
#: Gymnasium id of the Clearpath Husky in PyBullet (``pip install 'behavior-hmm[pybullet]'``).
HUSKY_ENV_ID: Final[str] = "behavior_hmm/Husky-v0"
#: Gymnasium id of our Khepera with a gripper, in MuJoCo (the thesis's grasp behavior).
GRIPPER_ENV_ID: Final[str] = "behavior_hmm/KheperaGripper-v0"
#: Steps after which ``gymnasium.make(id)`` truncates an episode (``max_episode_steps``).
DEFAULT_MAX_EPISODE_STEPS: Final[int] = 4000


def register_envs() -> None:
    """Register our ids once (re-importing or reloading is harmless).

    The env's own step limit is off: ``gymnasium.make``'s TimeLimit alone decides, so
    ``gymnasium.make(id, max_episode_steps=N)`` is honored for any N.
    """
    import gymnasium

    for env_id, backend in ((ENV_ID, "mujoco"), (KINEMATIC_ENV_ID, "kinematic")):
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="behavior_hmm.sim._env:make_contract_env",
                kwargs={"backend": backend, "max_episode_steps": None},
                max_episode_steps=DEFAULT_MAX_EPISODE_STEPS,
            )
    if GRIPPER_ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=GRIPPER_ENV_ID,
            entry_point="behavior_hmm.sim._gripper:make_gripper",
            max_episode_steps=DEFAULT_MAX_EPISODE_STEPS,
        )
    if HUSKY_ENV_ID not in gymnasium.registry:  # pybullet is imported only by make()
        gymnasium.register(
            id=HUSKY_ENV_ID,
            entry_point="behavior_hmm.sim._husky:make_husky",
            max_episode_steps=DEFAULT_MAX_EPISODE_STEPS,
        )
