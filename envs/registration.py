"""Registration of the sb3-adc environments under the Gymnasium namespace ``sb3_adc/``.

Entry points are given as ``"module:callable"`` strings, so registering imports nothing heavy;
Gymnasium imports the module (and with it pybullet or highway-env) on ``gym.make``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

NAMESPACE = "sb3_adc"

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
        "entry_point": "sb3_adc_envs.lidar_course.noisy:make_noisy_lidar_course",
        "max_episode_steps": 500,
        "kwargs": {"noise_low": -0.1, "noise_high": 0.1},
    },
    f"{NAMESPACE}/HighwayObstacle-v0": {
        "entry_point": "sb3_adc_envs.highway_obstacle:HighwayObstacleEnv",
    },
}


def register_envs() -> None:
    """Register every id of :data:`ENV_SPECS` with Gymnasium; ids already registered are left alone."""
    for env_id, spec_kwargs in ENV_SPECS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, **spec_kwargs)
