"""
The critic networks of the dueling interval critic, one per ``critic_design``.

ADC paper, Section 4 (Eq. 13-14): ``Q(s, a) = V(s) + A(s, z_a) - mean_z A(s, z)``, one advantage per uniform
interval ``z`` of the action range. The paper computes both streams from one layer over ``[s, a]``
(``critic_design="paper"``, :class:`DuelingIntervalNetwork`), so its ``V`` depends on the action, and each
interval's advantage is a separate output trained only by the samples whose action falls in that interval. The
other designs keep the equation and change what computes its terms:

- ``"state_value"`` (:class:`StateValueIntervalNetwork`): ``V`` reads the state features only; the interval
  advantages are the paper's, on a trunk over ``[s, a]``.
- ``"legendre"`` (:class:`~sb3_adc.adc.legendre.LegendreAdvantageNetwork`, the default): ``V`` and the advantage
  read the state only, and the advantage of every interval is a polynomial of degree ``basis_degree`` in the interval centre:
  ``A(s, z) = sum_k c_k(s) P_k(centre_z)`` (Legendre polynomials ``P_k``). Neighbouring intervals share
  strength, every sample trains every interval's advantage, and the advantage is evaluated at the action
  itself, ``A(s, a) = sum_k c_k(s) P_k(a)``, so ``dQ/da`` is a smooth polynomial. The intervals are nearly
  vestigial here: the baseline ``mean_z P_k(centre_z)`` is the midpoint rule for the integral of ``P_k`` over
  ``[-1, 1]``, which is zero, and is below 1.7e-4 for 100 intervals and 4.2e-3 for 20 at the default degree 4.
  So this design is a state-dependent polynomial advantage (the family of NAF and Q-functionals), and
  ``n_intervals`` only shifts ``Q(s, .)`` by a constant in the action, leaving ``dQ/da`` unchanged.
- ``"action_network"`` (:class:`ActionAdvantageNetwork`): ``V`` reads the state only; the advantage is a network
  over ``[s, a]`` evaluated at the action, centred on its mean (or maximum) over the interval centres:
  ``Q = V(s) + A(s, a) - mean_z A(s, centre_z)``.

Every design is a :class:`CriticNetwork` built from one :class:`NetworkSpec`: ``forward(features, actions)`` gives
``V`` ``(batch, 1)`` and the advantages of the interval centres ``(batch, branches, n_intervals)``, and ``q_value``
gives ``Q`` ``(batch, 1)``. With several action dimensions the advantage is one branch per dimension, summed, or
(:class:`ActionAdvantageNetwork`) a network of the whole action centred on a Latin-hypercube set of interval centres.

Only ``"legendre"`` reads every interval centre's ``Q`` off one pass (``greedy_intervals``, used by ADC's greedy
targets and greedy policy improvement, and ``advantages_at_centres``, used by its exploration from the advantages):
its streams read the state only and its ``Q`` is additive across action dimensions. The other designs' advantage
networks read the action, so ``Q(s, z)`` at a centre needs a pass with the action set to that centre,
``n_intervals ** action_dim`` passes per state for the whole grid.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import torch as th
from stable_baselines3.common.torch_layers import create_mlp
from torch import nn

from sb3_adc.adc.intervals import Aggregation, Interpolation, UniformIntervalPartition, aggregate


def mlp(input_dim: int, output_dim: int, net_arch: list[int], activation_fn: type[nn.Module]) -> nn.Sequential:
    """SB3's ``create_mlp`` as one ``nn.Sequential`` (``output_dim=-1``: no output layer)."""
    return nn.Sequential(*create_mlp(input_dim, output_dim, net_arch, activation_fn))


def centred_advantage(selected: th.Tensor, at_centres: th.Tensor, aggregation: Aggregation) -> th.Tensor:
    """``A(s, a) - mean_z A(s, z)`` (Eq. 13) or ``- max_z A(s, z)`` (Eq. 11), summed over action branches.

    :param selected: ``(batch, branches)`` advantage of the action in each branch
    :param at_centres: ``(batch, branches, n_intervals)`` advantages of the interval centres
    :return: ``(batch, 1)``
    """
    baseline = at_centres.mean(dim=-1) if aggregation == "mean" else at_centres.amax(dim=-1)
    return (selected - baseline).sum(dim=1, keepdim=True)


