"""sb3-adc: the Actor-Dueling-Critic method for Stable-Baselines3.

Importing the package registers every environment of :mod:`sb3_adc_envs` under the Gymnasium namespace
``sb3_adc/`` (without importing pybullet or highway-env until one of those environments is made). The
algorithm's names (``ADC``, ...) load PyTorch and Stable-Baselines3 on first use, so that the light modules
(:mod:`sb3_adc.extras`, the environments) can be imported without them.
"""

from __future__ import annotations

import importlib
import os
from typing import TYPE_CHECKING, Any

from sb3_adc_envs.registration import register_envs

if TYPE_CHECKING:
    from sb3_adc.adc import ADC, ADCPolicy, DuelingIntervalCritic
    from sb3_adc.common.noise import EpsilonGaussianNoise
    from sb3_adc.diagnostics import CriticDiagnosticsCallback

register_envs()

with open(os.path.join(os.path.dirname(__file__), "version.txt")) as version_file:
    __version__ = version_file.read().strip()

#: Public name -> the module that defines it, imported on first access (PEP 562).
_LAZY_NAMES = {
    "ADC": "sb3_adc.adc",
    "ADCPolicy": "sb3_adc.adc",
    "DuelingIntervalCritic": "sb3_adc.adc",
    "EpsilonGaussianNoise": "sb3_adc.common.noise",
    "CriticDiagnosticsCallback": "sb3_adc.diagnostics",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY_NAMES:
        value = getattr(importlib.import_module(_LAZY_NAMES[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY_NAMES])


__all__ = ["ADC", "ADCPolicy", "CriticDiagnosticsCallback", "DuelingIntervalCritic", "EpsilonGaussianNoise", "__version__"]
