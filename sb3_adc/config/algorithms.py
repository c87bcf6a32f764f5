"""The algorithms the tooling trains, by the name used for ``--algo`` and for the hyperparameter file."""

from __future__ import annotations

from stable_baselines3.common.base_class import BaseAlgorithm

from sb3_adc.config.allowlists import AllowList
from sb3_adc.config.errors import HyperparamsError

#: ``--algo`` name -> algorithm class (``ddpg``, ``td3``: SB3's with an optional averaged actor; ``tqc``, ``crossq``:
#: sb3-contrib's). Add your own with ``ALGORITHMS.add("name", AlgorithmClass)`` and a ``name.yml`` file.
ALGORITHMS = AllowList(
    "algorithm",
    {
        "adc": "sb3_adc.adc:ADC",
        "ddpg": "sb3_adc.baselines:SplitRateDDPG",
        "td3": "sb3_adc.baselines:AveragedActorTD3",
        "sac": "stable_baselines3:SAC",
        "tqc": "sb3_contrib:TQC",
        "crossq": "sb3_contrib:CrossQ",
        "dqn": "stable_baselines3:DQN",
        "vanilla_ac": "sb3_adc.baselines:VanillaActorCritic",
    },
)


def get_algorithm(name: str, source: str = "command line", key: str = "--algo") -> type[BaseAlgorithm]:
    """
    The algorithm class of an ``--algo`` name.

    :param name: The name (``adc``, ``ddpg``, ``td3``, ``sac``, ... or one added to :data:`ALGORITHMS`)
    :param source: Where the name was read, for the error message
    :param key: The option or key that gave the name, for the error message
    :raises HyperparamsError: for an unknown name (the message lists the accepted ones)
    """
    algorithm = ALGORITHMS.resolve(name, source, key)
    if not (isinstance(algorithm, type) and issubclass(algorithm, BaseAlgorithm)):
        raise HyperparamsError(source, key, f"{name!r} is registered as {algorithm!r}, not an SB3 algorithm class")
    return algorithm
