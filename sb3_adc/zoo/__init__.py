"""
``python -m sb3_adc.zoo train|enjoy ...``: the RL Zoo's command names on sb3-adc's engine (the Zoo's
``ExperimentManager`` subclassed, :class:`~sb3_adc.experiment.manager.RunManager`), and
:func:`register_algorithms`, which adds ADC and the paper's baselines to the Zoo's ``ALGOS`` table for your own
use of the Zoo's modules.
"""

from sb3_adc.extras import requires_extra
from sb3_adc.zoo.bridge import main


def register_algorithms() -> None:
    """Add sb3-adc's algorithms (``adc``, ``vanilla_ac``, ``ddpg`` with a critic learning rate, ``td3`` with an
    averaged actor, and every name added to ``sb3_adc.config.algorithms.ALGORITHMS``) to ``rl_zoo3.utils.ALGOS``,
    and the search spaces of ``adc`` and ``vanilla_ac`` to ``rl_zoo3.hyperparams_opt.HYPERPARAMS_SAMPLER``
    (:func:`~sb3_adc.experiment.samplers.register_zoo_samplers`)."""
    with requires_extra("zoo", "sb3_adc.zoo.register_algorithms"):
        from sb3_adc.experiment.manager import register_algorithms as register
        from sb3_adc.experiment.samplers import register_zoo_samplers

    register()
    register_zoo_samplers()


__all__ = ["main", "register_algorithms"]
