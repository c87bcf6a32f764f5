"""Checks of the spaces an algorithm is given, with errors that name the parameter and the accepted values."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces


class ActionSpaceError(AssertionError):
    """
    An action space the algorithm cannot act in.

    SB3 rejects such spaces with ``assert`` (``supported_action_spaces`` and the finite-bounds check of
    ``BaseAlgorithm``), so code written against SB3 catches ``AssertionError``; the subclasses are also the
    built-in type that says what is wrong (``TypeError`` or ``ValueError``).
    """


class UnsupportedActionSpaceError(ActionSpaceError, TypeError):
    """The action space is not a :class:`gymnasium.spaces.Box` (an ``AssertionError`` and a ``TypeError``)."""


class ActionBoundsError(ActionSpaceError, ValueError):
    """The bounds of a ``Box`` action space are infinite, NaN or empty (an ``AssertionError`` and a ``ValueError``)."""


def check_action_space(action_space: spaces.Space) -> None:
    """
    Raise an error unless ``action_space`` is a bounded, finite :class:`gymnasium.spaces.Box`.

    ADC's actor outputs continuous actions squashed into ``[low, high]`` and its critic partitions that range
    into uniform intervals, so the range must be continuous and finite.

    :param action_space: The environment's action space
    :raises UnsupportedActionSpaceError: if it is not a ``Box`` (for instance ``Discrete`` or ``MultiDiscrete``);
        an ``AssertionError``, as SB3 raises, and a ``TypeError``
    :raises ActionBoundsError: if a bound is infinite or NaN, or ``high <= low`` somewhere; an ``AssertionError``,
        as SB3 raises, and a ``ValueError``
    """
    if not isinstance(action_space, spaces.Box):
        hint = ""
        if isinstance(action_space, (spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary)):
            hint = " For discrete actions use a value-based method such as SB3's DQN."
        raise UnsupportedActionSpaceError(
            f"`action_space` must be a continuous gymnasium.spaces.Box with finite bounds, got {action_space!r}.{hint}"
        )
    low, high = np.asarray(action_space.low), np.asarray(action_space.high)
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        raise ActionBoundsError(
            f"`action_space` must have finite bounds (the critic partitions [low, high] into intervals), "
            f"got low={low.tolist()}, high={high.tolist()}. Give the space the true, finite limits of the actuator, "
            "e.g. with a gymnasium.ActionWrapper whose `action_space` is a Box of those limits (gymnasium's ClipAction "
            "keeps infinite bounds infinite and RescaleAction refuses them, so neither helps here)."
        )
    if np.any(high <= low):
        raise ActionBoundsError(
            f"`action_space` must have high > low in every dimension, got low={low.tolist()}, high={high.tolist()}."
        )
