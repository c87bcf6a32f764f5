"""Training and evaluation environments of a run, built from its resolved hyperparameters."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium as gym
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecFrameStack, VecNormalize

from sb3_adc.config import ExperimentConfig
from sb3_adc.experiment.divergence import FiniteCheck

#: ``info`` key (and monitor CSV column) with the number of steps the environment has taken during training.
TOTAL_STEPS_KEY = "total_steps"


class TotalStepsInfo(gym.Wrapper[Any, Any, Any, Any]):
    """
    Add ``info["total_steps"]``: the steps this environment has taken since training started, across episodes.

    The monitor CSV records it at the end of every episode, which places each episode on the timestep axis and
    lets a resumed run drop the episodes that came after its checkpoint.

    :param env: The environment
    :param offset: Steps already taken (by a run that is being resumed)
    """

    def __init__(self, env: gym.Env[Any, Any], offset: int = 0):
        super().__init__(env)
        self.total_steps = int(offset)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        self.total_steps += 1
        info[TOTAL_STEPS_KEY] = self.total_steps
        return observation, reward, terminated, truncated, info


def _env_factory(
    config: ExperimentConfig,
    env_kwargs: dict[str, Any],
    monitor_file: str | None,
    steps_offset: int,
    append_monitor: bool,
    render_mode: str | None,
) -> Callable[[], gym.Env]:
    def make() -> gym.Env:
        kwargs = dict(env_kwargs)
        if render_mode is not None:
            kwargs["render_mode"] = render_mode
        env: gym.Env = gym.make(config.env_id, **kwargs)
        if monitor_file is not None:
            env = TotalStepsInfo(env, steps_offset)
            env = Monitor(env, monitor_file, info_keywords=(TOTAL_STEPS_KEY,), override_existing=not append_monitor)
        else:
            env = Monitor(env)
        # As SB3's make_vec_env: wrappers go outside the Monitor, which records the environment's own returns.
        return config.wrap_env(env)

    return make


def make_vec_env(
    config: ExperimentConfig,
    n_envs: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
    monitor_files: list[str] | None = None,
    steps_offset: int = 0,
    append_monitor: bool = False,
    vec_env: str = "dummy",
    render_mode: str | None = None,
) -> VecEnv:
    """
    ``n_envs`` environments of ``config`` (``env_kwargs`` and ``env_wrapper`` applied), seeded
    ``seed, seed + 1, ...``; :func:`wrap_vec_env` then applies ``normalize`` and ``frame_stack``.

    :param config: The resolved hyperparameters
    :param n_envs: Number of environments
    :param seed: Seed of the first environment
    :param env_kwargs: Keyword arguments of ``gym.make`` replacing the config's (``None``: the config's)
    :param monitor_files: One monitor CSV path (without ``.monitor.csv``) per environment, or ``None`` for
        no monitor file
    :param steps_offset: Steps each environment has already taken (resumed runs)
    :param append_monitor: Append to existing monitor files instead of replacing them
    :param vec_env: ``dummy`` or ``subproc``
    :param render_mode: Gymnasium render mode passed to ``gym.make``
    """
    kwargs = config.env_kwargs if env_kwargs is None else env_kwargs
    factories = [
        _env_factory(
            config,
            kwargs,
            None if monitor_files is None else monitor_files[rank],
            steps_offset,
            append_monitor,
            render_mode,
        )
        for rank in range(n_envs)
    ]
    venv: VecEnv = SubprocVecEnv(factories) if vec_env == "subproc" else DummyVecEnv(factories)
    venv.seed(seed)
    venv.action_space.seed(seed)
    return venv


def wrap_vec_env(config: ExperimentConfig, venv: VecEnv, training: bool, statistics: str | None = None) -> VecEnv:
    """
    Wrap ``venv`` in :class:`~sb3_adc.experiment.divergence.FiniteCheck` (SB3's ``VecCheckNan``: an error at the
    first NaN or inf), then ``VecNormalize`` and ``VecFrameStack`` if the config asks for them (the RL Zoo's order).

    Every environment of a run goes through here, so training and evaluation environments are wrapped alike,
    as SB3's ``sync_envs_normalization`` needs.

    :param config: The resolved hyperparameters
    :param venv: The environments
    :param training: Whether the statistics are updated and rewards normalized (``False`` for evaluation)
    :param statistics: A saved ``VecNormalize`` to load the statistics from
    """
    # Inside VecNormalize: a NaN is caught before it spoils the statistics, and named as the environment gave it.
    venv = FiniteCheck(venv, "training" if training else "evaluation")
    if config.normalize is not None:
        normalized = VecNormalize.load(statistics, venv) if statistics is not None else VecNormalize(venv, **config.normalize)
        if not training:
            normalized.training = False
            normalized.norm_reward = False
        venv = normalized
    if config.frame_stack is not None:
        venv = VecFrameStack(venv, config.frame_stack)
    return venv
