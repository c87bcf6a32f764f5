"""SB3's DDPG with its own critic learning rate, as the DDPG baseline of the ADC paper, and the averaged actor ADC can
deploy."""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3 import DDPG
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.td3.policies import TD3Policy

from sb3_adc.adc.policies import refuse_adc_policy
from sb3_adc.common.actor_average import TD3WithActorAverage
from sb3_adc.common.critic_learning_rate import TD3WithCriticLearningRate
from sb3_adc.common.model_files import CheckedModelFiles


class SplitRateDDPG(CheckedModelFiles, TD3WithCriticLearningRate, TD3WithActorAverage, DDPG):
    """
    Deep Deterministic Policy Gradient with separate actor and critic learning rates.

    SB3's :class:`~stable_baselines3.DDPG` uses one learning rate for both networks; the ADC paper's DDPG and
    vanilla actor-critic baselines use an actor rate ``a`` and a critic rate ``c = 2a`` (Tables 1-3). Its
    ``MlpPolicy`` also takes ``actor_average_tau``: the deployed policy is then a Polyak average of the actor's
    iterates, as :class:`~sb3_adc.ADC` and :class:`~sb3_adc.baselines.AveragedActorTD3` can deploy
    (:mod:`sb3_adc.common.actor_average`; DDPG updates its actor at every gradient step). With
    ``critic_learning_rate=None`` and no ``actor_average_tau`` (the defaults) this class is SB3's DDPG, update for
    update.

    Unlike SB3's DDPG, it refuses an :class:`~sb3_adc.adc.policies.ADCPolicy` (SB3's ``DDPG.load`` of an ADC
    model file silently builds and trains the ADC policy), and its ``load`` and ``set_parameters`` errors name
    the file and, for parameters of other shapes, the tensors (see :meth:`sb3_adc.ADC.load`).

    :param policy: The policy model to use (MlpPolicy, CnnPolicy, ...)
    :param env: The environment to learn from (if registered in Gym, can be str)
    :param learning_rate: learning rate of the actor's optimizer (a float or a schedule of the progress
        remaining, from 1 to 0)
    :param critic_learning_rate: learning rate of the critic's optimizer (a float or a schedule); ``None``
        uses ``learning_rate``
    :param buffer_size: size of the replay buffer
    :param learning_starts: how many steps of the model to collect transitions for before learning starts
    :param batch_size: Minibatch size for each gradient update
    :param tau: the soft update coefficient ("Polyak update", between 0 and 1)
    :param gamma: the discount factor
    :param train_freq: Update the model every ``train_freq`` steps, or a tuple such as ``(2, "episode")``
    :param gradient_steps: How many gradient steps to do after each rollout (``-1``: as many as steps collected)
    :param action_noise: the action noise type (None by default)
    :param replay_buffer_class: Replay buffer class to use (for instance ``HerReplayBuffer``)
    :param replay_buffer_kwargs: Keyword arguments to pass to the replay buffer on creation.
    :param optimize_memory_usage: Enable a memory efficient variant of the replay buffer
    :param n_steps: When ``n_steps > 1``, uses n-step returns when updating the Q-value network
    :param tensorboard_log: the log location for tensorboard (if None, no logging)
    :param policy_kwargs: additional arguments to be passed to the policy on creation
    :param verbose: Verbosity level: 0 for no output, 1 for info messages, 2 for debug messages
    :param seed: Seed for the pseudo random generators
    :param device: Device (cpu, cuda, ...) on which the code should be run.
    :param _init_setup_model: Whether or not to build the network at the creation of the instance
    """

    def __init__(
        self,
        policy: str | type[TD3Policy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 1e-3,
        critic_learning_rate: float | Schedule | None = None,
        buffer_size: int = 1_000_000,
        learning_starts: int = 100,
        batch_size: int = 256,
        tau: float = 0.005,
        gamma: float = 0.99,
        train_freq: int | tuple[int, str] = 1,
        gradient_steps: int = 1,
        action_noise: ActionNoise | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        optimize_memory_usage: bool = False,
        n_steps: int = 1,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ):
        super().__init__(
            policy=policy,
            env=env,
            learning_rate=learning_rate,
            buffer_size=buffer_size,
            learning_starts=learning_starts,
            batch_size=batch_size,
            tau=tau,
            gamma=gamma,
            train_freq=train_freq,
            gradient_steps=gradient_steps,
            action_noise=action_noise,
            replay_buffer_class=replay_buffer_class,
            replay_buffer_kwargs=replay_buffer_kwargs,
            optimize_memory_usage=optimize_memory_usage,
            n_steps=n_steps,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=False,
        )
        self.critic_learning_rate = critic_learning_rate
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        refuse_adc_policy(self.policy_class, "DDPG")
        super()._setup_model()
