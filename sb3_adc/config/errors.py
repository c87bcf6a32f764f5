"""The error raised for a bad hyperparameter file, entry, key or value."""

from __future__ import annotations


class HyperparamsError(ValueError):
    """
    A hyperparameter file or one of its values is invalid.

    The message names where the problem is (``source``: the file and, when known, the entry), the key,
    and the offending value or expression, then says what is accepted.

    :param source: Where the value comes from: a file path, optionally followed by ``[entry]``
        (for example ``hyperparams/adc.yml [Pendulum-v1]``), or ``command line``
    :param key: The hyperparameter key (dotted for nested values, e.g. ``policy_kwargs.activation_fn``);
        ``None`` for a problem with the file or entry as a whole
    :param problem: What is wrong and what is accepted
    :param expression: The offending value or expression as written, if any
    """

    def __init__(self, source: str, key: str | None, problem: str, expression: str | None = None):
        self.source = source
        self.key = key
        self.problem = problem
        self.expression = expression
        location = source if key is None else f"{source}: `{key}`"
        offending = "" if expression is None else f"; offending expression: {expression!r}"
        super().__init__(f"{location}: {problem}{offending}")
