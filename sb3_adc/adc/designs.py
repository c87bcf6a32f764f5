"""
Critic designs of the dueling interval critic beyond the paper's form.

ADC paper, Section 4 (Eq. 13-14): ``Q(s, a) = V(s) + A(s, z_a) - mean_z A(s, z)``, one advantage per uniform
interval ``z`` of the action range. The paper computes both streams from one layer over ``[s, a]``
(``critic_design="paper"``, :class:`~sb3_adc.adc.policies.DuelingIntervalNetwork`), so its ``V`` depends on the
action, and each interval's advantage is a separate output trained only by the samples whose action falls in
that interval. The designs here keep the equation and change what computes its terms:

- ``"state_value"`` (:class:`StateValueIntervalNetwork`): ``V`` reads the state features only; the interval
  advantages are the paper's, on a trunk over ``[s, a]``.
- ``"legendre"`` (:class:`LegendreAdvantageNetwork`): ``V`` and the advantage read the state only, and the
  advantage of every interval is a polynomial of degree ``basis_degree`` in the interval centre:
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

Every design exposes the same two methods: ``forward(features, actions)`` gives ``V`` ``(batch, 1)`` and the
advantages of the interval centres ``(batch, action_dim, n_intervals)``, and ``q_value`` gives ``Q``
``(batch, 1)``. With several action dimensions the advantage is one branch per dimension, summed
(:class:`LegendreAdvantageNetwork`), or a network of the whole action centred on a Latin-hypercube set of
interval centres (:class:`ActionAdvantageNetwork`).

Only ``"legendre"`` reads every interval centre's ``Q`` off one pass (``greedy_intervals``, used by ADC's greedy
targets and greedy policy improvement, and ``advantages_at_centres``, used by its exploration from the advantages):
its streams read the state only and its ``Q`` is additive across action dimensions. The other designs' advantage
networks read the action, so ``Q(s, z)`` at a centre needs a pass with the action set to that centre,
``n_intervals ** action_dim`` passes per state for the whole grid.
"""

from __future__ import annotations

import numpy as np
import torch as th
from numpy.polynomial import legendre
from stable_baselines3.common.torch_layers import create_mlp
from torch import nn
from torch.nn import functional as F

from sb3_adc.adc.intervals import Aggregation, Interpolation, UniformIntervalPartition, aggregate


def legendre_basis(x: th.Tensor, degree: int) -> th.Tensor:
    """
    The Legendre polynomials ``P_1 .. P_degree`` at ``x`` (Bonnet's recursion), orthogonal on ``[-1, 1]``.

    ``P_0`` (a constant) is left out: a constant advantage is not identifiable beside ``V``.

    :param x: Points in ``[-1, 1]``, any shape
    :param degree: Highest degree (>= 1)
    :return: ``(*x.shape, degree)``
    """
    polynomials = [th.ones_like(x), x]
    for k in range(1, degree):
        polynomials.append(((2 * k + 1) * x * polynomials[k] - k * polynomials[k - 1]) / (k + 1))
    return th.stack(polynomials[1 : degree + 1], dim=-1)


#: Up to this degree the ``"legendre"`` critic evaluates its centred basis from monomials: one power and one
#: matrix product instead of Bonnet's recursion, whose many small tensor operations (each with scalar operands)
#: dominate the cost of a small critic. In float32 the monomial form's rounding error grows with the coefficients
#: of ``P_k`` in the monomial basis (about ``2^k``), so higher degrees keep the recursion.
MONOMIAL_MAX_DEGREE = 8


def legendre_monomial_matrix(degree: int) -> th.Tensor:
    """
    The monomial coefficients of ``P_1 .. P_degree`` without their constant terms: ``M[j - 1, k - 1]`` is the
    coefficient of ``x^j`` in ``P_k``, so ``[x, x^2, .., x^degree] @ M`` is ``legendre_basis(x, degree)`` up to a
    constant per polynomial (which centring over the interval centres removes).

    :param degree: Highest degree (>= 1)
    :return: ``(degree, degree)``, float32
    """
    matrix = np.zeros((degree, degree))
    for k in range(1, degree + 1):
        monomials = legendre.leg2poly(np.eye(degree + 1)[k])  # P_k in the monomial basis, constant first
        matrix[: len(monomials) - 1, k - 1] = monomials[1:]
    return th.as_tensor(matrix, dtype=th.float32)


def _mlp(input_dim: int, output_dim: int, net_arch: list[int], activation_fn: type[nn.Module]) -> nn.Sequential:
    return nn.Sequential(*create_mlp(input_dim, output_dim, net_arch, activation_fn))


