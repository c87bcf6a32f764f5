"""
Checks of single hyperparameter values.

Every validator takes ``(value, source, key)``, returns the value in its canonical form (ints for counts,
floats for rates, ...) and raises :class:`~sb3_adc.config.errors.HyperparamsError` naming the source, the
key and the accepted values otherwise.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

from sb3_adc.config.errors import HyperparamsError, short_repr

Validator = Callable[[Any, str, str], Any]


def _fail(value: Any, source: str, key: str, accepted: str) -> HyperparamsError:
    return HyperparamsError(source, key, f"expected {accepted}, got {short_repr(value)} ({type(value).__name__})")


def _as_number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def integer(minimum: int | None = None, allowed: tuple[int, ...] = (), maximum: int | None = None) -> Validator:
    """
    An integer ``>= minimum`` and ``<= maximum`` (or one of ``allowed``); a float with an integer value (``1e5``)
    is accepted.

    :param minimum: The smallest accepted value
    :param allowed: Values accepted besides the range (such as ``-1`` for "all")
    :param maximum: The largest accepted value (for options that size memory)
    """
    low = "" if minimum is None else f" >= {minimum}"
    high = "" if maximum is None else f" <= {maximum}"
    accepted = "an integer" + low + ("," if low and high else "") + high + "".join(f" or {value}" for value in allowed)

    def check(value: Any, source: str, key: str) -> int:
        number = _as_number(value)
        if number is None or not math.isfinite(number) or number != int(number):
            raise _fail(value, source, key, accepted)
        result = int(number)
        if result in allowed or ((minimum is None or result >= minimum) and (maximum is None or result <= maximum)):
            return result
        raise _fail(value, source, key, accepted)

    return check


def real(minimum: float | None = None, maximum: float | None = None, exclusive_minimum: bool = False) -> Validator:
    """
    A finite number in a range (ints are accepted and converted).

    :param minimum: The lower bound
    :param maximum: The upper bound (included)
    :param exclusive_minimum: Whether ``minimum`` itself is excluded
    """
    low = "" if minimum is None else f" {'>' if exclusive_minimum else '>='} {minimum}"
    high = "" if maximum is None else f" <= {maximum}"
    accepted = "a number" + low + ("," if low and high else "") + high

    def check(value: Any, source: str, key: str) -> float:
        number = _as_number(value)
        if number is None or not math.isfinite(number):
            raise _fail(value, source, key, accepted)
        if minimum is not None and (number < minimum or (exclusive_minimum and number == minimum)):
            raise _fail(value, source, key, accepted)
        if maximum is not None and number > maximum:
            raise _fail(value, source, key, accepted)
        return number

    return check


def layer_sizes(max_width: int, max_weights: int) -> Validator:
    """
    Hidden layer sizes (``net_arch``): a list of integers from 1 to ``max_width``, or a mapping of such lists (SB3's
    ``dict(pi=[...], qf=[...])``), whose consecutive layers hold at most ``max_weights`` weights in all.

    :param max_width: The most units of a layer
    :param max_weights: The most weights between hidden layers (``sum(w[i] * w[i + 1])``) of each list
    """
    accepted = f"a list of layer sizes from 1 to {max_width} (or a mapping of such lists)"

    def check(value: Any, source: str, key: str) -> Any:
        if isinstance(value, dict):
            return {name: check(sizes, source, f"{key}.{name}") for name, sizes in mapping(value, source, key).items()}
        if not isinstance(value, (list, tuple)):
            raise _fail(value, source, key, accepted)
        sizes = [integer(1, maximum=max_width)(size, source, key) for size in value]
        weights = sum(a * b for a, b in itertools.pairwise(sizes))
        if weights > max_weights:
            raise HyperparamsError(
                source, key, f"expected at most {max_weights} weights between hidden layers, got {weights} for {sizes}"
            )
        return sizes

    return check


def boolean(value: Any, source: str, key: str) -> bool:
    """``true`` or ``false``."""
    if not isinstance(value, bool):
        raise _fail(value, source, key, "true or false")
    return value


def choice(*options: str) -> Validator:
    """
    One of the given strings.

    :param options: The accepted strings
    """

    def check(value: Any, source: str, key: str) -> str:
        if not isinstance(value, str) or value not in options:
            raise _fail(value, source, key, "one of " + ", ".join(repr(option) for option in options))
        return value

    return check


def string(value: Any, source: str, key: str) -> str:
    """A non-empty string."""
    if not isinstance(value, str) or not value:
        raise _fail(value, source, key, "a non-empty string")
    return value


def mapping(value: Any, source: str, key: str) -> dict[str, Any]:
    """A mapping with string keys (``{}`` for ``null``)."""
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(name, str) for name in value):
        raise _fail(value, source, key, "a mapping with string keys")
    return dict(value)


def scalar(value: Any, source: str, key: str) -> Any:
    """A YAML scalar: a number, string, boolean or ``null``."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise _fail(value, source, key, "a number, string, boolean or null")