@dataclass(frozen=True)
class NetworkSpec:
    """
    What a critic network of any design is built from: the critic builds one and hands it to each of its networks.

    :param features_dim: Number of state features
    :param action_dim: Number of action dimensions (advantage branches)
    :param n_intervals: Number of intervals per action dimension
    :param net_arch: Hidden layers of the trunk (what it reads depends on the design)
    :param value_net_arch: Hidden layers of the value stream
    :param advantage_net_arch: Hidden layers of the advantage stream
    :param activation_fn: Activation function
    :param aggregation: ``"mean"`` (Eq. 12-14) or ``"max"`` (Eq. 11): the dueling head's combining rule
    :param basis_degree: Degree of the advantage polynomial (``"legendre"`` only)
    """

    features_dim: int
    action_dim: int
    n_intervals: int
    net_arch: list[int]
    value_net_arch: list[int]
    advantage_net_arch: list[int]
    activation_fn: type[nn.Module]
    aggregation: Aggregation
    basis_degree: int


class CriticNetwork(nn.Module):
    """
    A critic network of any design: ``forward(features, actions)`` gives the value ``(batch, 1)`` and the advantages
    of the interval centres ``(batch, branches, n_intervals)``; :meth:`q_value` gives ``Q`` ``(batch, 1)``, here
    for the designs with one advantage output per interval (the others evaluate the advantage at the action and
    override it).

    :param spec: Sizes and options of the network
    """

    def __init__(self, spec: NetworkSpec):
        super().__init__()
        self.action_dim = spec.action_dim
        self.n_intervals = spec.n_intervals
        self.aggregation: Aggregation = spec.aggregation

    def q_value(
        self, features: th.Tensor, actions: th.Tensor, partition: UniformIntervalPartition, interpolation: Interpolation
    ) -> th.Tensor:
        """
        ``Q(s, a)`` (Eq. 11 or 13-14): both streams, then :func:`~sb3_adc.adc.intervals.aggregate` with the
        centred weights of the actions' intervals.

        :param features: ``(batch, features_dim)``
        :param actions: Scaled actions ``(batch, action_dim)``
        :param partition: The intervals of the action range
        :param interpolation: ``"none"`` or ``"linear"``
        :return: ``(batch, 1)``
        """
        value, advantages = self(features, actions)
        return aggregate(value, advantages, partition.centred_weights(actions, advantages, self.aggregation, interpolation))


