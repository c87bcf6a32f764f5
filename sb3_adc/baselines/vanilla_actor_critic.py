"""The vanilla deterministic actor-critic baseline of the ADC paper: no experience replay, no target networks."""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.td3.policies import TD3Policy

from sb3_adc.baselines.split_rate_ddpg import SplitRateDDPG

#: The settings that make DDPG a vanilla online actor-critic (fixed; not parameters of the class).
VANILLA_SETTINGS: dict[str, Any] = {
    # A replay buffer of one transition: every update uses the transition just observed.
    "buffer_size": 1,
    "batch_size": 1,
    # One update per environment step.
    "train_freq": 1,
    "gradient_steps": 1,
    "n_steps": 1,
    # Targets copied from the online networks after every update: the TD target of the next update is
    # computed with the current networks, i.e. there are no target networks.
    "tau": 1.0,
}


class VanillaActorCritic(SplitRateDDPG):
    """
    Online deterministic actor-critic without experience replay or target networks.

    The "actor-critic" baseline of the ADC paper (Section 5.1.1: "The vanilla actor-critic approach we used
    without buffer", "we did not apply soft replacement"): after every environment step, one critic update
    on that single transition, with the TD target ``r + gamma * Q(s', mu(s'))`` from the current networks,
    then one deterministic policy-gradient step of the actor.

    It is SB3's DDPG (through :class:`SplitRateDDPG`, for the paper's separate critic rate) with the fixed
    settings of :data:`VANILLA_SETTINGS`: a replay buffer and batch of one transition, one gradient step
    per environment step, and ``tau=1`` (the target networks are copies of the online ones after every
    update, so they never lag behind).

    :param policy: The policy model to use (MlpPolicy, CnnPolicy, ...)
    :param env: The environment to learn from (if registered in Gym, can be str)
    :param learning_rate: learning rate of the actor's optimizer (a float or a schedule)
    :param critic_learning_rate: learning rate of the critic's optimizer; ``None`` uses ``learning_rate``
    :param learning_starts: how many steps to take uniformly random actions before learning starts
    :param gamma: the discount factor
    :param action_noise: the action noise type (None by default)
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
        learning_starts: int = 0,
        gamma: float = 0.99,
        action_noise: ActionNoise | None = None,
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
            critic_learning_rate=critic_learning_rate,
            learning_starts=learning_starts,
            gamma=gamma,
            action_noise=action_noise,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=False,
            **VANILLA_SETTINGS,
        )
        if _init_setup_model:
            self._setup_model()
