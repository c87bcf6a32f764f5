"""``sb3_adc/NoisyPendulum-v1``: Gymnasium's Pendulum-v1 with uniform observation noise (ADC paper, Section 5.2)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.classic_control.pendulum import PendulumEnv

from sb3_adc_envs.wrappers import UniformObservationNoise


def make_noisy_pendulum(
    noise_low: float = -0.1,
    noise_high: float = 0.1,
    render_mode: str | None = None,
    g: float = 10.0,
) -> gym.Env[np.ndarray, Any]:
    """
    Pendulum-v1 whose observations carry i.i.d. uniform noise in ``[noise_low, noise_high]``.

    Registered as ``sb3_adc/NoisyPendulum-v1`` (200 steps per episode, as Pendulum-v1); the bounds are
    make kwargs: ``gym.make("sb3_adc/NoisyPendulum-v1", noise_low=-0.2, noise_high=0.2)``.

    :param noise_low: Lower bound of the observation noise
    :param noise_high: Upper bound of the observation noise
    :param render_mode: Passed to :class:`~gymnasium.envs.classic_control.pendulum.PendulumEnv`
    :param g: Gravity, passed to :class:`~gymnasium.envs.classic_control.pendulum.PendulumEnv`
    """
    return UniformObservationNoise(PendulumEnv(render_mode=render_mode, g=g), low=noise_low, high=noise_high)
