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

    def set_total_steps(self, total_steps: int) -> None:
        """
        Set the count (a resumed run, after replaying the episode in progress, which counted its steps again).

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
    SB3's ``make_vec_env`` for a run: ``n_envs`` environments of ``config`` (``env_kwargs`` and ``env_wrapper``
    applied outside the ``Monitor``, and outside them all an
    :class:`~sb3_adc.experiment.continuation.EpisodeRecorder`, which checkpoints keep for an exact resume),
    seeded ``seed, seed + 1, ...``; :func:`wrap_vec_env` then applies ``normalize`` and ``frame_stack``. With a
    ``monitor_dir``, each environment counts its steps across episodes (:class:`TotalStepsInfo`, continuing from
    ``steps_offset`` on resume) and its ``Monitor`` records that count.

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
    Wrap ``venv`` in :class:`~sb3_adc.experiment.divergence.FiniteCheck` (SB3's ``VecCheckNan``: an error at the
    first NaN or inf), then ``VecNormalize`` and ``VecFrameStack`` if the config asks for them (the RL Zoo's order).

    Every environment of a run goes through here, so training and evaluation environments are wrapped alike,
    as SB3's ``sync_envs_normalization`` needs.

    :param config: The resolved hyperparameters
    :param venv: The environments
    :param training: Whether the statistics are updated and rewards normalized (``False`` for evaluation)
    :param statistics: A saved ``VecNormalize`` to load the statistics from (a file, or one read already)
    """
    # Inside VecNormalize: a NaN is caught before it spoils the statistics, and named as the environment gave it.
    venv = FiniteCheck(venv, "training" if training else "evaluation")
    if config.normalize is not None:
        normalized = load_vec_normalize(statistics, venv) if statistics is not None else VecNormalize(venv, **config.normalize)
        if not training:
            normalized.training = False
            normalized.norm_reward = False
        venv = normalized
    if config.frame_stack is not None:
        venv = VecFrameStack(venv, config.frame_stack)
    return venv
