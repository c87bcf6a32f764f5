"""A dueling Q-network policy for SB3's :class:`~stable_baselines3.DQN` (Wang et al., 2016)."""

from __future__ import annotations

from typing import Any

import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, create_mlp
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from stable_baselines3.dqn.policies import DQNPolicy, QNetwork
from torch import nn


class DuelingQNetwork(QNetwork):
    """
    Dueling Q-network: a shared trunk followed by a value stream ``V(s)`` and an advantage stream ``A(s, a)``,
    aggregated with the mean-centred rule of Wang et al. (2016), Eq. 9 (the ADC paper's Eq. 12):
    ``Q(s, a) = V(s) + A(s, a) - mean_a' A(s, a')``.

    :param observation_space: Observation space
    :param action_space: Action space (``Discrete``)
    :param features_extractor: The features extractor
    :param features_dim: Number of features
    :param net_arch: Hidden layer sizes of the shared trunk (``[]``: the streams read the features)
    :param value_net_arch: Hidden layer sizes of the value stream (its output layer has 1 unit)
    :param advantage_net_arch: Hidden layer sizes of the advantage stream (its output layer has one unit per
        action)
    :param activation_fn: Activation function
    :param normalize_images: Whether to normalize images or not, dividing by 255.0 (True by default)
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Discrete,
        features_extractor: BaseFeaturesExtractor,
        features_dim: int,
        net_arch: list[int] | None = None,
        value_net_arch: list[int] | None = None,
        advantage_net_arch: list[int] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        normalize_images: bool = True,
    ) -> None:
        # QNetwork.__init__ would build a plain Q-head: set up the BasePolicy part only.
        BasePolicy.__init__(
            self,
            observation_space,
            action_space,
            features_extractor=features_extractor,
            normalize_images=normalize_images,
        )
        self.net_arch = list(net_arch) if net_arch is not None else [64]
        self.value_net_arch = list(value_net_arch) if value_net_arch is not None else [64]
        self.advantage_net_arch = list(advantage_net_arch) if advantage_net_arch is not None else [64]
        self.activation_fn = activation_fn
        self.features_dim = features_dim
        n_actions = int(self.action_space.n)
        trunk_dim = self.net_arch[-1] if self.net_arch else features_dim
        self.trunk = nn.Sequential(*create_mlp(features_dim, -1, self.net_arch, activation_fn))
        self.value_stream = nn.Sequential(*create_mlp(trunk_dim, 1, self.value_net_arch, activation_fn))
        self.advantage_stream = nn.Sequential(*create_mlp(trunk_dim, n_actions, self.advantage_net_arch, activation_fn))

    def value_and_advantages(self, obs: PyTorchObs) -> tuple[th.Tensor, th.Tensor]:
        """
        The two streams before aggregation.

        :param obs: Observation
        :return: ``V(s)`` of shape ``(batch, 1)`` and ``A(s, .)`` of shape ``(batch, n_actions)``
        """
        hidden = self.trunk(self.extract_features(obs, self.features_extractor))
        return self.value_stream(hidden), self.advantage_stream(hidden)

    def forward(self, obs: PyTorchObs) -> th.Tensor:
        """
        Predict the Q-values.

        :param obs: Observation
        :return: ``Q(s, .)`` of shape ``(batch, n_actions)``
        """
        value, advantages = self.value_and_advantages(obs)
        return value + advantages - advantages.mean(dim=1, keepdim=True)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(value_net_arch=self.value_net_arch, advantage_net_arch=self.advantage_net_arch)
        return data


class DuelingDQNPolicy(DQNPolicy):
    """
    DQN policy whose Q-network (and target network) is a :class:`DuelingQNetwork`.

    Use it as ``DQN(DuelingDQNPolicy, env)``, or in a hyperparameter file as
    ``policy: sb3_adc.baselines.DuelingDQNPolicy``. The ADC paper's Pendulum baseline (25 discrete actions,
    Section 5.1.1) is ``dict(net_arch=[30], advantage_net_arch=[100], value_net_arch=[20])`` on
    :class:`~sb3_adc_envs.wrappers.DiscretizedActions` with ``n_actions=25``.

    The other parameters (``activation_fn``, ``features_extractor_class``, ``features_extractor_kwargs``,
    ``normalize_images``, ``optimizer_class``, ``optimizer_kwargs``), by position after ``net_arch`` or by name, are
    those of SB3's :class:`~stable_baselines3.dqn.policies.DQNPolicy`, with its defaults.

    :param observation_space: Observation space
    :param action_space: Action space (``Discrete``)
    :param lr_schedule: Learning rate schedule (could be constant)
    :param net_arch: Hidden layer sizes of the shared trunk (default ``[64]``)
    :param value_net_arch: Hidden layer sizes of the value stream (default ``[64]``)
    :param advantage_net_arch: Hidden layer sizes of the advantage stream (default ``[64]``)
    """

    q_net: DuelingQNetwork
    q_net_target: DuelingQNetwork

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Discrete,
        lr_schedule: Schedule,
        net_arch: list[int] | None = None,
        *args: Any,
        value_net_arch: list[int] | None = None,
        advantage_net_arch: list[int] | None = None,
        **kwargs: Any,
    ) -> None:
        if not isinstance(action_space, spaces.Discrete):
            raise TypeError(
                f"DuelingDQNPolicy needs a Discrete action space, got {action_space!r}; wrap a Box action space with "
                "sb3_adc_envs.wrappers.DiscretizedActions."
            )
        # DQNPolicy.__init__ builds the networks (through ``make_q_net``): the stream sizes must be set first.
        self.dueling_kwargs: dict[str, Any] = {
            "value_net_arch": [64] if value_net_arch is None else list(value_net_arch),
            "advantage_net_arch": [64] if advantage_net_arch is None else list(advantage_net_arch),
        }
        net_arch = [64] if net_arch is None else list(net_arch)
        super().__init__(observation_space, action_space, lr_schedule, net_arch, *args, **kwargs)

    def make_q_net(self) -> DuelingQNetwork:
        # Make sure we always have separate networks for features extractors etc
        net_args = self._update_features_extractor(self.net_args, features_extractor=None)
        return DuelingQNetwork(**net_args, **self.dueling_kwargs).to(self.device)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(self.dueling_kwargs)
        return data
