"""Training and evaluation environments of a run, built from its resolved hyperparameters."""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecFrameStack, VecNormalize

from sb3_adc.common.safe_load import load_vec_normalize
from sb3_adc.config import ExperimentConfig
from sb3_adc.experiment.continuation import EpisodeRecorder
from sb3_adc.experiment.divergence import FiniteCheck

#: ``info`` key (and monitor CSV column) with the number of steps the environment has taken during training.
TOTAL_STEPS_KEY = "total_steps"


class TotalStepsInfo(gym.Wrapper[Any, Any, Any, Any]):
    """
    Add ``info["total_steps"]``, the steps taken since training started: the monitor CSV records it, which places
    each episode on the timestep axis (and lets a resume drop the episodes after its checkpoint).

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

    def set_total_steps(self, total_steps: int) -> None:
        """
        Set the count (after a resume's replay, which counted the episode's steps again).

        :param total_steps: Steps taken since training started
        """
        self.total_steps = int(total_steps)


def make_run_envs(
    config: ExperimentConfig,
    n_envs: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
    monitor_dir: str | None = None,
    steps_offset: int = 0,
    append_monitor: bool = False,
    vec_env: str = "dummy",
    render_mode: str | None = None,
) -> VecEnv:
    """
    SB3's ``make_vec_env`` for a run: ``n_envs`` environments of ``config`` seeded ``seed, seed + 1, ...``, its
    ``env_wrapper`` outside the ``Monitor`` and an :class:`~sb3_adc.experiment.continuation.EpisodeRecorder` outside
    all; with a ``monitor_dir``, the ``Monitor`` records :class:`TotalStepsInfo`'s count. :func:`wrap_vec_env` then
    applies ``normalize`` and ``frame_stack``.

    :param config: The resolved hyperparameters
    :param n_envs: Number of environments
    :param seed: Seed of the first environment
    :param env_kwargs: Keyword arguments of ``gym.make`` replacing the config's (``None``: the config's)
    :param monitor_dir: Folder of the ``{rank}.monitor.csv`` files (``None``: none written)
    :param steps_offset: Steps each environment has already taken (resumed runs)
    :param append_monitor: Append to existing monitor files instead of replacing them
    :param vec_env: ``dummy`` or ``subproc``
    :param render_mode: Gymnasium render mode passed to ``gym.make``
    """
    kwargs = dict(config.env_kwargs if env_kwargs is None else env_kwargs)
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    logged = monitor_dir is not None

    def make_env(**make_kwargs: Any) -> gym.Env:
        env: gym.Env = gym.make(config.env_id, **make_kwargs)
        return TotalStepsInfo(env, steps_offset) if logged else env

    def wrap(env: gym.Env) -> gym.Env:
        return EpisodeRecorder(config.wrap_env(env))

    return make_vec_env(
        make_env,
        n_envs,
        seed=seed,
        env_kwargs=kwargs,
        monitor_dir=monitor_dir,
        wrapper_class=wrap,
        vec_env_cls=SubprocVecEnv if vec_env == "subproc" else DummyVecEnv,
        monitor_kwargs={"info_keywords": (TOTAL_STEPS_KEY,), "override_existing": not append_monitor} if logged else None,
    )


def wrap_vec_env(
    config: ExperimentConfig, venv: VecEnv, training: bool, statistics: str | VecNormalize | None = None
) -> VecEnv:
    """
    Wrap ``venv`` in :class:`~sb3_adc.experiment.divergence.FiniteCheck` (SB3's ``VecCheckNan``), then
    ``VecNormalize`` and ``VecFrameStack`` if the config asks for them (the RL Zoo's order), for every environment
    of a run alike (as ``sync_envs_normalization`` needs).

    :param config: The resolved hyperparameters
    :param venv: The environments
    :param training: Whether the statistics are updated and rewards normalized (``False`` for evaluation)
    :param statistics: A saved ``VecNormalize`` to load the statistics from (a file, or one read already)
    """
    venv = FiniteCheck(venv, "training" if training else "evaluation")  # inside VecNormalize: before it spoils statistics
    if config.normalize is not None:
        normalized = load_vec_normalize(statistics, venv) if statistics is not None else VecNormalize(venv, **config.normalize)
        if not training:
            normalized.training = False
            normalized.norm_reward = False
        venv = normalized
    if config.frame_stack is not None:
        venv = VecFrameStack(venv, config.frame_stack)
    return venv
