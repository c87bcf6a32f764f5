"""``sb3_adc/LidarObstacleCourseNoisy-v0``: the lidar course with uniform observation noise (ADC paper, Section 5.2)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from sb3_adc_envs.lidar_course.env import LidarObstacleCourseEnv
from sb3_adc_envs.wrappers import UniformObservationNoise


def make_noisy_lidar_course(
    noise_low: float = -0.1,
    noise_high: float = 0.1,
    **env_kwargs: Any,
) -> gym.Env[np.ndarray, np.ndarray]:
    """
    :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv` whose lidar readings carry i.i.d. uniform
    noise in ``[noise_low, noise_high]`` (the observation space widens to ``[noise_low, 1 + noise_high]``).

    Registered as ``sb3_adc/LidarObstacleCourseNoisy-v0`` (500 steps per episode); every keyword of the
    environment is a make kwarg too: ``gym.make("sb3_adc/LidarObstacleCourseNoisy-v0", course="unseen_narrow")``.

    :param noise_low: Lower bound of the observation noise
    :param noise_high: Upper bound of the observation noise
    :param env_kwargs: Keyword arguments of :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv`
    """
    return UniformObservationNoise(LidarObstacleCourseEnv(**env_kwargs), low=noise_low, high=noise_high)
