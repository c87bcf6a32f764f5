"""Registration of the sb3-adc environments under the Gymnasium namespace ``sb3_adc/``.

Entry points are given as ``"module:callable"`` strings, so registering imports nothing heavy;
Gymnasium imports the module (and with it pybullet or highway-env) on ``gym.make``. Importing
``sb3_adc_envs`` registers the ids, so ``gym.make("sb3_adc_envs:sb3_adc/LidarObstacleCourse-v1")`` works in a
fresh process without importing torch or Stable-Baselines3.
"""

from __future__ import annotations

import re
import warnings
from typing import Any

import gymnasium as gym

NAMESPACE = "sb3_adc"

#: Make kwargs of ``sb3_adc/LidarObstacleCourse-v1``: a new procedural layout at every reset, from the training
#: layout seeds, seen through :data:`V1_N_RAYS` rays (docs/envs/lidar_course.rst says why that many).
V1_N_RAYS = 24
_LIDAR_V1_KWARGS: dict[str, Any] = {"course": "procedural", "n_rays": V1_N_RAYS}

#: Every environment the package registers: id -> keyword arguments of :func:`gymnasium.register`.
ENV_SPECS: dict[str, dict[str, Any]] = {
    f"{NAMESPACE}/NoisyPendulum-v1": {
        "entry_point": "sb3_adc_envs.pendulum:make_noisy_pendulum",
        "max_episode_steps": 200,
        "kwargs": {"noise_low": -0.1, "noise_high": 0.1},
    },
    f"{NAMESPACE}/LidarObstacleCourse-v0": {
        "entry_point": "sb3_adc_envs.lidar_course.env:LidarObstacleCourseEnv",
        "max_episode_steps": 500,
    },
    f"{NAMESPACE}/LidarObstacleCourseNoisy-v0": {
        "entry_point": "sb3_adc_envs.lidar_course.noisy:NoisyLidarObstacleCourse",
        "max_episode_steps": 500,
        "kwargs": {"noise_low": -0.1, "noise_high": 0.1},
    },
    f"{NAMESPACE}/LidarObstacleCourse-v1": {
        "entry_point": "sb3_adc_envs.lidar_course.env:LidarObstacleCourseEnv",
        "max_episode_steps": 500,
        "kwargs": _LIDAR_V1_KWARGS,
    },
    f"{NAMESPACE}/LidarObstacleCourseNoisy-v1": {
        "entry_point": "sb3_adc_envs.lidar_course.noisy:NoisyLidarObstacleCourse",
        "max_episode_steps": 500,
        "kwargs": {"noise_low": -0.1, "noise_high": 0.1, **_LIDAR_V1_KWARGS},
    },
    # Two actions, steering and speed (sb3_adc_envs.lidar_course.speed): the -v1 task with a multi-dimensional action.
    f"{NAMESPACE}/LidarObstacleCourseSpeed-v1": {
        "entry_point": "sb3_adc_envs.lidar_course.speed:SpeedSteeringLidarCourse",
        "max_episode_steps": 500,
        "kwargs": _LIDAR_V1_KWARGS,
    },
    # 200 steps: highway-env ends an episode itself after `duration` (40 s) at `policy_frequency` (5 Hz); a config
    # with another duration or frequency needs `max_episode_steps=` at `gym.make` to match.
    f"{NAMESPACE}/HighwayObstacle-v0": {
        "entry_point": "sb3_adc_envs.highway_obstacle:HighwayObstacleEnv",
        "max_episode_steps": 200,
    },
    # The same task seen through 64 lidar rays instead of 16 (sb3_adc_envs.highway_obstacle.env.HighwayObstacleV1Env).
    f"{NAMESPACE}/HighwayObstacle-v1": {
        "entry_point": "sb3_adc_envs.highway_obstacle:HighwayObstacleV1Env",
        "max_episode_steps": 200,
    },
}


#: Ids whose ``-v1`` is another task, not a newer version: ``-v0`` drives the fixed course files, ``-v1`` procedural
#: layouts. Gymnasium takes a higher version of a name for an upgrade and warns at every ``gym.make`` of these ids
#: that they are "out of date"; :func:`register_envs` silences that one warning for them (every other warning stays).
CURRENT_V0_IDS = (f"{NAMESPACE}/LidarObstacleCourse-v0", f"{NAMESPACE}/LidarObstacleCourseNoisy-v0")


def register_envs() -> None:
    """
    Register every id of :data:`ENV_SPECS` with Gymnasium; ids already registered are left alone. Gymnasium's
    "out of date" warning is silenced for the ids of :data:`CURRENT_V0_IDS`, which are current tasks.
    """
    for env_id, spec_kwargs in ENV_SPECS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, **spec_kwargs)
    for env_id in CURRENT_V0_IDS:
        # Gymnasium's message starts with colour codes and "WARN: "; only the exact id's warning matches.
        warnings.filterwarnings(
            "ignore", message=rf".*The environment {re.escape(env_id)} is out of date\.", category=DeprecationWarning
        )
