"""Environments of sb3-adc, installed under the import name ``sb3_adc_envs``.

``import sb3_adc`` registers every environment id below the Gymnasium namespace ``sb3_adc/``
(see :mod:`sb3_adc_envs.registration`). Importing this package never imports pybullet or
highway-env: the simulators are imported when an environment that needs them is made.
"""

from sb3_adc_envs.registration import register_envs
from sb3_adc_envs.wrappers import DiscretizedActions, UniformObservationNoise

__all__ = ["DiscretizedActions", "UniformObservationNoise", "register_envs"]
