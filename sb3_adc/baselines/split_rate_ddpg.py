"""SB3's DDPG with its own critic learning rate, as the DDPG baseline of the ADC paper."""

from __future__ import annotations

import io
import pathlib
from typing import Any, TypeVar

import torch as th
from stable_baselines3 import DDPG
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.type_aliases import GymEnv, Schedule, TensorDict
from stable_baselines3.td3.policies import TD3Policy

from sb3_adc.adc.policies import ADCPolicy
from sb3_adc.common.critic_learning_rate import TD3WithCriticLearningRate
from sb3_adc.common.model_files import check_parameter_shapes, model_file_errors

SelfSplitRateDDPG = TypeVar("SelfSplitRateDDPG", bound="SplitRateDDPG")


class SplitRateDDPG(TD3WithCriticLearningRate, DDPG):
    """
    Deep Deterministic Policy Gradient with separate actor and critic learning rates.

    SB3's :class:`~stable_baselines3.DDPG` uses one learning rate for both networks; the ADC paper's DDPG and
    vanilla actor-critic baselines use an actor rate ``a`` and a critic rate ``c = 2a`` (Tables 1-3). With
    ``critic_learning_rate=None`` (the default) this class is SB3's DDPG, update for update.

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
        if isinstance(self.policy_class, type) and issubclass(self.policy_class, ADCPolicy):
            raise TypeError(
                f"`policy` must be a DDPG (TD3Policy) policy, got the ADC policy {self.policy_class.__name__}. "
                "(Loading a model file saved by ADC? Load it with sb3_adc.ADC.load.)"
            )
        super()._setup_model()

    def set_parameters(
        self,
        load_path_or_dict: str | TensorDict,
        exact_match: bool = True,
        device: th.device | str = "auto",
    ) -> None:
        """
        Load parameters from a zip file or a dictionary of state dicts (see SB3's ``set_parameters``), after
        checking that their tensors have this model's shapes (the same spaces and network sizes). Errors are
        :class:`~sb3_adc.common.model_files.ModelFileError`, a ``ValueError`` that is also the type SB3 raises (a
        ``RuntimeError`` for tensors of another shape, where SB3 lets torch's size mismatch through).

        :param load_path_or_dict: Location of the saved data, or a dictionary of state dicts
        :param exact_match: If True, the given parameters must include every parameter of every module
        :param device: Device on which the code should run.
        """
        if isinstance(load_path_or_dict, dict):
            params = load_path_or_dict
        else:
            with model_file_errors(load_path_or_dict, type(self).__name__):
                _, params, _ = load_from_zip_file(load_path_or_dict, device=device, load_data=False)
        check_parameter_shapes(self, params)
        super().set_parameters(params, exact_match=exact_match, device=device)

    @classmethod
    def load(
        cls: type[SelfSplitRateDDPG],
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        **kwargs: Any,
    ) -> SelfSplitRateDDPG:
        """
        Load a model from a zip file (see SB3's ``BaseAlgorithm.load``), with errors that name the file:
        :class:`~sb3_adc.common.model_files.ModelFileError` (a ``ValueError`` that is also the type SB3 raises),
        among them a ``TypeError`` for a file saved by ADC; ``FileNotFoundError`` naming ``path``.

        :param path: path to the file (or a file-like) where to load the agent from
        :param env: the new environment to run the loaded model on (can be None if you only need prediction)
        :param device: Device on which the code should run.
        :param custom_objects: Dictionary of objects to replace upon loading
        :param print_system_info: Whether to print system info from the saved model
        :param force_reset: Force call to ``reset()`` before training to avoid unexpected behavior
        :param kwargs: extra arguments to change the model when loading
        :return: new model instance with loaded parameters
        """
        with model_file_errors(path, cls.__name__):
            return super().load(
                path,
                env=env,
                device=device,
                custom_objects=custom_objects,
                print_system_info=print_system_info,
                force_reset=force_reset,
                **kwargs,
            )
