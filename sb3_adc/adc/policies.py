"""The ADC policies (TD3's actor with a dueling interval critic) and the critic itself, with its options."""

from __future__ import annotations

from typing import Any, Literal, get_args

import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BaseModel
from stable_baselines3.common.preprocessing import get_action_dim
from stable_baselines3.common.torch_layers import (
    BaseFeaturesExtractor,
    CombinedExtractor,
    NatureCNN,
)
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from sb3_adc.adc.designs import (
    ActionAdvantageNetwork,
    CriticNetwork,
    DuelingIntervalNetwork,
    NetworkSpec,
    StateValueIntervalNetwork,
)
from sb3_adc.adc.intervals import Aggregation, Interpolation, UniformIntervalPartition, validate_interval_options
from sb3_adc.adc.legendre import LegendreAdvantageNetwork
from sb3_adc.common.actor_average import ActorAverageTD3Policy
from sb3_adc.common.fast_update import fast_optimizer_kwargs
from sb3_adc.common.spaces import check_action_space

CriticDesign = Literal["paper", "state_value", "legendre", "action_network"]
#: The designs of the dueling interval critic (``critic_design``), see :class:`DuelingIntervalCritic`.
CRITIC_DESIGNS: tuple[str, ...] = get_args(CriticDesign)
#: The network class of each critic design.
_NETWORKS: dict[str, type[CriticNetwork]] = {
    "paper": DuelingIntervalNetwork,
    "state_value": StateValueIntervalNetwork,
    "legendre": LegendreAdvantageNetwork,
    "action_network": ActionAdvantageNetwork,
}
#: The designs whose advantage has one output per interval (the others evaluate it at the action itself).
INTERVAL_OUTPUT_DESIGNS = ("paper", "state_value")
#: The designs whose ``Q`` at every interval centre comes from one pass (see
#: :meth:`DuelingIntervalCritic.greedy_action`): the streams read the state only and ``Q`` is additive across action
#: dimensions. The others' advantage networks read the action (``n_intervals ** action_dim`` passes per state).
GREEDY_CRITIC_DESIGNS: tuple[str, ...] = ("legendre",)
#: The critic design of ``ADC("MlpPolicy", env)`` (chosen by the critic study: docs/results).
DEFAULT_CRITIC_DESIGN: CriticDesign = "legendre"
#: Degree of the ``"legendre"`` advantage polynomial unless ``basis_degree`` says otherwise.
DEFAULT_BASIS_DEGREE = 4


def validate_critic_options(
    critic_design: object,
    n_intervals: object,
    aggregation: object,
    advantage_interpolation: object,
    basis_degree: object,
    n_critics: object = 1,
) -> None:
    """
    Raise ``ValueError`` naming the parameter and its accepted values when an option of
    :class:`DuelingIntervalCritic` is invalid. The one place these rules live: the hyperparameter files and the
    CLI ask it.

    :param critic_design: One of :data:`CRITIC_DESIGNS`
    :param n_intervals: Number of uniform intervals per action dimension
    :param aggregation: ``"mean"`` or ``"max"``
    :param advantage_interpolation: ``"none"`` or ``"linear"`` (``"linear"`` for the interval-output designs only)
    :param basis_degree: Degree of the ``"legendre"`` polynomial, an integer in ``[1, 16]``
    :param n_critics: Number of critic networks, an integer >= 1
    """
    if critic_design not in CRITIC_DESIGNS:
        raise ValueError(f"`critic_design` must be one of {CRITIC_DESIGNS}, got {critic_design!r}.")
    validate_interval_options(n_intervals, aggregation, advantage_interpolation)
    if advantage_interpolation != "none" and critic_design not in INTERVAL_OUTPUT_DESIGNS:
        raise ValueError(
            f'`advantage_interpolation` must be "none" with critic_design={critic_design!r} (its advantage is '
            f"evaluated at the action itself); interpolation applies to {INTERVAL_OUTPUT_DESIGNS}."
        )
    if isinstance(basis_degree, bool) or not isinstance(basis_degree, int) or not 1 <= basis_degree <= 16:
        raise ValueError(f"`basis_degree` must be an integer in [1, 16], got {basis_degree!r}.")
    if isinstance(n_critics, bool) or not isinstance(n_critics, int) or n_critics < 1:
        raise ValueError(f"`n_critics` must be an integer >= 1, got {n_critics!r}.")