def _centre(selected: th.Tensor, at_centres: th.Tensor, aggregation: Aggregation) -> th.Tensor:
    """``A(s, a) - mean_z A(s, z)`` (Eq. 13) or ``- max_z A(s, z)`` (Eq. 11), summed over action branches.

    :param selected: ``(batch, branches)`` advantage of the action in each branch
    :param at_centres: ``(batch, branches, n_intervals)`` advantages of the interval centres
    :return: ``(batch, 1)``
    """
    baseline = at_centres.mean(dim=-1) if aggregation == "mean" else at_centres.amax(dim=-1)
    return (selected - baseline).sum(dim=1, keepdim=True)


class StateValueIntervalNetwork(nn.Module):
    """
    ``critic_design="state_value"``: ``V(s)`` from the state features only (its own MLP), and the paper's
    interval advantages from a trunk over ``[features, action]``.

    :param features_dim: Number of state features
    :param action_dim: Number of action dimensions (advantage branches)
    :param n_intervals: Number of intervals per action dimension
    :param net_arch: Hidden layers of the advantage trunk over ``[features, action]`` and of the value network
    :param value_net_arch: Further hidden layers of the value network
    :param advantage_net_arch: Further hidden layers of the advantage stream
    :param activation_fn: Activation function
    """

    def __init__(
        self,
        features_dim: int,
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
        self.value_net = _mlp(features_dim, 1, [*net_arch, *value_net_arch], activation_fn)
        self.advantage_net = _mlp(
            features_dim + action_dim, action_dim * n_intervals, [*net_arch, *advantage_net_arch], activation_fn
        )

    def forward(self, features: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        :param features: ``(batch, features_dim)``
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: value ``(batch, 1)`` and interval advantages ``(batch, action_dim, n_intervals)``
        """
        advantages = self.advantage_net(th.cat([features, actions], dim=1))
        return self.value_net(features), advantages.view(-1, self.action_dim, self.n_intervals)

    def q_value(
        self,
        features: th.Tensor,
        actions: th.Tensor,
        partition: UniformIntervalPartition,
        aggregation: Aggregation,
        interpolation: Interpolation,
    ) -> th.Tensor:
        """``Q(s, a)`` (Eq. 11 or 13-14) with the state value. Parameters as in :meth:`forward`, plus the partition
        and the aggregation and interpolation modes. :return: ``(batch, 1)``"""
        value, advantages = self(features, actions)
        return aggregate(value, advantages, partition.centred_weights(actions, advantages, aggregation, interpolation))


class LegendreAdvantageNetwork(nn.Module):
    """
    ``critic_design="legendre"``: a state trunk with a value head and a head of Legendre coefficients, one set of
    ``basis_degree`` coefficients per action dimension; ``A(s, a_d) = sum_k c_{d,k}(s) P_k(a_d)``.

    The interval advantages of the paper are this polynomial at the interval centres, so the mean (or max) over
    intervals of Eq. 13-14 (Eq. 11) is taken over the centres; the advantage of the action is the polynomial at the
    action itself (no interpolation is needed). With the mean that baseline is nearly zero (each ``P_k`` averages
    to zero over ``[-1, 1]``; over the centres, below 1.7e-4 for 100 intervals and 4.2e-3 for 20 at degree 4), so
    ``n_intervals`` hardly matters: the critic is a polynomial advantage in the action, as in NAF or Q-functionals.

    :param features_dim: Number of state features
    :param action_dim: Number of action dimensions (advantage branches)
    :param n_intervals: Number of intervals per action dimension (centres of the baseline)
    :param net_arch: Hidden layers of the state trunk
    :param value_net_arch: Hidden layers of the value head
    :param advantage_net_arch: Hidden layers of the coefficient head
    :param activation_fn: Activation function
    :param basis_degree: Degree of the polynomial in the action
    """

    basis_at_centres: th.Tensor
    centred_basis_offset: th.Tensor
    exponents: th.Tensor
    monomial_matrix: th.Tensor
    q_weight_matrix: th.Tensor

    def __init__(
        self,
        features_dim: int,
        action_dim: int,
        n_intervals: int,
        net_arch: list[int],
        value_net_arch: list[int],
        advantage_net_arch: list[int],
        activation_fn: type[nn.Module],
        basis_degree: int,
    ):
        super().__init__()
        self.action_dim = action_dim
        self.n_intervals = n_intervals
        self.basis_degree = basis_degree
        self.trunk = nn.Sequential(*create_mlp(features_dim, -1, net_arch, activation_fn))
        trunk_dim = net_arch[-1] if net_arch else features_dim
        self.fused_heads = not value_net_arch and not advantage_net_arch
        if self.fused_heads:
            # Two single-layer heads are one layer with outputs [V | c]: the same function and, Adam being
            # elementwise, the same update rule, but one weight and one bias for the optimiser and the target
            # update instead of two of each, whose per-tensor overhead dominates a small critic's update
            # (benchmarks/training_throughput.py). The layer is filled from the two heads, drawn as before, so a
            # seed gives the same initial critic as separate heads (training then differs by float rounding).
            value_head, coefficient_head = nn.Linear(trunk_dim, 1), nn.Linear(trunk_dim, action_dim * basis_degree)
            self.heads = nn.utils.skip_init(nn.Linear, trunk_dim, 1 + action_dim * basis_degree)
            with th.no_grad():
                self.heads.weight.copy_(th.cat([value_head.weight, coefficient_head.weight]))
                self.heads.bias.copy_(th.cat([value_head.bias, coefficient_head.bias]))
        else:
            self.value_head = _mlp(trunk_dim, 1, value_net_arch, activation_fn)
            self.coefficient_head = _mlp(trunk_dim, action_dim * basis_degree, advantage_net_arch, activation_fn)
        centres = UniformIntervalPartition(n_intervals).centres
        self.register_buffer("basis_at_centres", legendre_basis(centres, basis_degree).T.contiguous(), persistent=False)
        # Derived constants, not saved: models saved before them load unchanged.
        self.monomials = basis_degree <= MONOMIAL_MAX_DEGREE
        self.register_buffer("exponents", th.arange(1, basis_degree + 1, dtype=th.float32), persistent=False)
        self.register_buffer("monomial_matrix", legendre_monomial_matrix(basis_degree), persistent=False)
        self.register_buffer("centred_basis_offset", th.zeros(basis_degree), persistent=False)
        self.centred_basis_offset = self._basis(centres).mean(dim=0)
        # [1 | a_1, .., a_1^K | a_2, ..] @ q_weight_matrix = [1 | centred basis of a_1 | of a_2 ..] (monomial path).
        q_weight_matrix = th.block_diag(th.ones(1, 1), *[self.monomial_matrix] * action_dim)
        q_weight_matrix[0, 1:] = -self.centred_basis_offset.repeat(action_dim)
        self.register_buffer("q_weight_matrix", q_weight_matrix, persistent=False)

    def _basis(self, x: th.Tensor) -> th.Tensor:
        """The basis at ``x`` ``(*x.shape, basis_degree)``, up to a constant per polynomial (see
        :data:`MONOMIAL_MAX_DEGREE`)."""
        if self.monomials:
            return x.unsqueeze(-1).pow(self.exponents) @ self.monomial_matrix
        return legendre_basis(x, self.basis_degree)

    def centred_basis(self, actions: th.Tensor) -> th.Tensor:
        """
        ``P_k(a_d) - mean_z P_k(centre_z)`` for every action dimension ``d`` and degree ``k``.

        :param actions: Scaled actions ``(batch, action_dim)`` in ``[-1, 1]``, as SB3 gives them (the actor's
            ``tanh``, clipped replay actions, clipped target smoothing); the polynomial extrapolates beyond. Not
            clamped here: a clamp would cost a twentieth of a small critic's update for nothing.
        :return: ``(batch, action_dim, basis_degree)``
        """
        return self._basis(actions) - self.centred_basis_offset

    def _heads(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        hidden = self.trunk(features)
        if self.fused_heads:
            outputs = self.heads(hidden)
            value, coefficients = outputs[:, :1], outputs[:, 1:]
        else:
            value, coefficients = self.value_head(hidden), self.coefficient_head(hidden)
        return value, coefficients.reshape(-1, self.action_dim, self.basis_degree)

    def forward(self, features: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        :param features: ``(batch, features_dim)``
        :param actions: Scaled actions ``(batch, action_dim)`` (unused: the streams read the state only)
        :return: value ``(batch, 1)`` and the advantages of the interval centres ``(batch, action_dim, n_intervals)``
        """
        value, coefficients = self._heads(features)
        return value, coefficients @ self.basis_at_centres

    def advantages_at_centres(self, features: th.Tensor) -> th.Tensor:
        """
        ``A(s, z) = sum_k c_k(s) P_k(centre_z)`` at every interval centre (Eq. 13-14's interval advantages, raw), from
        one pass of the state heads.

        :param features: ``(batch, features_dim)``
        :return: ``(batch, action_dim, n_intervals)``
        """
        return self._heads(features)[1] @ self.basis_at_centres

    def q_value(
        self,
        features: th.Tensor,
        actions: th.Tensor,
        partition: UniformIntervalPartition,
        aggregation: Aggregation,
        interpolation: Interpolation,
    ) -> th.Tensor:
        """``Q(s, a) = V(s) + A(s, a) - mean_z A(s, centre_z)`` (``max`` for Eq. 11). Parameters as in
        :meth:`forward`; ``partition`` and ``interpolation`` are not used. :return: ``(batch, 1)``"""
        # The mean over the centres is linear in the coefficients: centring the basis once (a constant) gives
        # A(s, a) - mean_z A(s, centre_z) without evaluating every centre.
        if aggregation == "mean" and self.fused_heads and self.monomials:
            # Q is the dot product of the layer's outputs [V | c] with [1 | centred basis], and that vector is
            # [1 | powers of the actions] times a constant matrix: a few tensor operations in all, and no slicing
            # of the outputs, whose backward would write into zeroed copies of them.
            powers = F.pad(actions.unsqueeze(-1).pow(self.exponents).flatten(1), (1, 0), value=1.0)
            return (self.heads(self.trunk(features)) * (powers @ self.q_weight_matrix)).sum(dim=1, keepdim=True)
        value, coefficients = self._heads(features)
        if aggregation == "mean":
            return value + (coefficients * self.centred_basis(actions)).flatten(1).sum(dim=1, keepdim=True)
        selected = (coefficients * legendre_basis(actions, self.basis_degree)).sum(dim=-1)
        return value + _centre(selected, coefficients @ self.basis_at_centres, aggregation)

    def greedy_intervals(self, features: th.Tensor, aggregation: Aggregation) -> tuple[th.Tensor, th.Tensor]:
        """
        The best grid point of the interval centres and its Q-value, from one pass of the state heads.

        ADC paper, Eq. 13-14 (Eq. 11 with ``max``) at every interval centre: ``Q(s, z) = V(s) + sum_d (A(s, z_d) -
        b_d(s))`` with ``b_d`` the mean (or max) of ``A(s, .)`` over the centres of dimension ``d``. Every term
        depends on one action dimension only, so the per-dimension argmax ``z*_d = argmax_z A(s, z_d)`` is the
        argmax over the whole grid of ``n_intervals ** action_dim`` centres, and
        ``Q(s, z*) = V(s) + sum_d (max_z A(s, z_d) - b_d(s))``.

        :param features: ``(batch, features_dim)``
        :param aggregation: ``"mean"`` or ``"max"`` (then ``Q(s, z*) = V(s)``)
        :return: the interval index of ``z*`` in each dimension ``(batch, action_dim)`` (int64) and ``Q(s, z*)``
            ``(batch, 1)``
        """
        value, coefficients = self._heads(features)
        at_centres = coefficients @ self.basis_at_centres
        best, index = at_centres.max(dim=-1)
        baseline = at_centres.mean(dim=-1) if aggregation == "mean" else best
        return index, value + (best - baseline).sum(dim=1, keepdim=True)


class ActionAdvantageNetwork(nn.Module):
    """
    ``critic_design="action_network"``: ``V(s)`` from the state features only, and an advantage network over
    ``[features, action]`` with one output, evaluated at the action and at the interval centres;
    ``Q = V(s) + A(s, a) - mean_z A(s, centre_z)``.

    With several action dimensions the centres are ``n_intervals`` points of a fixed Latin hypercube over the
    interval centres (each dimension takes every centre once), so the baseline is a stratified estimate of the
    mean of ``A`` over the action box.

    :param features_dim: Number of state features
    :param action_dim: Number of action dimensions
    :param n_intervals: Number of intervals per action dimension (centres of the baseline)
    :param net_arch: Hidden layers of the advantage network and of the value network
    :param value_net_arch: Further hidden layers of the value network
    :param advantage_net_arch: Further hidden layers of the advantage network
    :param activation_fn: Activation function
    """

    centre_actions: th.Tensor

    def __init__(
        self,
        features_dim: int,
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
        self.value_net = _mlp(features_dim, 1, [*net_arch, *value_net_arch], activation_fn)
        self.advantage_net = _mlp(features_dim + action_dim, 1, [*net_arch, *advantage_net_arch], activation_fn)
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
        self,
        features: th.Tensor,
        actions: th.Tensor,
        partition: UniformIntervalPartition,
        aggregation: Aggregation,
        interpolation: Interpolation,
    ) -> th.Tensor:
        """``Q(s, a) = V(s) + A(s, a) - mean_z A(s, centre_z)`` (``max`` for Eq. 11). Parameters as in
        :meth:`forward`; ``partition`` and ``interpolation`` are not used. :return: ``(batch, 1)``"""
        selected = self.advantage_net(th.cat([features, actions], dim=1))
        return self.value_net(features) + _centre(selected, self._advantage_at_centres(features), aggregation)
