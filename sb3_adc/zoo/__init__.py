"""
``python -m sb3_adc.zoo train|enjoy ...``: the RL Zoo's command names on sb3-adc's engine (the Zoo's
``ExperimentManager`` subclassed, :class:`~sb3_adc.experiment.manager.RunManager`), and
:func:`register_algorithms`, which adds ADC and the paper's baselines to the Zoo's ``ALGOS`` table for your own
use of the Zoo's modules.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from sb3_adc.extras import requires_extra

USAGE = """\
usage: python -m sb3_adc.zoo {train,enjoy} [options]

The RL Zoo's commands with ADC and the paper's baselines: `python -m sb3_adc.zoo train` is `sb3-adc train`
and `python -m sb3_adc.zoo enjoy` is `sb3-adc enjoy`. Both run on sb3-adc's engine, the RL Zoo's
ExperimentManager subclassed (sb3_adc.experiment.manager.RunManager): the Zoo's options (-f, -conf,
-params, -n, -tb, -i, -optimize, --eval-freq, --save-freq, --track, ...), sb3-adc's hyperparameter files
read safely (nothing eval'd), and resume (--resume). In enjoy, -n counts episodes.

examples:
  python -m sb3_adc.zoo train --algo adc --env Pendulum-v1 -f logs
  python -m sb3_adc.zoo enjoy --algo adc --env Pendulum-v1 -f logs --no-render -n 5
Options: python -m sb3_adc.zoo train --help.
"""


def main(argv: Sequence[str] | None = None) -> int:
    """
    ``python -m sb3_adc.zoo {train,enjoy} ...``.

    :param argv: The arguments (default: ``sys.argv[1:]``)
    :return: The exit status (that of ``sb3-adc``)
    """
    arguments = list(sys.argv[1:] if argv is None else argv)
    if arguments[:1] in (["-h"], ["--help"]):
        print(USAGE)
        return 0
    if arguments[:1] not in (["train"], ["enjoy"]):
        print(USAGE, file=sys.stderr)
        return 2
    from sb3_adc.cli import main as sb3_adc_main

    return sb3_adc_main(arguments)


def register_algorithms() -> None:
    """
    Add sb3-adc's algorithms (``adc``, ``vanilla_ac``, ``ddpg`` with a critic learning rate, ``td3`` with an
    averaged actor, and every name added to ``sb3_adc.config.algorithms.ALGORITHMS``) to ``rl_zoo3.utils.ALGOS``,
    and the search spaces of ``adc`` and ``vanilla_ac`` to ``rl_zoo3.hyperparams_opt.HYPERPARAMS_SAMPLER``
    (:func:`~sb3_adc.experiment.samplers.register_zoo_samplers`)."""
    with requires_extra("zoo", "sb3_adc.zoo.register_algorithms"):
        from sb3_adc.experiment.manager import register_algorithms as register
        from sb3_adc.experiment.samplers import register_zoo_samplers

    register()
    register_zoo_samplers()


__all__ = ["main", "register_algorithms"]
