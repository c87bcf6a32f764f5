"""
Exploration from the advantages: a Boltzmann draw over the interval centres beside the actor and its action noise.

Not in the ADC paper, whose exploration is the actor plus epsilon-gated Gaussian noise (Algorithm 1, line 5). The
critic's advantage stream gives ``A_d(s, z)`` at every interval centre ``z`` of every action dimension ``d`` in one
pass (Eq. 13-14 evaluated at the centres). When collecting experience, with probability ``p`` (independently per
action dimension) the action component is replaced by a draw of an interval ``k`` from the Boltzmann distribution
of its advantages, then a uniform draw within that interval::

    P(k | s) = softmax_k(A_d(s, z_k) / T),      a_d ~ U[e_k, e_{k+1})

(``e`` the interval edges of the scaled action range ``[-1, 1]``); otherwise the actor's action plus the action
noise is kept. Because ``Q`` is additive across action dimensions, ``A_d(s, z) / T`` is ``Q(s, .) / T`` along
dimension ``d`` up to a constant, so the draw is the Boltzmann policy of ``Q`` over that dimension's intervals
whatever the other components are. The baseline subtracted from the advantages (Eq. 11 or 13) cancels in the
softmax.
"""

from __future__ import annotations

from collections.abc import Callable

import torch as th


def boltzmann_interval_draw(
    advantages: th.Tensor,
    edges: th.Tensor,
    temperature: float,
    generator: th.Generator | None = None,
) -> tuple[th.Tensor, th.Tensor]:
    """
    Interval advantages of the dueling critic (Eq. 13-14 at the interval centres) turned into exploratory actions:
    per action dimension, an interval ``k`` drawn with probability ``softmax_k(A(s, z_k) / T)``, then an action drawn
    uniformly within it.

    The interval is drawn by the Gumbel-max trick, ``argmax_k ((A_k - max_j A_j) / T + G_k)`` with ``G_k`` standard
    Gumbel, which is exact for every ``T > 0`` and, as ``T`` goes to 0, the argmax of the advantages.

    :param advantages: ``A(s, z)`` of every interval centre, ``(batch, action_dim, n_intervals)``
    :param edges: The ``n_intervals + 1`` interval edges of the scaled action range ``[-1, 1]``, increasing
    :param temperature: ``T > 0``
    :param generator: Random generator of the draws (on the advantages' device); ``None``: torch's global one
    :return: the scaled actions ``(batch, action_dim)``, each in ``[e_k, e_{k+1})`` of its drawn interval ``k``,
        and the drawn interval indices ``(batch, action_dim)`` (int64)
    """
    scores = (advantages - advantages.amax(dim=-1, keepdim=True)) / temperature
    # Exp(1) -> -log: standard Gumbel noise.
    gumbel = th.empty_like(scores).exponential_(generator=generator).log_().neg_()
    index = (scores + gumbel).argmax(dim=-1)
    lower, upper = edges[index], edges[index + 1]
    uniform = th.rand(index.shape, generator=generator, dtype=edges.dtype, device=edges.device)
    # Kept below the upper edge, which belongs to the next interval, whatever the rounding of the product.
    return th.minimum(lower + uniform * (upper - lower), th.nextafter(upper, lower)), index


def explore_from_advantages(
    actions: th.Tensor,
    advantages: Callable[[], th.Tensor],
    edges: th.Tensor,
    probability: float,
    temperature: float,
    generator: th.Generator | None = None,
) -> th.Tensor:
    """
    Exploration from the interval advantages: each component of the exploratory actions (the actor's plus action
    noise) replaced, with probability ``p`` and independently of the others, by a Boltzmann draw over the intervals
    of its dimension (:func:`boltzmann_interval_draw`).

    :param actions: Scaled actions to explore around, ``(batch, action_dim)`` in ``[-1, 1]``
    :param advantages: Gives ``A(s, z)`` of every interval centre, ``(batch, action_dim, n_intervals)``, on the device
        of ``actions``; called only when a component is replaced (a critic pass saved on the other steps)
    :param edges: The ``n_intervals + 1`` interval edges of ``[-1, 1]``
    :param probability: ``p`` in ``[0, 1]``
    :param temperature: ``T > 0``
    :param generator: Random generator of the draws; ``None``: torch's global one
    :return: ``(batch, action_dim)``, of the dtype of ``actions``
    """
    replaced = th.rand(actions.shape, generator=generator, device=actions.device) < probability
    if not replaced.any():
        return actions
    drawn, _ = boltzmann_interval_draw(advantages(), edges, temperature, generator)
    return th.where(replaced, drawn.to(actions.dtype), actions)
