"""Reusable Gymnasium wrappers."""

from __future__ import annotations

from typing import Any, SupportsFloat

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


class ClearanceShaping(gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """
    Potential-based reward shaping (Ng, Harada and Russell, 1999) on the lidar course's clearance: the reward of
    a step from ``s`` to ``s'`` gains ``gamma * phi(s') - phi(s)``, with the potential
    ``phi(s) = -scale * max(0, 1 - clearance(s) / safe_distance)`` (0 with at least ``safe_distance`` of free space
    around the robot, ``-scale`` touching) and ``phi = 0`` after the last step of a terminated episode.

    With the algorithm's own discount as ``gamma`` the shaping leaves the optimal policies of the task unchanged
    (the shaping terms of an episode telescope to ``-phi(s_0)`` plus a discounted ``phi`` of the last state), while
    every step near a wall or an obstacle now says so, long before a collision does. Success (``is_success``) and
    the rest of ``info`` are the environment's; ``info["shaping"]`` holds the step's term.

    :param env: A lidar course environment (its ``info`` has ``clearance``), wrapped or not
    :param gamma: The discount of the algorithm trained on it (the entry's ``gamma``)
    :param safe_distance: Clearance from which the potential is 0 [m]
    :param scale: Depth of the potential at zero clearance (the collision reward of the course is -1)
    """

    def __init__(self, env: gym.Env[np.ndarray, np.ndarray], gamma: float, safe_distance: float = 0.5, scale: float = 0.5):
        super().__init__(env)
        if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not 0.0 < gamma <= 1.0:
            raise ValueError(f"ClearanceShaping: `gamma` must be in (0, 1] (the algorithm's discount), got {gamma!r}.")
        for name, value in (("safe_distance", safe_distance), ("scale", scale)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0.0:
                raise ValueError(f"ClearanceShaping: `{name}` must be a finite number > 0, got {value!r}.")
        self.gamma = float(gamma)
        self.safe_distance = float(safe_distance)
        self.scale = float(scale)
        self._potential = 0.0

    def potential(self, info: dict[str, Any]) -> float:
        """``phi`` of the state whose ``info`` is given."""
        if "clearance" not in info:
            raise KeyError("ClearanceShaping needs `clearance` in the environment's info (the lidar course's).")
        return -self.scale * max(0.0, 1.0 - float(info["clearance"]) / self.safe_distance)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        self._potential = self.potential(info)
        return observation, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        potential = 0.0 if terminated else self.potential(info)
        shaping = self.gamma * potential - self._potential
        self._potential = potential
        return observation, float(reward) + shaping, terminated, truncated, {**info, "shaping": shaping}
