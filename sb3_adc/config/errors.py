"""The error raised for a bad hyperparameter file, entry, key or value."""

from __future__ import annotations

import reprlib
from typing import Any

#: Longest representation of an offending value or expression shown in an error message (characters).
MAX_SHOWN_CHARACTERS = 200

_SHORT_REPR = reprlib.Repr()
_SHORT_REPR.maxlevel, _SHORT_REPR.maxstring, _SHORT_REPR.maxother = 3, 60, 60


def short_repr(value: Any) -> str:
    """
    A bounded representation of ``value`` for an error message, whose cost does not grow with a YAML alias bomb.

    :param value: The value to show
    """
    text = repr(value) if isinstance(value, str) else _SHORT_REPR.repr(value)  # an expression: whole up to the limit
    half = MAX_SHOWN_CHARACTERS // 2
    return text if len(text) <= MAX_SHOWN_CHARACTERS else f"{text[:half]}...{text[-half:]}"


class HyperparamsError(ValueError):
    """
    A hyperparameter file or value is invalid: the message names source, key and offending value, and what is accepted.

    :param source: Where the value comes from: a file path, optionally followed by ``[entry]``
        (for example ``hyperparams/adc.yml [Pendulum-v1]``), or ``command line``
    :param key: The hyperparameter key (dotted for nested values, e.g. ``policy_kwargs.activation_fn``);
        ``None`` for a problem with the file or entry as a whole
    :param problem: What is wrong and what is accepted
    :param expression: The offending value or expression as written, if any
    """

    def __init__(self, source: str, key: str | None, problem: str, expression: str | None = None):
        self.source, self.key, self.problem, self.expression = source, key, problem, expression
        location = source if key is None else f"{source}: `{key}`"
        offending = "" if expression is None else f"; offending expression: {short_repr(expression)}"
        super().__init__(f"{location}: {problem}{offending}")
