"""``python -m sb3_adc.zoo {train,enjoy}``: the RL Zoo's command names on sb3-adc's engine."""

from __future__ import annotations

import sys
from collections.abc import Sequence

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
