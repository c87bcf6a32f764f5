from __future__ import annotations

from typing import Any, NamedTuple

import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BaseModel
from stable_baselines3.common.preprocessing import get_action_dim
from stable_baselines3.common.torch_layers import (
    BaseFeaturesExtractor,
    CombinedExtractor,
    FlattenExtractor,
    NatureCNN,
    create_mlp,
)
from stable_baselines3.common.type_aliases import Schedule
from stable_baselines3.td3.policies import TD3Policy
from torch import nn

from sb3_adc.adc.intervals import Aggregation, Interpolation, UniformIntervalPartition, aggregate, validate_interval_options
from sb3_adc.common.spaces import check_action_space


class DuelingEstimate(NamedTuple):
    """
    The outputs of one dueling critic network for a batch of (observation, action) pairs.

    :param q_value: ``(batch, 1)`` aggregated Q-value
    :param value: ``(batch, 1)`` output of the value stream
    :param advantages: ``(batch, action_dim, n_intervals)`` output of the advantage stream
    """

    q_value: th.Tensor
    value: th.Tensor
    advantages: th.Tensor


class DuelingIntervalNetwork(nn.Module):
    """
    One dueling critic network: a shared trunk over ``[features, action]`` (the paper's first layer
    ``theta^Q``), a value stream (``beta``) and an advantage stream (``alpha``) with ``n_intervals`` outputs
    per action dimension.

    :param input_dim: ``features_dim + action_dim``
    :param action_dim: Number of action dimensions (advantage branches)
    :param n_intervals: Number of intervals per action dimension
    :param net_arch: Hidden layer sizes of the shared trunk
    :param value_net_arch: Hidden layer sizes of the value stream (its output layer has 1 unit)
    :param advantage_net_arch: Hidden layer sizes of the advantage stream (its output layer has
        ``action_dim * n_intervals`` units)
    :param activation_fn: Activation function
    """

    def __init__(
        self,
        input_dim: int,
        action_dim: int,
        n_intervals: int,
        net_arch: list[int],
        value_net_arch: list[int],
        advantage_net_arch: list[int],
        activation_fn: type[nn.Module],
    ):
        super().__init__()
        self.action_dim = action_dim
        self.n_intervals = n_intervals
        trunk_layers = create_mlp(input_dim, -1, net_arch, activation_fn)
        trunk_dim = net_arch[-1] if net_arch else input_dim
        # An empty trunk is the identity: both streams then see [features, action] directly.
        self.trunk = nn.Sequential(*trunk_layers)
        self.value_stream = nn.Sequential(*create_mlp(trunk_dim, 1, value_net_arch, activation_fn))
        self.advantage_stream = nn.Sequential(
            *create_mlp(trunk_dim, action_dim * n_intervals, advantage_net_arch, activation_fn)
        )

    def forward(self, features_actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        :param features_actions: ``(batch, features_dim + action_dim)``
        :return: value ``(batch, 1)`` and advantages ``(batch, action_dim, n_intervals)``
        """
        hidden = self.trunk(features_actions)
        advantages = self.advantage_stream(hidden).view(-1, self.action_dim, self.n_intervals)
        return self.value_stream(hidden), advantages


class DuelingIntervalCritic(BaseModel):
    """
    Dueling interval critic of the Actor-Dueling-Critic method.

    Actor-Dueling-Critic paper, Section 4 and Figure 3: a shared layer over (state, action), a value stream
    ``V`` and an advantage stream with one output per uniform interval of the action range, combined as
    ``Q = V + A(s, z_a) - mean_z A(s, z)`` (Eq. 13-14), or with ``max`` in place of ``mean`` (Eq. 11).

    It honours the contract of SB3's :class:`~stable_baselines3.common.policies.ContinuousCritic`, so
    TD3's update machinery applies: ``forward`` returns one ``(batch, 1)`` Q tensor per critic network,
    ``q1_forward`` evaluates the first network only, and a features extractor shared with the actor is
    trained by the actor loss only.

    Extensions beyond the paper (which covers 1-D actions): with several action dimensions the advantage
    is factorised, one branch of ``n_intervals`` per dimension, each centred on its own and summed (as in
    action-branching dueling networks); ``advantage_interpolation="linear"`` makes the advantage piecewise
    linear in the action; ``n_critics=2`` gives a twin, clipped double-Q variant.

    :param observation_space: Observation space
    :param action_space: Action space (a bounded ``Box``)
    :param net_arch: Hidden layer sizes of the shared trunk over ``[features, action]``
    :param features_extractor: Network to extract features (a CNN for images, ``nn.Flatten()`` otherwise)
    :param features_dim: Number of features
    :param activation_fn: Activation function
    :param normalize_images: Whether to normalize images or not, dividing by 255.0 (True by default)
    :param n_critics: Number of critic networks (1 in the paper; 2 for clipped double-Q)
    :param share_features_extractor: Whether the features extractor is shared with the actor
    :param n_intervals: Number of uniform intervals per action dimension (the paper uses 100 on Pendulum)
    :param value_net_arch: Hidden layer sizes of the value stream (the paper's Pendulum net: ``[20]``)
    :param advantage_net_arch: Hidden layer sizes of the advantage stream (the paper: ``[]``, the interval
        outputs sit directly on the trunk)
    :param aggregation: ``"mean"`` (Eq. 12-14, default) or ``"max"`` (Eq. 11)
    :param advantage_interpolation: ``"none"`` (the paper: advantage of the interval containing the action)
        or ``"linear"`` (interpolate between the two nearest interval centres)
    """

    features_extractor: BaseFeaturesExtractor

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        net_arch: list[int],
        features_extractor: BaseFeaturesExtractor,
        features_dim: int,
        activation_fn: type[nn.Module] = nn.ReLU,
        normalize_images: bool = True,
        n_critics: int = 1,
        share_features_extractor: bool = True,
        n_intervals: int = 100,
        value_net_arch: list[int] | None = None,
        advantage_net_arch: list[int] | None = None,
        aggregation: Aggregation = "mean",
        advantage_interpolation: Interpolation = "none",
    ):
        super().__init__(
            observation_space,
            action_space,
            features_extractor=features_extractor,
            normalize_images=normalize_images,
        )
        check_action_space(action_space)
        validate_interval_options(n_intervals, aggregation, advantage_interpolation)
        if isinstance(n_critics, bool) or not isinstance(n_critics, int) or n_critics < 1:
            raise ValueError(f"`n_critics` must be an integer >= 1, got {n_critics!r}.")

        action_dim = get_action_dim(self.action_space)
        self.share_features_extractor = share_features_extractor
        self.n_critics = n_critics
        self.n_intervals = n_intervals
        self.aggregation: Aggregation = aggregation
        self.advantage_interpolation: Interpolation = advantage_interpolation
        self.partition = UniformIntervalPartition(n_intervals)
        self.q_networks: list[DuelingIntervalNetwork] = []
        for idx in range(n_critics):
            q_net = DuelingIntervalNetwork(
                features_dim + action_dim,
                action_dim,
                n_intervals,
                net_arch,
                list(value_net_arch or []),
                list(advantage_net_arch or []),
                activation_fn,
            )
            self.add_module(f"qf{idx}", q_net)
            self.q_networks.append(q_net)

    def _estimate(self, q_net: DuelingIntervalNetwork, features: th.Tensor, actions: th.Tensor) -> DuelingEstimate:
        value, advantages = q_net(th.cat([features, actions], dim=1))
        selected = self.partition.select(advantages, actions, self.advantage_interpolation)
        return DuelingEstimate(aggregate(value, advantages, selected, self.aggregation), value, advantages)

    def estimate(self, obs: th.Tensor, actions: th.Tensor) -> tuple[DuelingEstimate, ...]:
        """
        Q-value, value and advantages of every critic network.

        Gradients follow the rules of :meth:`forward`.

        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)`` in ``[-1, 1]``
        :return: One :class:`DuelingEstimate` per critic network
        """
        # Learn the features extractor using the policy loss only
        # when the features_extractor is shared with the actor
        with th.set_grad_enabled(not self.share_features_extractor):
            features = self.extract_features(obs, self.features_extractor)
        return tuple(self._estimate(q_net, features, actions) for q_net in self.q_networks)

    def forward(self, obs: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, ...]:
        """
        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)`` in ``[-1, 1]``
        :return: One ``(batch, 1)`` Q-value tensor per critic network
        """
        return tuple(estimate.q_value for estimate in self.estimate(obs, actions))

    def q1_forward(self, obs: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        Q-value of the first critic network only, with the features extractor frozen (used for the actor loss).

        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: ``(batch, 1)``
        """
        with th.no_grad():
            features = self.extract_features(obs, self.features_extractor)
        return self._estimate(self.q_networks[0], features, actions).q_value

    def decompose(self, obs: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """
        The two streams of the first critic network, for diagnostics and tests.

        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: ``value`` of shape ``(batch, 1)``, ``advantages`` of shape ``(batch, action_dim, n_intervals)``
            (raw, before centring) and ``interval_index`` of shape ``(batch, action_dim)``, the interval that
            contains each action component
        """
        features = self.extract_features(obs, self.features_extractor)
        value, advantages = self.q_networks[0](th.cat([features, actions], dim=1))
        return value, advantages, self.partition.index(actions)


class ADCPolicy(TD3Policy):
    """
    Policy class (an actor and a dueling interval critic, with their target networks) for ADC.

    Actor-Dueling-Critic paper, Figure 3: the actor is TD3's deterministic actor; the critic is a
    :class:`DuelingIntervalCritic`. The paper's Pendulum network (one hidden layer of 30 units in the actor
    and in the critic trunk, 100 intervals, a value stream of 20 units) is
    ``dict(net_arch=dict(pi=[30], qf=[30]), n_intervals=100, value_net_arch=[20])``.

    :param observation_space: Observation space
    :param action_space: Action space (a bounded ``Box``)
    :param lr_schedule: Learning rate schedule (could be constant); ADC sets the critic optimizer's rate
        from its own ``critic_learning_rate``
    :param net_arch: The actor's hidden layers and the critic trunk's hidden layers: a list for both, or
        ``dict(pi=[...], qf=[...])``
    :param activation_fn: Activation function
    :param features_extractor_class: Features extractor to use.
    :param features_extractor_kwargs: Keyword arguments to pass to the features extractor.
    :param normalize_images: Whether to normalize images or not, dividing by 255.0 (True by default)
    :param optimizer_class: The optimizer to use, ``th.optim.Adam`` by default
    :param optimizer_kwargs: Additional keyword arguments, excluding the learning rate, to pass to the optimizer
    :param n_critics: Number of dueling critic networks (1 in the paper)
    :param share_features_extractor: Whether to share or not the features extractor between the actor and
        the critic (this saves computation time)
    :param n_intervals: Number of uniform intervals per action dimension
    :param value_net_arch: Hidden layer sizes of the value stream
    :param advantage_net_arch: Hidden layer sizes of the advantage stream
    :param aggregation: ``"mean"`` (Eq. 12-14) or ``"max"`` (Eq. 11)
    :param advantage_interpolation: ``"none"`` (the paper) or ``"linear"``
    """

    critic: DuelingIntervalCritic  # type: ignore[assignment]
    critic_target: DuelingIntervalCritic  # type: ignore[assignment]

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = FlattenExtractor,
        features_extractor_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = True,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        n_critics: int = 1,
        share_features_extractor: bool = False,
        n_intervals: int = 100,
        value_net_arch: list[int] | None = None,
        advantage_net_arch: list[int] | None = None,
        aggregation: Aggregation = "mean",
        advantage_interpolation: Interpolation = "none",
    ):
        check_action_space(action_space)
        validate_interval_options(n_intervals, aggregation, advantage_interpolation)
        # TD3Policy.__init__ builds the networks (through ``make_critic``), so the dueling options must be
        # in place before it runs.
        self.dueling_kwargs: dict[str, Any] = {
            "n_intervals": n_intervals,
            "value_net_arch": list(value_net_arch or []),
            "advantage_net_arch": list(advantage_net_arch or []),
            "aggregation": aggregation,
            "advantage_interpolation": advantage_interpolation,
        }
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            net_arch=net_arch,
            activation_fn=activation_fn,
            features_extractor_class=features_extractor_class,
            features_extractor_kwargs=features_extractor_kwargs,
            normalize_images=normalize_images,
            optimizer_class=optimizer_class,
            optimizer_kwargs=optimizer_kwargs,
            n_critics=n_critics,
            share_features_extractor=share_features_extractor,
        )

    @property
    def n_intervals(self) -> int:
        """Number of uniform intervals per action dimension of the critic."""
        return int(self.dueling_kwargs["n_intervals"])

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(self.dueling_kwargs)
        return data

    def make_critic(self, features_extractor: BaseFeaturesExtractor | None = None) -> DuelingIntervalCritic:  # type: ignore[override]
        critic_kwargs = self._update_features_extractor(self.critic_kwargs, features_extractor)
        return DuelingIntervalCritic(**critic_kwargs, **self.dueling_kwargs).to(self.device)


MlpPolicy = ADCPolicy


class CnnPolicy(ADCPolicy):
    """
    Policy class for ADC with image observations: :class:`ADCPolicy` with SB3's ``NatureCNN`` features
    extractor by default. Parameters as :class:`ADCPolicy`.
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = NatureCNN,
        **kwargs: Any,
    ):
        super().__init__(
            observation_space, action_space, lr_schedule, net_arch, activation_fn, features_extractor_class, **kwargs
        )


class MultiInputPolicy(ADCPolicy):
    """
    Policy class for ADC with ``Dict`` observations: :class:`ADCPolicy` with SB3's ``CombinedExtractor``
    features extractor by default. Parameters as :class:`ADCPolicy`.
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = CombinedExtractor,
        **kwargs: Any,
    ):
        super().__init__(
            observation_space, action_space, lr_schedule, net_arch, activation_fn, features_extractor_class, **kwargs
        )
