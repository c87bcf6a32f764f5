"""``sb3_adc/LidarObstacleCourseNoisy-v0``/``-v1``: the lidar course with uniform observation noise (ADC paper, 5.2)."""

from __future__ import annotations

from typing import Any

from sb3_adc_envs.lidar_course.env import LidarObstacleCourseEnv
from sb3_adc_envs.wrappers import UniformObservationNoise


class NoisyLidarObstacleCourse(UniformObservationNoise):
    """
    :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv` whose lidar readings carry i.i.d. uniform
    noise in ``[noise_low, noise_high]`` (the observation space widens to ``[noise_low, 1 + noise_high]``).

    Registered as ``sb3_adc/LidarObstacleCourseNoisy-v0`` and ``-v1`` (500 steps per episode), the noisy twins of
    ``sb3_adc/LidarObstacleCourse-v0`` and ``-v1``; every keyword of the environment is a make kwarg too:
    ``gym.make("sb3_adc/LidarObstacleCourseNoisy-v0", course="unseen_narrow")``. The class carries the
    environment's ``metadata``, so ``gym.make`` reads its render modes before making it and wraps
    ``render_mode="human"`` in ``HumanRendering`` as it does for the clean environment.

    :param noise_low: Lower bound of the observation noise
    :param noise_high: Upper bound of the observation noise
    :param env_kwargs: Keyword arguments of :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv`
    """

    metadata = LidarObstacleCourseEnv.metadata

    def __init__(self, noise_low: float = -0.1, noise_high: float = 0.1, **env_kwargs: Any):
        super().__init__(LidarObstacleCourseEnv(**env_kwargs), low=noise_low, high=noise_high)


def make_noisy_lidar_course(noise_low: float = -0.1, noise_high: float = 0.1, **env_kwargs: Any) -> NoisyLidarObstacleCourse:
    """
    The noisy lidar course (:class:`NoisyLidarObstacleCourse`).

    :param noise_low: Lower bound of the observation noise
    :param noise_high: Upper bound of the observation noise
    :param env_kwargs: Keyword arguments of :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv`
    """
    return NoisyLidarObstacleCourse(noise_low, noise_high, **env_kwargs)
