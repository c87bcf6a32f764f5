"""
Action intervals of the dueling critic: the uniform partition of the action range and the aggregation of
the advantage stream into a Q-value.

ADC paper, Section 4: the action range is split into ``n`` uniform intervals ``z_1 .. z_n``; the advantage
stream outputs one value per interval, and the Q-value of an action ``a`` uses the advantage of the interval
``z_a`` that contains it (Eq. 13-14)::

    Q(s, a) = V(s) + A(s, z_a) - mean_z A(s, z)        (aggregation="mean", Eq. 12-14)
    Q(s, a) = V(s) + A(s, z_a) - max_z A(s, z)         (aggregation="max", Eq. 11)

The centred advantage is linear in the vector of interval advantages: ``A(s, z_a) - mean_z A(s, z)`` is the
dot product of ``A(s, .)`` with the weights ``e_{z_a} - 1/n`` (``e_k`` the k-th unit vector), and with
``e_{z_a} - e_{argmax}`` for the max. The code computes it that way: one weight vector per sample, written by a
scatter into a filled tensor (no ``n x n`` table: memory is linear in ``n``), then a product and a sum, which is
the cheapest form for autograd.

Actions are SB3's scaled actions in ``[-1, 1]``. With several action dimensions the advantage is factorised:
one branch of ``n`` intervals per dimension, each branch centred on its own, and the centred branches summed.
"""

from __future__ import annotations

from typing import Literal, get_args

import torch as th
from torch import nn

Aggregation = Literal["mean", "max"]
Interpolation = Literal["none", "linear"]

AGGREGATIONS: tuple[str, ...] = get_args(Aggregation)
INTERPOLATIONS: tuple[str, ...] = get_args(Interpolation)


#: Largest accepted ``n_intervals``. The critic's advantage output layer has ``action_dim * n_intervals`` units, and
#: every training sample carries weights over all of them: 10 000 intervals per action dimension (a resolution of
#: 0.0002 of the action range) already cost about 40 kB per sample and dimension.
MAX_N_INTERVALS = 10_000


def check_n_intervals(n_intervals: object) -> None:
    """
    Raise ``ValueError`` unless ``n_intervals`` is an integer from 2 to :data:`MAX_N_INTERVALS`.

    :param n_intervals: Number of uniform intervals per action dimension
    """
    if isinstance(n_intervals, bool) or not isinstance(n_intervals, int) or not 2 <= n_intervals <= MAX_N_INTERVALS:
        raise ValueError(
            f"`n_intervals` must be an integer >= 2 (one advantage per interval) and <= {MAX_N_INTERVALS} "
            f"(MAX_N_INTERVALS), got {n_intervals!r}."
        )


def validate_interval_options(n_intervals: object, aggregation: object, advantage_interpolation: object) -> None:
    """
    Raise ``ValueError`` naming the parameter and its accepted values when an option of the dueling
    critic is invalid.

    :param n_intervals: Number of uniform intervals per action dimension (an ``int`` >= 2)
    :param aggregation: ``"mean"`` (Eq. 12-14) or ``"max"`` (Eq. 11)
    :param advantage_interpolation: ``"none"`` or ``"linear"``
    """
    check_n_intervals(n_intervals)
    if aggregation not in AGGREGATIONS:
        raise ValueError(f"`aggregation` must be one of {AGGREGATIONS}, got {aggregation!r}.")
    if advantage_interpolation not in INTERPOLATIONS:
        raise ValueError(f"`advantage_interpolation` must be one of {INTERPOLATIONS}, got {advantage_interpolation!r}.")


