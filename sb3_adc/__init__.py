"""sb3-adc: the Actor-Dueling-Critic method for Stable-Baselines3.

Importing the package registers every environment of :mod:`sb3_adc_envs` under the Gymnasium namespace
``sb3_adc/`` (without importing pybullet or highway-env until one of those environments is made).
"""

import os

from sb3_adc.adc import ADC, ADCPolicy, DuelingIntervalCritic
from sb3_adc.common.noise import EpsilonGaussianNoise
from sb3_adc_envs.registration import register_envs

register_envs()

with open(os.path.join(os.path.dirname(__file__), "version.txt")) as version_file:
    __version__ = version_file.read().strip()

__all__ = ["ADC", "ADCPolicy", "DuelingIntervalCritic", "EpsilonGaussianNoise", "__version__"]
