"""Reusable Gymnasium wrappers."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding


class UniformObservationNoise(gym.ObservationWrapper[np.ndarray, Any, np.ndarray]):
    """
    Add i.i.d. uniform noise in ``[low, high]`` to every channel of a ``Box`` observation.

    This is the disturbance of the ADC paper's noisy experiments (Section 5.2 uses ``[-0.1, 0.1]``).
    The observation space is widened by the noise bounds so that noisy observations stay inside it.
    The noise has its own random generator, seeded by ``reset(seed=...)``: the same seed gives the
    same noise sequence, and drawing noise leaves the wrapped environment's generator untouched.

    :param env: Environment with a ``Box`` observation space
    :param low: Lower bound of the noise (a scalar, or one value per observation channel)
    :param high: Upper bound of the noise (same shape rules as ``low``); ``high >= low``
    """

    def __init__(self, env: gym.Env[np.ndarray, Any], low: float | np.ndarray = -0.1, high: float | np.ndarray = 0.1):
        super().__init__(env)
        if not isinstance(env.observation_space, spaces.Box):
            raise TypeError(
                f"UniformObservationNoise needs a Box observation space, got {env.observation_space!r} (parameter `env`)."
            )
        box = env.observation_space
        noise_low = np.broadcast_to(np.asarray(low, dtype=np.float64), box.shape)
        noise_high = np.broadcast_to(np.asarray(high, dtype=np.float64), box.shape)
        if not (np.all(np.isfinite(noise_low)) and np.all(np.isfinite(noise_high))):
            raise ValueError(f"UniformObservationNoise: `low` and `high` must be finite, got low={low!r}, high={high!r}.")
        if np.any(noise_high < noise_low):
            raise ValueError(f"UniformObservationNoise: `high` must be >= `low`, got low={low!r}, high={high!r}.")
        self.noise_low = noise_low.astype(box.dtype)
        self.noise_high = noise_high.astype(box.dtype)
        self.observation_space = spaces.Box(
            low=(box.low + self.noise_low).astype(box.dtype),
            high=(box.high + self.noise_high).astype(box.dtype),
            shape=box.shape,
            dtype=box.dtype,
        )
        self._noise_rng, _ = seeding.np_random()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self._noise_rng, _ = seeding.np_random(seed)
        return super().reset(seed=seed, options=options)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        noise = self._noise_rng.uniform(self.noise_low, self.noise_high)
        return (observation + noise).astype(self.observation_space.dtype)