class UniformIntervalPartition(nn.Module):
    """
    The uniform partition of the scaled action range ``[-1, 1]`` into ``n_intervals`` intervals.

    Interval ``k`` (0-based) is ``[edges[k], edges[k + 1])``; the last one also contains ``+1``, so ``-1``
    falls in the first interval and ``+1`` in the last. Actions outside ``[-1, 1]`` fall in the nearest
    end interval. The edges are a buffer: they travel with the state dict, which lets a loaded model
    be checked against the ``n_intervals`` it was saved with.

    :param n_intervals: Number of intervals (from 2 to :data:`MAX_N_INTERVALS`); the module's memory is linear in it
    """

    edges: th.Tensor
    centres: th.Tensor
    _inner_edges: th.Tensor

    def __init__(self, n_intervals: int):
        super().__init__()
        check_n_intervals(n_intervals)
        self.n_intervals = n_intervals
        edges = th.linspace(-1.0, 1.0, n_intervals + 1)
        self.register_buffer("edges", edges)
        self.register_buffer("centres", (edges[:-1] + edges[1:]) / 2, persistent=False)
        self.register_buffer("_inner_edges", edges[1:-1].contiguous(), persistent=False)

    def extra_repr(self) -> str:
        return f"n_intervals={self.n_intervals}"

    def _filled(self, shape: tuple[int, ...], value: float, dtype: th.dtype | None = None) -> th.Tensor:
        """A new tensor of ``shape`` filled with ``value``, on the partition's device (and dtype by default)."""
        return th.full(shape, value, dtype=dtype or self.edges.dtype, device=self.edges.device)

    def _one_hot(self, index: th.Tensor, on: float = 1.0, off: float = 0.0) -> th.Tensor:
        """``(*index.shape, n_intervals)``: ``on`` at each index, ``off`` elsewhere (the rows of ``(on - off) I + off``
        that ``index`` selects, without the ``n x n`` table)."""
        return self._filled((*index.shape, self.n_intervals), off).scatter_(-1, index.unsqueeze(-1), on)

    def index(self, actions: th.Tensor) -> th.Tensor:
        """
        Index of the interval that contains each action.

        :param actions: Scaled actions, any shape
        :return: ``int64`` tensor of the same shape, values in ``[0, n_intervals - 1]``
        """
        return th.bucketize(actions, self._inner_edges, right=True)

    def selection_weights(self, actions: th.Tensor, interpolation: Interpolation) -> th.Tensor:
        """
        Weights over the intervals that read the advantage of each action: ``sum_z w_z A(s, z)``.

        ``"none"`` (the paper): the unit vector of the interval that contains the action, so the advantage is
        piecewise constant in the action. ``"linear"`` (an extension): linear interpolation between the two
        interval centres nearest to the action (constant beyond the first and last centre), so the advantage is
        piecewise linear in the action and passes a gradient to it.

        :param actions: ``(batch, action_dim)`` scaled actions
        :param interpolation: ``"none"`` or ``"linear"``
        :return: ``(batch, action_dim, n_intervals)``, each row non-negative and summing to 1
        """
        if interpolation == "none":
            return self._one_hot(self.index(actions))
        lower, upper_share = self._neighbour_centres(actions)
        upper_share = upper_share.unsqueeze(-1)
        lower = lower.unsqueeze(-1)
        weights = self._filled((*lower.shape[:-1], self.n_intervals), 0.0, upper_share.dtype)
        # Differentiable in the action through the shares (scatter passes the gradient of its source).
        return weights.scatter(-1, lower, 1.0 - upper_share).scatter(-1, lower + 1, upper_share)

    def _neighbour_centres(self, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """The interval centres on either side of each action: the lower one's index, and the upper one's share
        of the linear interpolation (in ``[0, 1]``, with a gradient with respect to the action)."""
        n = self.n_intervals
        # Position in units of intervals, measured from the first centre: centre k sits at position k.
        position = ((actions + 1.0) * (n / 2.0) - 0.5).clamp(0.0, n - 1.0)
        lower = position.detach().floor().clamp(max=n - 2).long()
        return lower, position - lower

    def centred_weights(
        self,
        actions: th.Tensor,
        advantages: th.Tensor | None,
        aggregation: Aggregation,
        interpolation: Interpolation,
    ) -> th.Tensor:
        """
        Weights ``c`` such that ``sum_z c_z A(s, z)`` is the centred advantage of each action branch:
        ``A(s, z_a) - mean_z A(s, z)`` (Eq. 13) or ``A(s, z_a) - max_z A(s, z)`` (Eq. 11).

        :param actions: ``(batch, action_dim)`` scaled actions
        :param advantages: ``(batch, action_dim, n_intervals)``, used (without gradient) to find the maximum
            for ``aggregation="max"``; not needed (``None``) for ``"mean"``
        :param aggregation: ``"mean"`` or ``"max"``
        :param interpolation: ``"none"`` or ``"linear"``
        :return: ``(batch, action_dim, n_intervals)``
        """
        if aggregation == "mean" and interpolation == "none":
            # The paper's case, in one scatter: e_{z_a} - 1/n.
            return self._one_hot(self.index(actions), on=1.0 - 1.0 / self.n_intervals, off=-1.0 / self.n_intervals)
        weights = self.selection_weights(actions, interpolation)
        if aggregation == "mean":
            return weights - 1.0 / self.n_intervals
        if advantages is None:
            raise ValueError('`advantages` are needed to centre on their maximum (aggregation="max").')
        # The gradient of max_z A is the unit vector of the arg max.
        return weights - self._one_hot(advantages.detach().argmax(dim=-1))

    def select(self, advantages: th.Tensor, actions: th.Tensor, interpolation: Interpolation) -> th.Tensor:
        """
        The advantage of each action (see :meth:`selection_weights`).

        :param advantages: ``(batch, action_dim, n_intervals)``
        :param actions: ``(batch, action_dim)`` scaled actions
        :param interpolation: ``"none"`` or ``"linear"``
        :return: ``(batch, action_dim)``
        """
        return (advantages * self.selection_weights(actions, interpolation)).sum(dim=-1)


def aggregate(value: th.Tensor, advantages: th.Tensor, centred_weights: th.Tensor) -> th.Tensor:
    """
    Combine the value and advantage streams into ``Q`` (Eq. 11 or Eq. 12-14), one centred advantage branch
    per action dimension, summed over the dimensions.

    :param value: ``(batch, 1)``
    :param advantages: ``(batch, action_dim, n_intervals)``
    :param centred_weights: ``(batch, action_dim, n_intervals)`` from
        :meth:`UniformIntervalPartition.centred_weights`
    :return: ``(batch, 1)``
    """
    return value + (advantages * centred_weights).flatten(1).sum(dim=1, keepdim=True)