class DuelingIntervalNetwork(CriticNetwork):
    """
    ``critic_design="paper"``: a shared trunk over ``[features, action]`` (the paper's first layer ``theta^Q``), a
    value stream (``beta``) and an advantage stream (``alpha``) with ``n_intervals`` outputs per action dimension.

    The first layers of the two streams read the same trunk output, so one ``nn.Linear`` (``stream_inputs``)
    computes both and its output is split between them: mathematically two separate layers, at half the
    per-layer cost of the optimizer and the target updates. An empty trunk is the identity: both streams then read
    ``[features, action]``.

    :param spec: Sizes and options; ``net_arch`` is the shared trunk, ``value_net_arch`` and ``advantage_net_arch``
        the hidden layers of the streams (output layers of 1 and ``action_dim * n_intervals`` units)
    """

    def __init__(self, spec: NetworkSpec):
        super().__init__(spec)
        input_dim = spec.features_dim + spec.action_dim
        trunk_dim = spec.net_arch[-1] if spec.net_arch else input_dim
        value_sizes = [*spec.value_net_arch, 1]
        advantage_sizes = [*spec.advantage_net_arch, spec.action_dim * spec.n_intervals]
        self.trunk = mlp(input_dim, -1, spec.net_arch, spec.activation_fn)
        self.stream_inputs = nn.Linear(trunk_dim, value_sizes[0] + advantage_sizes[0])
        self.split_sizes = (value_sizes[0], advantage_sizes[0])
        # The layers after the first of each stream; None for a single-layer stream.
        self.value_stream = _stream_tail(value_sizes, spec.activation_fn)
        self.advantage_stream = _stream_tail(advantage_sizes, spec.activation_fn)

    def forward(self, features: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        value, advantages = self.stream_inputs(self.trunk(th.cat([features, actions], dim=1))).split(self.split_sizes, 1)
        if self.value_stream is not None:
            value = self.value_stream(value)
        if self.advantage_stream is not None:
            advantages = self.advantage_stream(advantages)
        return value, advantages.view(-1, self.action_dim, self.n_intervals)

    def stream_layer_sizes(self) -> dict[str, list[tuple[int, int]]]:
        """``(in_features, out_features)`` of every linear layer of the trunk and of each stream."""

        def linear_sizes(layers: nn.Sequential | None) -> list[tuple[int, int]]:
            return [] if layers is None else [(m.in_features, m.out_features) for m in layers if isinstance(m, nn.Linear)]

        first_value, first_advantage = self.split_sizes
        first_in = self.stream_inputs.in_features
        return {
            "trunk": linear_sizes(self.trunk),
            "value": [(first_in, first_value), *linear_sizes(self.value_stream)],
            "advantage": [(first_in, first_advantage), *linear_sizes(self.advantage_stream)],
        }


def _stream_tail(sizes: list[int], activation_fn: type[nn.Module]) -> nn.Sequential | None:
    """The layers of a stream after its first linear layer (an activation and a linear layer per step), if any."""
    layers: list[nn.Module] = []
    for in_features, out_features in itertools.pairwise(sizes):
        layers += [activation_fn(), nn.Linear(in_features, out_features)]
    return nn.Sequential(*layers) if layers else None


class StateValueIntervalNetwork(CriticNetwork):
    """
    ``critic_design="state_value"``: ``V(s)`` from the state features only (its own MLP), and the paper's
    interval advantages from a trunk over ``[features, action]``.

    :param spec: Sizes and options; ``net_arch`` is the first hidden layers of both the advantage network over
        ``[features, action]`` and the value network, ``value_net_arch`` and ``advantage_net_arch`` their further
        hidden layers
    """

    def __init__(self, spec: NetworkSpec):
        super().__init__(spec)
        self.value_net = mlp(spec.features_dim, 1, [*spec.net_arch, *spec.value_net_arch], spec.activation_fn)
        self.advantage_net = mlp(
            spec.features_dim + spec.action_dim,
            spec.action_dim * spec.n_intervals,
            [*spec.net_arch, *spec.advantage_net_arch],
            spec.activation_fn,
        )

    def forward(self, features: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        advantages = self.advantage_net(th.cat([features, actions], dim=1))
        return self.value_net(features), advantages.view(-1, self.action_dim, self.n_intervals)


class ActionAdvantageNetwork(CriticNetwork):
    """
    ``critic_design="action_network"``: ``V(s)`` from the state features only, and an advantage network over
    ``[features, action]`` with one output, evaluated at the action and at the interval centres;
    ``Q = V(s) + A(s, a) - mean_z A(s, centre_z)``.

    With several action dimensions the centres are ``n_intervals`` points of a fixed Latin hypercube over the
    interval centres (each dimension takes every centre once), so the baseline is a stratified estimate of the
    mean of ``A`` over the action box.

    :param spec: Sizes and options; ``net_arch`` is the first hidden layers of both the advantage network over
        ``[features, action]`` and the value network, ``value_net_arch`` and ``advantage_net_arch`` their further
        hidden layers, ``n_intervals`` the centres of the baseline
    """

    centre_actions: th.Tensor

    def __init__(self, spec: NetworkSpec):
        super().__init__(spec)
        action_dim, n_intervals = spec.action_dim, spec.n_intervals
        self.value_net = mlp(spec.features_dim, 1, [*spec.net_arch, *spec.value_net_arch], spec.activation_fn)
        self.advantage_net = mlp(
            spec.features_dim + action_dim, 1, [*spec.net_arch, *spec.advantage_net_arch], spec.activation_fn
        )
        centres = UniformIntervalPartition(n_intervals).centres
        # A fixed Latin hypercube: dimension d visits the centres in the order of a permutation drawn once.
        generator = th.Generator().manual_seed(0)
        columns = [centres] + [centres[th.randperm(n_intervals, generator=generator)] for _ in range(action_dim - 1)]
        self.register_buffer("centre_actions", th.stack(columns, dim=1), persistent=False)

    def _advantage_at_centres(self, features: th.Tensor) -> th.Tensor:
        batch, n = features.shape[0], self.n_intervals
        tiled = features.unsqueeze(1).expand(batch, n, features.shape[1])
        centres = self.centre_actions.unsqueeze(0).expand(batch, n, self.action_dim)
        return self.advantage_net(th.cat([tiled, centres], dim=2)).view(batch, 1, n)

    def forward(self, features: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        :param features: ``(batch, features_dim)``
        :param actions: Scaled actions ``(batch, action_dim)`` (unused: see :meth:`q_value`)
        :return: value ``(batch, 1)`` and the advantages of the interval centres ``(batch, 1, n_intervals)``
            (one branch for the whole action)
        """
        return self.value_net(features), self._advantage_at_centres(features)

    def q_value(
        self, features: th.Tensor, actions: th.Tensor, partition: UniformIntervalPartition, interpolation: Interpolation
    ) -> th.Tensor:
        """``Q(s, a) = V(s) + A(s, a) - mean_z A(s, centre_z)`` (``max`` for Eq. 11). Parameters as in
        :meth:`CriticNetwork.q_value`; ``partition`` and ``interpolation`` are not used. :return: ``(batch, 1)``"""
        selected = self.advantage_net(th.cat([features, actions], dim=1))
        return self.value_net(features) + centred_advantage(selected, self._advantage_at_centres(features), self.aggregation)
