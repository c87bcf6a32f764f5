"""Environments of sb3-adc, installed under the import name ``sb3_adc_envs``.

Importing this package (or ``sb3_adc``) registers every environment id below the Gymnasium namespace
``sb3_adc/`` (see :mod:`sb3_adc_envs.registration`), so ``gym.make("sb3_adc_envs:sb3_adc/LidarObstacleCourse-v1")``
works in a fresh process. Importing it never imports torch, Stable-Baselines3, pybullet or highway-env: the
simulators are imported when an environment that needs them is made.
"""

from sb3_adc_envs.registration import register_envs
from sb3_adc_envs.wrappers import ClearanceShaping, DiscretizedActions, UniformObservationNoise

__all__ = ["ClearanceShaping", "DiscretizedActions", "UniformObservationNoise", "register_envs"]

register_envs()