def learning_rate(value: Any, source: str, key: str) -> float | str:
    """A positive number, or ``lin_<number>`` (linear decay from that number to 0 over training)."""
    accepted = "a number > 0 or 'lin_<number>' (linear decay to 0)"
    if isinstance(value, str):
        prefix, _, initial = value.partition("_")
        try:
            number = float(initial)
        except ValueError:
            raise _fail(value, source, key, accepted) from None
        if prefix != "lin" or not (math.isfinite(number) and number > 0):
            raise _fail(value, source, key, accepted)
        return value
    rate = _as_number(value)
    if rate is None or not (math.isfinite(rate) and rate > 0):
        raise _fail(value, source, key, accepted)
    return rate


def train_freq(value: Any, source: str, key: str) -> int | list[Any]:
    """An integer >= 1 (steps), or ``[n, "step"]`` / ``[n, "episode"]``."""
    accepted = 'an integer >= 1 or [n, "step" | "episode"]'
    if isinstance(value, (list, tuple)):
        if len(value) != 2 or value[1] not in ("step", "episode"):
            raise _fail(value, source, key, accepted)
        return [integer(1)(value[0], source, key), value[1]]
    try:
        return integer(1)(value, source, key)
    except HyperparamsError:
        raise _fail(value, source, key, accepted) from None


def noise_std(value: Any, source: str, key: str) -> float | list[float]:
    """A number >= 0, or one number >= 0 per action dimension."""
    if isinstance(value, (list, tuple)) and value:
        return [real(0.0)(element, source, key) for element in value]
    return real(0.0)(value, source, key)


def entropy_coefficient(value: Any, source: str, key: str) -> float | str:
    """SAC's ``ent_coef``: a number >= 0, ``auto`` or ``auto_<initial value>``."""
    if isinstance(value, str):
        if value == "auto" or (value.startswith("auto_") and _is_positive_float(value[len("auto_") :])):
            return value
        raise _fail(value, source, key, "a number >= 0, 'auto' or 'auto_<initial value>'")
    return real(0.0)(value, source, key)


def target_entropy(value: Any, source: str, key: str) -> float | str:
    """SAC's ``target_entropy``: a number or ``auto``."""
    if value == "auto":
        return value
    return real()(value, source, key)


def _is_positive_float(text: str) -> bool:
    try:
        number = float(text)
    except ValueError:
        return False
    return math.isfinite(number) and number > 0


def class_reference(value: Any, source: str, key: str) -> Any:
    """A name (resolved later through an allow-list), a list of names, or a mapping ``{name: kwargs}``."""
    if isinstance(value, str) and value:
        return value
    if isinstance(value, dict) and len(value) == 1:
        ((name, kwargs),) = value.items()
        if isinstance(name, str):
            return {name: mapping(kwargs, source, f"{key}.{name}")}
    if isinstance(value, list):
        return [class_reference(element, source, key) for element in value]
    raise _fail(value, source, key, "a name, a {name: {keyword: value}} mapping, or a list of those")


def mapping_or_expression(value: Any, source: str, key: str) -> dict[str, Any] | str:
    """A mapping, or a string such as ``"dict(net_arch=[64, 64])"`` (parsed later, never executed)."""
    if isinstance(value, str):
        return value
    return mapping(value, source, key)


def normalize(value: Any, source: str, key: str) -> bool | dict[str, Any] | str:
    """``true``/``false``, a mapping of ``VecNormalize`` keywords, or such a mapping as a string."""
    if isinstance(value, bool):
        return value
    if isinstance(value, (dict, str)):
        return mapping_or_expression(value, source, key)
    raise _fail(value, source, key, "true, false, or a mapping of VecNormalize keywords (norm_obs, norm_reward, ...)")


def optional(validator: Validator) -> Validator:
    """
    ``null`` or a value accepted by ``validator``.

    :param validator: The validator of non-null values
    """

    def check(value: Any, source: str, key: str) -> Any:
        return None if value is None else validator(value, source, key)

    return check


def checked_by(check: Callable[[Any], None], canonical: Validator | None = None) -> Validator:
    """
    A value accepted by ``check``, the validation function of the class that owns the option (for instance
    :func:`sb3_adc.adc.intervals.check_n_intervals`), so that the files accept exactly what the class does.

    :param check: Raises ``ValueError`` (or ``TypeError``) naming the accepted values for a value it refuses
    :param canonical: A validator applied first, for the value's canonical form (``integer()`` reads ``1e2`` as 100)
    """

    def validate(value: Any, source: str, key: str) -> Any:
        if canonical is not None:
            value = canonical(value, source, key)
        try:
            check(value)
        except (ValueError, TypeError) as error:
            raise HyperparamsError(source, key, str(error)) from None
        return value

    return validate
