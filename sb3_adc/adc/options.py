"""Checks of ADC's own constructor options (those that are not the policy's), as the class and the config files apply them."""

from __future__ import annotations

import math
from collections.abc import Callable


def _check_number(name: str, value: object, in_range: Callable[[float], bool], expected: str) -> None:
    """
    Raise ``ValueError`` unless ``value`` is an int or a float (not a bool) for which ``in_range`` holds.

    :param name: The option's name, for the message
    :param value: The value given
    :param in_range: Whether a number is accepted
    :param expected: What is accepted, for the message (``"a number in [0, 1]"``)
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not in_range(value):
        raise ValueError(f"`{name}` must be {expected}, got {value!r}.")


def check_target_greedy_mix(target_greedy_mix: object) -> None:
    """
    Raise ``ValueError`` unless ``target_greedy_mix`` is a number in ``[0, 1]`` (see :class:`~sb3_adc.ADC`).

    :param target_greedy_mix: Share of the greedy value ``Q'(s', z*)`` in the TD target's next-state value
    """
    _check_number("target_greedy_mix", target_greedy_mix, lambda x: 0 <= x <= 1, "a number in [0, 1]")


def check_actor_greedy_weight(actor_greedy_weight: object) -> None:
    """
    Raise ``ValueError`` unless ``actor_greedy_weight`` is a finite number >= 0 (see :class:`~sb3_adc.ADC`).

    :param actor_greedy_weight: Weight of the actor's pull toward the best interval centre
    """
    _check_number("actor_greedy_weight", actor_greedy_weight, lambda x: 0 <= x < math.inf, "a finite number >= 0")


def check_interval_exploration(interval_exploration: object) -> None:
    """
    Raise ``ValueError`` unless ``interval_exploration`` is a number in ``[0, 1]`` (see :class:`~sb3_adc.ADC`).

    :param interval_exploration: Probability ``p`` that an action component is drawn from the Boltzmann
        distribution of the interval advantages instead of the actor plus its action noise
    """
    _check_number("interval_exploration", interval_exploration, lambda x: 0 <= x <= 1, "a number in [0, 1]")


def check_interval_temperature(interval_temperature: object) -> None:
    """
    Raise ``ValueError`` unless ``interval_temperature`` is a finite number > 0 (see :class:`~sb3_adc.ADC`).

    :param interval_temperature: Temperature ``T`` of the Boltzmann distribution ``softmax(A(s, z) / T)`` over the
        interval centres, in the units of the critic's Q-values
    """
    _check_number("interval_temperature", interval_temperature, lambda x: 0 < x < math.inf, "a finite number > 0")


def check_fast_update(fast_update: object) -> None:
    """
    Raise ``ValueError`` unless ``fast_update`` is a bool (see :class:`~sb3_adc.ADC`).

    :param fast_update: Whether ADC trains with its fast update path
    """
    if not isinstance(fast_update, bool):
        raise ValueError(f"`fast_update` must be true or false, got {fast_update!r}.")
