"""
Action intervals of the dueling critic: the uniform partition of the action range and the aggregation of
the advantage stream into a Q-value.

ADC paper, Section 4: the action range is split into ``n`` uniform intervals ``z_1 .. z_n``; the advantage
stream outputs one value per interval, and the Q-value of an action ``a`` uses the advantage of the interval
``z_a`` that contains it (Eq. 13-14)::

    Q(s, a) = V(s) + A(s, z_a) - mean_z A(s, z)        (aggregation="mean", Eq. 12-14)
    Q(s, a) = V(s) + A(s, z_a) - max_z A(s, z)         (aggregation="max", Eq. 11)

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


def validate_interval_options(n_intervals: object, aggregation: object, advantage_interpolation: object) -> None:
    """
    Raise ``ValueError`` naming the parameter and its accepted values when an option of the dueling
    critic is invalid.

    :param n_intervals: Number of uniform intervals per action dimension (an ``int`` >= 2)
    :param aggregation: ``"mean"`` (Eq. 12-14) or ``"max"`` (Eq. 11)
    :param advantage_interpolation: ``"none"`` or ``"linear"``
    """
    if isinstance(n_intervals, bool) or not isinstance(n_intervals, int) or n_intervals < 2:
        raise ValueError(f"`n_intervals` must be an integer >= 2 (one advantage per interval), got {n_intervals!r}.")
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

    :param n_intervals: Number of intervals (>= 2)
    """

    edges: th.Tensor
    centres: th.Tensor
    _inner_edges: th.Tensor

    def __init__(self, n_intervals: int):
        super().__init__()
        if isinstance(n_intervals, bool) or not isinstance(n_intervals, int) or n_intervals < 2:
            raise ValueError(f"`n_intervals` must be an integer >= 2, got {n_intervals!r}.")
        self.n_intervals = n_intervals
        edges = th.linspace(-1.0, 1.0, n_intervals + 1)
        self.register_buffer("edges", edges)
        self.register_buffer("centres", (edges[:-1] + edges[1:]) / 2, persistent=False)
        self.register_buffer("_inner_edges", edges[1:-1].contiguous(), persistent=False)

    def extra_repr(self) -> str:
        return f"n_intervals={self.n_intervals}"

    def index(self, actions: th.Tensor) -> th.Tensor:
        """
        Index of the interval that contains each action.

        :param actions: Scaled actions, any shape
        :return: ``int64`` tensor of the same shape, values in ``[0, n_intervals - 1]``
        """
        return th.bucketize(actions.detach().contiguous(), self._inner_edges, right=True)

    def select(self, advantages: th.Tensor, actions: th.Tensor, interpolation: Interpolation) -> th.Tensor:
        """
        The advantage of each action, read from the per-interval advantages.

        ``"none"`` (the paper): the advantage of the interval that contains the action, piecewise constant in
        the action. ``"linear"`` (an extension): linear interpolation between the two interval centres
        nearest to the action (constant beyond the first and last centre), so the advantage is piecewise
        linear in the action and passes a gradient to it.

        :param advantages: ``(batch, action_dim, n_intervals)``
        :param actions: ``(batch, action_dim)`` scaled actions
        :param interpolation: ``"none"`` or ``"linear"``
        :return: ``(batch, action_dim)``
        """
        if interpolation == "none":
            return advantages.gather(-1, self.index(actions).unsqueeze(-1)).squeeze(-1)
        n = self.n_intervals
        # Position in units of intervals, measured from the first centre: centre k sits at position k.
        position = ((actions + 1.0) * (n / 2.0) - 0.5).clamp(0.0, n - 1.0)
        lower = position.detach().floor().clamp(max=n - 2).long()
        weight = (position - lower).unsqueeze(-1)
        neighbours = advantages.gather(-1, th.stack((lower, lower + 1), dim=-1))
        return (neighbours[..., :1] * (1.0 - weight) + neighbours[..., 1:] * weight).squeeze(-1)


def aggregate(value: th.Tensor, advantages: th.Tensor, selected: th.Tensor, aggregation: Aggregation) -> th.Tensor:
    """
    Combine the value and advantage streams into ``Q`` (Eq. 11 or Eq. 12-14), one centred advantage branch
    per action dimension, summed over the dimensions.

    :param value: ``(batch, 1)``
    :param advantages: ``(batch, action_dim, n_intervals)``
    :param selected: ``(batch, action_dim)``, the advantage of the taken action in each branch
    :param aggregation: ``"mean"`` or ``"max"``
    :return: ``(batch, 1)``
    """
    baseline = advantages.mean(dim=-1) if aggregation == "mean" else advantages.amax(dim=-1)
    return value + (selected - baseline).sum(dim=-1, keepdim=True)
