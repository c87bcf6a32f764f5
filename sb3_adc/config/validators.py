"""Validators: ``(value, source, key)`` -> the value in canonical form, or a HyperparamsError naming the accepted."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

from sb3_adc.config.errors import HyperparamsError, short_repr

Validator = Callable[[Any, str, str], Any]


def _fail(value: Any, source: str, key: str, accepted: str) -> HyperparamsError:
    return HyperparamsError(source, key, f"expected {accepted}, got {short_repr(value)} ({type(value).__name__})")


def _accepting(accepted: str, test: Callable[[Any], bool], convert: Callable[[Any], Any] = lambda value: value) -> Validator:
    """The validator of the values that pass ``test``, returned as ``convert(value)``; ``accepted`` describes them."""

    def check(value: Any, source: str, key: str) -> Any:
        if not test(value):
            raise _fail(value, source, key, accepted)
        return convert(value)

    return check


def _finite(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def _integral(value: Any) -> int | None:
    number = _finite(value)
    return None if number is None or number != int(number) else int(number)


def _positive(text: str, prefix: str) -> bool:
    try:
        return text.startswith(prefix) and (_finite(float(text[len(prefix) :])) or 0.0) > 0
    except ValueError:
        return False


def _range(minimum: float | None, maximum: float | None, low: str = ">=") -> str:
    bounds = [f"{low} {minimum}"] * (minimum is not None) + [f"<= {maximum}"] * (maximum is not None)
    return f" {', '.join(bounds)}" if bounds else ""


def _within(number: float | None, minimum: float | None, maximum: float | None, exclusive_minimum: bool = False) -> bool:
    if number is None:
        return False
    above = minimum is None or number > minimum or (number == minimum and not exclusive_minimum)
    return above and (maximum is None or number <= maximum)


def integer(minimum: int | None = None, allowed: tuple[int, ...] = (), maximum: int | None = None) -> Validator:
    """
    An integer ``>= minimum`` and ``<= maximum`` (or one of ``allowed``); a float with an integer value (``1e5``) too.

    :param minimum: The smallest accepted value
    :param allowed: Values accepted besides the range (such as ``-1`` for "all")
    :param maximum: The largest accepted value (for options that size memory)
    """
    accepted = "an integer" + _range(minimum, maximum) + "".join(f" or {value}" for value in allowed)
    return _accepting(
        accepted, lambda value: _integral(value) in allowed or _within(_integral(value), minimum, maximum), _integral
    )


def real(minimum: float | None = None, maximum: float | None = None, exclusive_minimum: bool = False) -> Validator:
    """
    A finite number in a range (ints are accepted and converted).

    :param minimum: The lower bound
    :param maximum: The upper bound (included)
    :param exclusive_minimum: Whether ``minimum`` itself is excluded
    """
    accepted = "a number" + _range(minimum, maximum, ">" if exclusive_minimum else ">=")
    return _accepting(accepted, lambda value: _within(_finite(value), minimum, maximum, exclusive_minimum), float)


def choice(*options: str) -> Validator:
    """
    One of the given strings.

    :param options: The accepted strings
    """
    accepted = "one of " + ", ".join(repr(option) for option in options)
    return _accepting(accepted, lambda value: isinstance(value, str) and value in options)


boolean = _accepting("true or false", lambda value: isinstance(value, bool))
string = _accepting("a non-empty string", lambda value: isinstance(value, str) and value != "")
scalar = _accepting("a number, string, boolean or null", lambda value: isinstance(value, (bool, int, float, str, type(None))))
#: A mapping with string keys (``{}`` for ``null``).
mapping = _accepting(
    "a mapping with string keys",
    lambda value: value is None or (isinstance(value, dict) and all(isinstance(name, str) for name in value)),
    lambda value: dict(value or {}),
)


def layer_sizes(max_width: int, max_weights: int) -> Validator:
    """
    Hidden layer sizes (``net_arch``): a list of integers from 1 to ``max_width``, or a mapping of such lists.

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
            problem = f"expected at most {max_weights} weights between hidden layers, got {weights} for {sizes}"
            raise HyperparamsError(source, key, problem)
        return sizes

    return check


def _text_or(text: Validator, other: Validator) -> Validator:
    """``text`` validates strings, ``other`` any other value."""
    return lambda value, source, key: (text if isinstance(value, str) else other)(value, source, key)


_LEARNING_RATE = "a number > 0 or 'lin_<number>' (linear decay to 0)"
#: A positive number, or ``lin_<number>`` (linear decay from that number to 0 over training).
learning_rate = _text_or(
    _accepting(_LEARNING_RATE, lambda value: _positive(value, "lin_")),
    _accepting(_LEARNING_RATE, lambda value: (_finite(value) or 0.0) > 0, float),
)
#: SAC's ``ent_coef``: a number >= 0, ``auto`` or ``auto_<initial value>``.
entropy_coefficient = _text_or(
    _accepting("a number >= 0, 'auto' or 'auto_<initial value>'", lambda value: value == "auto" or _positive(value, "auto_")),
    real(0.0),
)
#: SAC's ``target_entropy``: a number or ``auto``.
target_entropy = _text_or(_accepting("a number", lambda value: value == "auto"), real())
#: A mapping, or a string such as ``"dict(net_arch=[64, 64])"`` (parsed later, never executed).
mapping_or_expression = _text_or(lambda value, source, key: value, mapping)


def train_freq(value: Any, source: str, key: str) -> int | list[Any]:
    """An integer >= 1 (steps), or ``[n, "step"]`` / ``[n, "episode"]``."""
    if isinstance(value, (list, tuple)) and len(value) == 2 and value[1] in ("step", "episode"):
        return [integer(1)(value[0], source, key), value[1]]
    if isinstance(value, (list, tuple)) or (steps := _integral(value)) is None or steps < 1:
        raise _fail(value, source, key, 'an integer >= 1 or [n, "step" | "episode"]')
    return steps


def noise_std(value: Any, source: str, key: str) -> float | list[float]:
    """A number >= 0, or one number >= 0 per action dimension."""
    if isinstance(value, (list, tuple)) and value:
        return [real(0.0)(element, source, key) for element in value]
    return real(0.0)(value, source, key)


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


def normalize(value: Any, source: str, key: str) -> bool | dict[str, Any] | str:
    """``true``/``false``, a mapping of ``VecNormalize`` keywords, or such a mapping as a string."""
    if not isinstance(value, (bool, dict, str)):
        raise _fail(value, source, key, "true, false, or a mapping of VecNormalize keywords (norm_obs, norm_reward, ...)")
    return value if isinstance(value, bool) else mapping_or_expression(value, source, key)


def optional(validator: Validator) -> Validator:
    """
    ``null`` or a value accepted by ``validator``.

    :param validator: The validator of non-null values
    """
    return lambda value, source, key: None if value is None else validator(value, source, key)


def checked_by(check: Callable[[Any], None], canonical: Validator | None = None) -> Validator:
    """
    A value accepted by ``check``, the check of the class owning the option, so files accept exactly what it does.

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
