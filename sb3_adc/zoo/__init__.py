"""
``python -m sb3_adc.zoo train|enjoy ...``: the RL Zoo's command names on sb3-adc's engine (the Zoo's
``ExperimentManager`` subclassed, :class:`~sb3_adc.experiment.manager.RunManager`), and
:func:`register_algorithms`, which adds ADC and the paper's baselines to the Zoo's ``ALGOS`` table for your own
use of the Zoo's modules.
"""

from sb3_adc.extras import requires_extra
from sb3_adc.zoo.bridge import main


def register_algorithms() -> None:
    """Add ``adc``, ``vanilla_ac`` and ``ddpg`` (with a critic learning rate) to ``rl_zoo3.utils.ALGOS``."""
    with requires_extra("zoo", "sb3_adc.zoo.register_algorithms"):
        from sb3_adc.experiment.manager import register_algorithms as register

    register()


__all__ = ["main", "register_algorithms"]
