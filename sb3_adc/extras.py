"""
Optional dependencies: which extra of ``sb3-adc`` brings which package, and a clear message when one is missing.

The core install (``pip install sb3-adc``) is what ``ADC("MlpPolicy", env)`` needs: Stable-Baselines3, PyTorch,
Gymnasium, NumPy and PyYAML. The robot environments, the ``sb3-adc`` command, its statistics and figures, Ray,
video, tracking and Gymnasium's MuJoCo tasks come with extras (``pip install "sb3-adc[envs,experiment]"``). Where
such a package is imported, :func:`import_optional` (or :func:`requires_extra` around a block of imports) turns the
``ModuleNotFoundError`` into a :class:`MissingExtraError` whose message names the extra to install.

This module imports only the standard library, so that it can guard imports anywhere.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

#: The name of the distribution, as in ``pip install "sb3-adc[EXTRA]"``.
DISTRIBUTION = "sb3-adc"

#: Extra -> the top-level modules it brings that the core install lacks (``setup.cfg`` declares the
#: distributions; tests/test_extras.py checks that the two agree).
EXTRA_MODULES: dict[str, tuple[str, ...]] = {
    "envs": ("pybullet", "highway_env", "PIL", "scipy"),
    "experiment": ("rl_zoo3", "sb3_contrib", "optuna", "tqdm", "rich", "rliable", "scipy", "imageio", "matplotlib", "pandas"),
    "zoo": ("rl_zoo3", "sb3_contrib"),
    "ray": ("ray",),
    "video": ("imageio", "imageio_ffmpeg"),
    "track": ("wandb",),
    "mujoco": ("mujoco",),
}


class MissingExtraError(ModuleNotFoundError):
    """
    An optional package is not installed; the message names the extra of ``sb3-adc`` that brings it.

    Subclasses ``ModuleNotFoundError`` (with the same ``name``), so that code catching that keeps working.

    :param module: The top-level module that could not be imported
    :param extra: The extra that brings it
    :param purpose: What needs it (e.g. ``"the lidar course"``), for the message
    """

    def __init__(self, module: str, extra: str, purpose: str = "") -> None:
        self.module = module
        self.extra = extra
        needed_by = f" (needed by {purpose})" if purpose else ""
        super().__init__(
            f"the package {module!r}{needed_by} is not installed: it comes with the {extra!r} extra of {DISTRIBUTION}; "
            f'install it with: pip install "{DISTRIBUTION}[{extra}]"',
            name=module,
        )


def extras_providing(module: str) -> tuple[str, ...]:
    """
    The extras that bring a module, in the order of :data:`EXTRA_MODULES`.

    :param module: A module name (a sub-module such as ``"scipy.stats"`` counts as its top-level package)
    :return: The extras; empty for a module that no extra brings
    """
    top_level = module.split(".", 1)[0]
    return tuple(extra for extra, modules in EXTRA_MODULES.items() if top_level in modules)


def _check_extra(extra: str) -> None:
    if extra not in EXTRA_MODULES:
        raise ValueError(f"extra must be one of {', '.join(EXTRA_MODULES)}, got {extra!r}")


def missing_extra(error: ModuleNotFoundError, extra: str | None = None) -> MissingExtraError | None:
    """
    The :class:`MissingExtraError` that explains ``error``, or ``None`` when no extra brings the missing module
    (a missing module of the code itself, which must stay a plain error).

    :param error: The error raised by an import
    :param extra: The extra expected to bring the module; ``None``: the first extra of :data:`EXTRA_MODULES`
        that brings it
    """
    if isinstance(error, MissingExtraError):
        return error
    if extra is not None:
        _check_extra(extra)
    top_level = (error.name or "").split(".", 1)[0]
    candidates = extras_providing(top_level)
    if not candidates:
        return None
    return MissingExtraError(top_level, extra if extra in candidates else candidates[0])


def import_optional(module: str, extra: str, purpose: str = "") -> ModuleType:
    """
    Import a module of an optional package, or raise a :class:`MissingExtraError` naming ``extra``.

    :param module: The module to import (e.g. ``"pybullet"`` or ``"rliable.library"``)
    :param extra: The extra that brings it: one of :data:`EXTRA_MODULES`
    :param purpose: What needs it, for the message
    :return: The module
    """
    _check_extra(extra)
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as error:
        missing = missing_extra(error, extra)
        if missing is None:
            raise
        raise MissingExtraError(missing.module, missing.extra, purpose) from error


@contextmanager
def requires_extra(extra: str, purpose: str = "") -> Iterator[None]:
    """
    A block of imports that need an extra: a missing optional package raises a :class:`MissingExtraError`.

    ::

        with requires_extra("experiment", "sb3-adc plot"):
            from rliable import library as rly

    :param extra: The extra the block needs: one of :data:`EXTRA_MODULES`
    :param purpose: What needs it, for the message
    """
    _check_extra(extra)
    try:
        yield
    except ModuleNotFoundError as error:
        missing = missing_extra(error, extra)
        if missing is None:
            raise
        if isinstance(error, MissingExtraError):
            raise
        raise MissingExtraError(missing.module, missing.extra, purpose) from error


__all__ = ["EXTRA_MODULES", "MissingExtraError", "extras_providing", "import_optional", "missing_extra", "requires_extra"]
