"""
Bridge to the RL Zoo (extra ``zoo``): ``python -m sb3_adc.zoo train|enjoy ...`` runs ``rl_zoo3``'s own
``train``/``enjoy`` with ADC and the paper's baselines in its ``ALGOS`` table and sb3-adc's hyperparameter
files, read by :mod:`sb3_adc.config` (nothing from a configuration file is ``eval``'d or imported by name).
"""

from sb3_adc.zoo.bridge import ZOO_ALGORITHMS, main, register_algorithms, run_enjoy, run_train

__all__ = ["ZOO_ALGORITHMS", "main", "register_algorithms", "run_enjoy", "run_train"]