class DuelingIntervalCritic(BaseModel):
    """
    Dueling interval critic of the Actor-Dueling-Critic method.

    Actor-Dueling-Critic paper, Section 4 and Figure 3: a value stream ``V`` and an advantage stream with one
    value per uniform interval of the action range, combined as ``Q = V + A(s, z_a) - mean_z A(s, z)``
    (Eq. 13-14), or with ``max`` in place of ``mean`` (Eq. 11). ``critic_design`` chooses the network that computes
    them (:mod:`sb3_adc.adc.designs` gives the equations of each): ``"paper"``, the paper's form, a shared trunk over
    (state, action) under both streams, one advantage output per interval; ``"state_value"``, ``V`` from the state
    only; ``"legendre"`` (the default), ``V`` and a polynomial advantage ``A(s, a) = sum_k c_k(s) P_k(a)`` from the
    state only, in effect a state-dependent polynomial advantage (the family of NAF and Q-functionals) on which
    ``n_intervals`` barely matters; ``"action_network"``, ``V`` from the state only and an advantage network over
    (state, action) evaluated at the action, centred on its mean over the interval centres.

    It honours the contract of SB3's :class:`~stable_baselines3.common.policies.ContinuousCritic`, so
    TD3's update machinery applies: ``forward`` returns one ``(batch, 1)`` Q tensor per critic network,
    ``q1_forward`` evaluates the first network only, and a features extractor shared with the actor is
    trained by the actor loss only.

    Extensions beyond the paper (which covers 1-D actions): with several action dimensions the advantage
    is factorised, one branch of ``n_intervals`` per dimension, each centred on its own and summed (as in
    action-branching dueling networks); ``advantage_interpolation="linear"`` makes the interval advantage
    piecewise linear in the action; ``n_critics=2`` gives a twin, clipped double-Q variant.

    :param observation_space: Observation space
    :param action_space: Action space (a bounded ``Box``)
    :param net_arch: Hidden layer sizes of the trunk (over ``[features, action]``, or over the features for
        ``"legendre"``) and of the state-value network of ``"state_value"`` and ``"action_network"``
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
        or ``"linear"`` (interpolate between the two nearest interval centres; interval-output designs only)
    :param critic_design: One of :data:`CRITIC_DESIGNS`
    :param basis_degree: Degree of the advantage polynomial of ``critic_design="legendre"``
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
        critic_design: CriticDesign = DEFAULT_CRITIC_DESIGN,
        basis_degree: int = DEFAULT_BASIS_DEGREE,
    ):
        super().__init__(
            observation_space,
            action_space,
            features_extractor=features_extractor,
            normalize_images=normalize_images,
        )
        check_action_space(action_space)
        validate_critic_options(critic_design, n_intervals, aggregation, advantage_interpolation, basis_degree, n_critics)

        self.share_features_extractor = share_features_extractor
        self.n_critics = n_critics
        self.n_intervals = n_intervals
        self.critic_design: CriticDesign = critic_design
        self.aggregation: Aggregation = aggregation
        self.advantage_interpolation: Interpolation = advantage_interpolation
        self.partition = UniformIntervalPartition(n_intervals)
        spec = NetworkSpec(
            features_dim,
            get_action_dim(self.action_space),
            n_intervals,
            list(net_arch),
            list(value_net_arch or []),
            list(advantage_net_arch or []),
            activation_fn,
            aggregation,
            basis_degree,
        )
        self.q_networks: list[CriticNetwork] = [_NETWORKS[critic_design](spec) for _ in range(n_critics)]
        for idx, q_net in enumerate(self.q_networks):
            self.add_module(f"qf{idx}", q_net)

    def forward(self, obs: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, ...]:
        """
        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)`` in ``[-1, 1]``
        :return: One ``(batch, 1)`` Q-value tensor per critic network
        """
        # A features extractor shared with the actor learns from the policy loss only.
        with th.set_grad_enabled(not self.share_features_extractor):
            features = self.extract_features(obs, self.features_extractor)
        return tuple(
            q_net.q_value(features, actions, self.partition, self.advantage_interpolation) for q_net in self.q_networks
        )

    def q1_forward(self, obs: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        Q-value of the first critic network only, with the features extractor frozen (used for the actor loss).

        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: ``(batch, 1)``
        """
        with th.no_grad():
            features = self.extract_features(obs, self.features_extractor)
        return self.q_networks[0].q_value(features, actions, self.partition, self.advantage_interpolation)

    def decompose(self, obs: PyTorchObs, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """
        The two streams of the first critic network, for diagnostics and tests.

        :param obs: Observations
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: ``value`` ``(batch, 1)``, the raw ``advantages`` ``(batch, branches, n_intervals)`` (before
            centring: the interval outputs, or the advantage at the interval centres; ``branches`` is ``action_dim``,
            or 1 for ``"action_network"``, whose advantage reads the whole action) and ``interval_index``
            ``(batch, action_dim)``, the interval that contains each action component
        """
        features = self.extract_features(obs, self.features_extractor)
        value, advantages = self.q_networks[0](features, actions)
        return value, advantages, self.partition.index(actions)

    @th.no_grad()
    def greedy_action(self, obs: PyTorchObs) -> tuple[th.Tensor, th.Tensor]:
        """
        The grid point of interval centres with the highest Q-value of the first critic network, and that value:
        ``z* = argmax_z Q_1(s, z)`` over the ``n_intervals ** action_dim`` points whose every component is an
        interval centre, and ``Q_1(s, z*)``.

        ADC paper, Eq. 13-14 (Eq. 11 with ``aggregation="max"``) at every interval centre, from one pass of the
        ``"legendre"`` network (:meth:`~sb3_adc.adc.legendre.LegendreAdvantageNetwork.greedy_intervals`). Evaluated
        without gradient.

        :param obs: Observations
        :return: ``z*`` ``(batch, action_dim)``, scaled actions in ``[-1, 1]``, and ``Q_1(s, z*)`` ``(batch, 1)``
        :raises ValueError: for a critic design not in :data:`GREEDY_CRITIC_DESIGNS`
        """
        q_net = self._one_pass_network("greedy_action")
        features = self.extract_features(obs, self.features_extractor)
        index, value = q_net.greedy_intervals(features)
        return self.partition.centres[index], value

    @th.no_grad()
    def interval_advantages(self, obs: PyTorchObs) -> th.Tensor:
        """
        The advantage stream of the first critic network at every interval centre, ``A_1(s, z)`` (Eq. 13-14 before
        centring), from one pass; what ADC's ``interval_exploration`` draws from. Evaluated without gradient.

        :param obs: Observations
        :return: ``(batch, action_dim, n_intervals)``
        :raises ValueError: for a critic design not in :data:`GREEDY_CRITIC_DESIGNS`
        """
        q_net = self._one_pass_network("interval_advantages")
        return q_net.advantages_at_centres(self.extract_features(obs, self.features_extractor))

    def _one_pass_network(self, caller: str) -> LegendreAdvantageNetwork:
        """The first critic network, if its design gives every interval centre's advantage in one pass."""
        q_net = self.q_networks[0]
        if not isinstance(q_net, LegendreAdvantageNetwork):
            raise ValueError(
                f"`{caller}` needs critic_design in {GREEDY_CRITIC_DESIGNS}, got {self.critic_design!r}: its "
                "advantage network reads the action, so one pass does not give the Q-value of every interval centre."
            )
        return q_net


def refuse_adc_policy(policy_class: object, algorithm: str) -> None:
    """
    Raise ``TypeError`` if ``policy_class`` is ADC's policy: for the TD3-family baselines, whose ``load`` of an ADC
    model file (as SB3's does) would otherwise build the ADC policy and train it with their own update.

    :param policy_class: The policy class the algorithm is about to build
    :param algorithm: The algorithm's name in the message (``"DDPG"``, ``"TD3"``)
    """
    if isinstance(policy_class, type) and issubclass(policy_class, ADCPolicy):
        raise TypeError(
            f"`policy` must be a {algorithm} (TD3Policy) policy, got the ADC policy {policy_class.__name__}. "
            "(Loading a model file saved by ADC? Load it with sb3_adc.ADC.load.)"
        )


class ADCPolicy(ActorAverageTD3Policy):
    """
    Policy class (an actor and a dueling interval critic, with their target networks) for ADC.

    Actor-Dueling-Critic paper, Figure 3: the actor is TD3's deterministic actor; the critic is a
    :class:`DuelingIntervalCritic`. The paper's Pendulum network (one hidden layer of 30 units in the actor
    and in the critic trunk, 100 intervals, a value stream of 20 units) is
    ``dict(net_arch=dict(pi=[30], qf=[30]), n_intervals=100, value_net_arch=[20])``.

    The other parameters (``net_arch``: the actor's and the critic trunk's hidden layers, a list for both or
    ``dict(pi=[...], qf=[...])``; ``activation_fn``, ``features_extractor_class``, ``features_extractor_kwargs``,
    ``normalize_images``, ``share_features_extractor``, ``actor_average_tau``), by name or the first five by position,
    are those of :class:`~sb3_adc.common.actor_average.ActorAverageTD3Policy`, with its defaults.

    :param observation_space: Observation space
    :param action_space: Action space (a bounded ``Box``)
    :param lr_schedule: Learning rate schedule (could be constant); ADC sets the critic optimizer's rate
        from its own ``critic_learning_rate``
    :param optimizer_class: The optimizer to use, ``th.optim.Adam`` by default
    :param optimizer_kwargs: Additional keyword arguments, excluding the learning rate, to pass to the optimizer;
        with Adam or AdamW and neither ``fused`` nor ``foreach`` given, ``fused=True`` is added (one kernel for all
        parameter tensors instead of SB3's per-tensor loop on the CPU, the same update up to float rounding; see
        :mod:`sb3_adc.common.fast_update`; ADC's ``fast_update=False`` trains with SB3's loop whatever this says)
    :param n_critics: Number of dueling critic networks (1 in the paper)
    :param n_intervals: Number of uniform intervals per action dimension (for ``"legendre"``, the centres of its
        nearly-zero baseline, and the grid that ADC's ``target_greedy_mix`` and ``actor_greedy_weight`` search)
    :param value_net_arch: Hidden layer sizes of the value stream
    :param advantage_net_arch: Hidden layer sizes of the advantage stream
    :param aggregation: ``"mean"`` (Eq. 12-14) or ``"max"`` (Eq. 11)
    :param advantage_interpolation: ``"none"`` (the paper) or ``"linear"``
    :param critic_design: What computes the value and advantage streams: ``"paper"`` (the paper's interval
        critic), ``"state_value"``, ``"legendre"`` (the default: a polynomial advantage in the action, on which
        ``n_intervals`` has almost no effect) or ``"action_network"`` (see :class:`DuelingIntervalCritic`)
    :param basis_degree: Degree of the advantage polynomial of ``critic_design="legendre"``
    """

    critic: DuelingIntervalCritic  # type: ignore[assignment]
    critic_target: DuelingIntervalCritic  # type: ignore[assignment]

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        *args: Any,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        n_critics: int = 1,
        n_intervals: int = 100,
        value_net_arch: list[int] | None = None,
        advantage_net_arch: list[int] | None = None,
        aggregation: Aggregation = "mean",
        advantage_interpolation: Interpolation = "none",
        critic_design: CriticDesign = DEFAULT_CRITIC_DESIGN,
        basis_degree: int = DEFAULT_BASIS_DEGREE,
        **kwargs: Any,
    ):
        # TD3Policy.__init__ builds the networks (through ``make_critic``), so the dueling options must be
        # in place before it runs.
        self.dueling_kwargs: dict[str, Any] = {
            "n_intervals": n_intervals,
            "value_net_arch": list(value_net_arch or []),
            "advantage_net_arch": list(advantage_net_arch or []),
            "aggregation": aggregation,
            "advantage_interpolation": advantage_interpolation,
            "critic_design": critic_design,
            "basis_degree": basis_degree,
        }
        # A default of the fast update path, which the caller's explicit `fused` or `foreach` overrides.
        optimizer_kwargs = fast_optimizer_kwargs(optimizer_class, optimizer_kwargs)
        kwargs.update(optimizer_class=optimizer_class, optimizer_kwargs=optimizer_kwargs, n_critics=n_critics)
        super().__init__(observation_space, action_space, lr_schedule, *args, **kwargs)

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

    def __init__(self, *args: Any, features_extractor_class: type[BaseFeaturesExtractor] = NatureCNN, **kwargs: Any):
        super().__init__(*args, features_extractor_class=features_extractor_class, **kwargs)


class MultiInputPolicy(ADCPolicy):
    """
    Policy class for ADC with ``Dict`` observations: :class:`ADCPolicy` with SB3's ``CombinedExtractor``
    features extractor by default. Parameters as :class:`ADCPolicy`.
    """

    def __init__(self, *args: Any, features_extractor_class: type[BaseFeaturesExtractor] = CombinedExtractor, **kwargs: Any):
        super().__init__(*args, features_extractor_class=features_extractor_class, **kwargs)
