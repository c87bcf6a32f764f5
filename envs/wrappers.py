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
        # From the bounds in the observation dtype, as `rng.uniform(self.noise_low, self.noise_high)` would draw.
        self._low = self.noise_low.astype(np.float64)
        self._span = self.noise_high.astype(np.float64) - self._low
        self._buffer = np.empty(box.shape, dtype=np.float64)
        self._noise_rng, _ = seeding.np_random()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self._noise_rng, _ = seeding.np_random(seed)
        return super().reset(seed=seed, options=options)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        # low + (high - low) * U[0, 1), in a preallocated buffer: the same draws as `rng.uniform(low, high)`,
        # without its per-call allocations.
        noisy = self._buffer
        self._noise_rng.random(out=noisy)
        noisy *= self._span
        noisy += self._low
        noisy += observation
        return noisy.astype(self.observation_space.dtype)


class DiscretizedActions(gym.ActionWrapper[Any, np.int64, np.ndarray]):
    """
    Replace a bounded ``Box`` action space by ``Discrete`` evenly spaced actions, for value-based methods
    such as DQN on continuous-control tasks (the ADC paper uses 25 actions on Pendulum, Section 5.1.1).

    Each of the ``d`` action dimensions takes ``n_actions`` evenly spaced values from ``low`` to ``high``
    (both included); the discrete space enumerates the grid of their combinations, ``n_actions ** d`` actions,
    the last dimension varying fastest. With one dimension, action ``0`` is ``low``, action ``n_actions - 1``
    is ``high``, and action ``i`` is ``low + i * (high - low) / (n_actions - 1)``.

    :param env: Environment with a ``Box`` action space with finite bounds
    :param n_actions: Number of values per action dimension (>= 2)
    """

    #: Largest number of discrete actions (``n_actions ** d``) accepted.
    MAX_ACTIONS = 1_000_000

    def __init__(self, env: gym.Env[Any, np.ndarray], n_actions: int = 25):
        super().__init__(env)
        box = env.action_space
        if not isinstance(box, spaces.Box):
            raise TypeError(f"DiscretizedActions needs a Box action space, got {box!r} (parameter `env`).")
        if not (np.all(np.isfinite(box.low)) and np.all(np.isfinite(box.high))):
            raise ValueError(f"DiscretizedActions needs finite action bounds, got low={box.low}, high={box.high}.")
        if isinstance(n_actions, bool) or not isinstance(n_actions, (int, np.integer)) or n_actions < 2:
            raise ValueError(f"DiscretizedActions: `n_actions` must be an integer >= 2, got {n_actions!r}.")
        n_dims = int(np.prod(box.shape))
        if n_actions**n_dims > self.MAX_ACTIONS:
            raise ValueError(
                f"DiscretizedActions: n_actions ** action_dim = {n_actions}**{n_dims} exceeds {self.MAX_ACTIONS} actions; "
                "use a smaller `n_actions`."
            )
        self.n_actions = int(n_actions)
        self.grid_shape = (self.n_actions,) * n_dims
        fractions = np.linspace(0.0, 1.0, self.n_actions)
        low, high = box.low.reshape(-1).astype(np.float64), box.high.reshape(-1).astype(np.float64)
        #: ``(action_dim, n_actions)`` values of each action dimension.
        self.action_values = low[:, None] + fractions[None, :] * (high - low)[:, None]
        # Exact bounds at both ends, whatever the rounding of the interpolation.
        self.action_values[:, 0], self.action_values[:, -1] = low, high
        self._box = box
        self._discrete = spaces.Discrete(self.n_actions**n_dims)
        self.action_space = self._discrete

    def action(self, action: np.int64) -> np.ndarray:
        """
        The continuous action of a discrete one.

        :param action: Index in ``[0, n_actions ** action_dim)``
        :return: The ``Box`` action
        """
        index = int(np.asarray(action).item())
        if not 0 <= index < self._discrete.n:
            raise ValueError(f"DiscretizedActions: action {index} is outside [0, {int(self._discrete.n)}).")
        digits = np.unravel_index(index, self.grid_shape)
        values = self.action_values[np.arange(len(digits)), np.asarray(digits)]
        return values.reshape(self._box.shape).astype(self._box.dtype)
