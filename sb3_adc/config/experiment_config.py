"""The resolved hyperparameters of one experiment (algorithm x environment), ready to build envs and models."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import ActionNoise, NormalActionNoise, OrnsteinUhlenbeckActionNoise

from sb3_adc.common.noise import EpsilonGaussianNoise


@dataclass(frozen=True)
class NoiseSpec:
    """
    Exploration noise of an off-policy algorithm (``noise_type`` and its keys).

    :param noise_type: ``normal``, ``ornstein-uhlenbeck`` or ``epsilon-normal``
    :param std: Standard deviation, in SB3's scaled action units ([-1, 1]): one number, or one per action dimension
    :param epsilon_decay_steps: ``epsilon-normal``: steps (per environment) over which epsilon decays
    :param epsilon_initial: ``epsilon-normal``: epsilon at the start
    :param epsilon_final: ``epsilon-normal``: epsilon after ``epsilon_decay_steps``
    """

    noise_type: str
    std: float | list[float]
    epsilon_decay_steps: int = 0
    epsilon_initial: float = 1.0
    epsilon_final: float = 0.0

    def build(self, action_space: spaces.Space) -> ActionNoise:
        """
        The noise object for an action space.

        :param action_space: The environment's action space (a ``Box``)
        :raises ValueError: if the space is not a ``Box`` or the per-dimension std has the wrong length
        """
        if not isinstance(action_space, spaces.Box):
            raise ValueError(f"`noise_type: {self.noise_type}` needs a Box action space, got {action_space!r}.")
        n_actions = int(np.prod(action_space.shape))
        std = np.asarray(self.std, dtype=np.float64)
        if std.ndim != 0 and std.shape != (n_actions,):
            raise ValueError(f"`noise_std` has {std.size} values, the action space has {n_actions} dimensions.")
        mean, sigma = np.zeros(n_actions), np.broadcast_to(std, (n_actions,)).copy()
        if self.noise_type in ("normal", "ornstein-uhlenbeck"):
            noise_class = NormalActionNoise if self.noise_type == "normal" else OrnsteinUhlenbeckActionNoise
            return noise_class(mean=mean, sigma=sigma)
        epsilons: dict[str, Any] = {"initial_epsilon": self.epsilon_initial, "final_epsilon": self.epsilon_final}
        return EpsilonGaussianNoise(mean=mean, sigma=sigma, decay_steps=self.epsilon_decay_steps, **epsilons)


@dataclass
class ExperimentConfig:
    """
    One hyperparameter entry resolved into Python objects (by :func:`~sb3_adc.config.loader.load_hyperparams`).

    :param algo: The algorithm's name (``adc``, ``ddpg``, ...)
    :param env_id: The Gymnasium id of the environment
    :param source: Where the entry was read (file and entry)
    :param algorithm_class: The algorithm's class
    :param n_timesteps: Training budget (environment steps, all environments together)
    :param n_envs: Number of parallel training environments
    :param model_kwargs: Keyword arguments of the algorithm's constructor (``policy`` included, ``env`` not)
    :param env_kwargs: Keyword arguments of ``gym.make``
    :param env_wrappers: Wrapper classes applied to each environment, in order, with their keyword arguments
    :param normalize: ``VecNormalize`` keyword arguments, or ``None`` for no normalization
    :param frame_stack: Number of frames stacked by ``VecFrameStack``, or ``None``
    :param callbacks: Callback classes with their keyword arguments, added to training
    :param noise: The exploration noise, or ``None``
    :param saved: The entry as plain YAML data (defaults filled in), saved next to the run as ``config.yml``
    """

    algo: str
    env_id: str
    source: str
    algorithm_class: type[BaseAlgorithm]
    n_timesteps: int
    n_envs: int
    model_kwargs: dict[str, Any]
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    env_wrappers: list[tuple[Callable[..., gym.Env], dict[str, Any]]] = field(default_factory=list)
    normalize: dict[str, Any] | None = None
    frame_stack: int | None = None
    callbacks: list[tuple[Callable[..., BaseCallback], dict[str, Any]]] = field(default_factory=list)
    noise: NoiseSpec | None = None
    saved: dict[str, Any] = field(default_factory=dict)

    def wrap_env(self, env: gym.Env) -> gym.Env:
        """
        Apply the ``env_wrapper`` classes to one environment.

        :param env: The environment
        """
        for wrapper_class, kwargs in self.env_wrappers:
            env = wrapper_class(env, **kwargs)
        return env

    def make_callbacks(self) -> list[BaseCallback]:
        """New instances of the ``callback`` classes."""
        return [callback_class(**kwargs) for callback_class, kwargs in self.callbacks]

    def make_action_noise(self, action_space: spaces.Space) -> ActionNoise | None:
        """
        The exploration noise for the environment's action space (``None`` without ``noise_type``).

        :param action_space: The (wrapped) environment's action space
        """
        return None if self.noise is None else self.noise.build(action_space)
