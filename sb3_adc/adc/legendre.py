"""
The ``"legendre"`` critic design (the default): a polynomial advantage in the action, from the state only.

``A(s, a) = sum_k c_k(s) P_k(a)`` with Legendre polynomials ``P_k`` and coefficients from a state network, centred on
its mean (or maximum) over the interval centres (ADC paper, Eq. 13-14 or Eq. 11). See :mod:`sb3_adc.adc.designs` for
how it relates to the paper's interval critic and the other designs.
"""

from __future__ import annotations

import numpy as np
import torch as th
from numpy.polynomial import legendre
from torch import nn
from torch.nn import functional as F

from sb3_adc.adc.designs import CriticNetwork, NetworkSpec, centred_advantage, mlp
from sb3_adc.adc.intervals import Interpolation, UniformIntervalPartition


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


class LegendreAdvantageNetwork(CriticNetwork):
    """
    ``critic_design="legendre"``: a state trunk with a value head and a head of Legendre coefficients, one set of
    ``basis_degree`` coefficients per action dimension; ``A(s, a_d) = sum_k c_{d,k}(s) P_k(a_d)``.

    The interval advantages of the paper are this polynomial at the interval centres, so the mean (or max) over
    intervals of Eq. 13-14 (Eq. 11) is taken over the centres; the advantage of the action is the polynomial at the
    action itself (no interpolation is needed). With the mean that baseline is nearly zero (each ``P_k`` averages
    to zero over ``[-1, 1]``; over the centres, below 1.7e-4 for 100 intervals and 4.2e-3 for 20 at degree 4), so
    ``n_intervals`` hardly matters: the critic is a polynomial advantage in the action, as in NAF or Q-functionals.

    :param spec: Sizes and options; ``net_arch`` is the state trunk, ``value_net_arch`` and ``advantage_net_arch``
        the hidden layers of the value and coefficient heads, ``n_intervals`` the centres of the baseline and
        ``basis_degree`` the degree of the polynomial in the action
    """

    basis_at_centres: th.Tensor
    centred_basis_offset: th.Tensor
    exponents: th.Tensor
    monomial_matrix: th.Tensor
    q_weight_matrix: th.Tensor

    def __init__(self, spec: NetworkSpec):
        super().__init__(spec)
        action_dim, basis_degree = spec.action_dim, spec.basis_degree
        self.basis_degree = basis_degree
        self.trunk = mlp(spec.features_dim, -1, spec.net_arch, spec.activation_fn)
        trunk_dim = spec.net_arch[-1] if spec.net_arch else spec.features_dim
        self.fused_heads = not spec.value_net_arch and not spec.advantage_net_arch
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
            self.value_head = mlp(trunk_dim, 1, spec.value_net_arch, spec.activation_fn)
            self.coefficient_head = mlp(trunk_dim, action_dim * basis_degree, spec.advantage_net_arch, spec.activation_fn)
        centres = UniformIntervalPartition(spec.n_intervals).centres
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
        self, features: th.Tensor, actions: th.Tensor, partition: UniformIntervalPartition, interpolation: Interpolation
    ) -> th.Tensor:
        """``Q(s, a) = V(s) + A(s, a) - mean_z A(s, centre_z)`` (``max`` for Eq. 11). Parameters as in
        :meth:`CriticNetwork.q_value`; ``partition`` and ``interpolation`` are not used. :return: ``(batch, 1)``"""
        # The mean over the centres is linear in the coefficients: centring the basis once (a constant) gives
        # A(s, a) - mean_z A(s, centre_z) without evaluating every centre.
        if self.aggregation == "mean" and self.fused_heads and self.monomials:
            # Q is the dot product of the layer's outputs [V | c] with [1 | centred basis], and that vector is
            # [1 | powers of the actions] times a constant matrix: a few tensor operations in all, and no slicing
            # of the outputs, whose backward would write into zeroed copies of them.
            powers = F.pad(actions.unsqueeze(-1).pow(self.exponents).flatten(1), (1, 0), value=1.0)
            return (self.heads(self.trunk(features)) * (powers @ self.q_weight_matrix)).sum(dim=1, keepdim=True)
        value, coefficients = self._heads(features)
        if self.aggregation == "mean":
            return value + (coefficients * self.centred_basis(actions)).flatten(1).sum(dim=1, keepdim=True)
        selected = (coefficients * legendre_basis(actions, self.basis_degree)).sum(dim=-1)
        return value + centred_advantage(selected, coefficients @ self.basis_at_centres, self.aggregation)

    def greedy_intervals(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        The best grid point of the interval centres and its Q-value, from one pass of the state heads.

        ADC paper, Eq. 13-14 (Eq. 11 with ``max``) at every interval centre: ``Q(s, z) = V(s) + sum_d (A(s, z_d) -
        b_d(s))`` with ``b_d`` the mean (or max: then ``Q(s, z*) = V(s)``) of ``A(s, .)`` over the centres of
        dimension ``d``. Every term
        depends on one action dimension only, so the per-dimension argmax ``z*_d = argmax_z A(s, z_d)`` is the
        argmax over the whole grid of ``n_intervals ** action_dim`` centres, and
        ``Q(s, z*) = V(s) + sum_d (max_z A(s, z_d) - b_d(s))``.

        :param features: ``(batch, features_dim)``
        :return: the interval index of ``z*`` in each dimension ``(batch, action_dim)`` (int64) and ``Q(s, z*)``
            ``(batch, 1)``
        """
        value, coefficients = self._heads(features)
        at_centres = coefficients @ self.basis_at_centres
        best, index = at_centres.max(dim=-1)
        baseline = at_centres.mean(dim=-1) if self.aggregation == "mean" else best
        return index, value + (best - baseline).sum(dim=1, keepdim=True)
