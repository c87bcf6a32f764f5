"""Running the RL Zoo's own ``train`` and ``enjoy`` with sb3-adc's algorithms and safe hyperparameter reading."""

from __future__ import annotations

import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

#: Algorithms added to the Zoo's ``ALGOS`` table. ``ddpg`` replaces SB3's DDPG by
#: :class:`~sb3_adc.baselines.SplitRateDDPG` (identical without ``critic_learning_rate``), which sb3-adc's
#: ``ddpg.yml`` uses.
ZOO_ALGORITHMS = {
    "adc": "sb3_adc.adc:ADC",
    "vanilla_ac": "sb3_adc.baselines:VanillaActorCritic",
    "ddpg": "sb3_adc.baselines:SplitRateDDPG",
}

USAGE = """\
usage: python -m sb3_adc.zoo {train,enjoy} [RL Zoo options]

Run the RL Zoo's own train or enjoy with ADC and the paper's baselines registered (adc, vanilla_ac, and
ddpg with a critic learning rate) and sb3-adc's hyperparameter files read safely: -conf defaults to
sb3-adc's {algo}.yml, policy_kwargs strings and -params values are parsed, never eval'd.

examples:
  python -m sb3_adc.zoo train --algo adc --env Pendulum-v1 -f logs
  python -m sb3_adc.zoo enjoy --algo adc --env Pendulum-v1 -f logs --no-render -n 1000
Options: python -m sb3_adc.zoo train --help (the RL Zoo's).
"""


def register_algorithms() -> None:
    """Add sb3-adc's algorithms to the Zoo's ``ALGOS`` table (the only way the Zoo takes new algorithms)."""
    from rl_zoo3.utils import ALGOS

    from sb3_adc.config import ALGORITHMS

    for name in ZOO_ALGORITHMS:
        ALGOS[name] = ALGORITHMS.resolve(name, "sb3_adc.zoo", "algo")  # type: ignore[assignment]


@contextmanager
def _patched(module: Any, **attributes: Any) -> Iterator[None]:
    """Replace module attributes for the duration of the block."""
    saved = {name: getattr(module, name) for name in attributes}
    for name, value in attributes.items():
        setattr(module, name, value)
    try:
        yield
    finally:
        for name, value in saved.items():
            setattr(module, name, value)


@contextmanager
def _argv(argv: list[str]) -> Iterator[None]:
    saved = sys.argv
    sys.argv = argv
    try:
        yield
    finally:
        sys.argv = saved


def run_train(argv: Sequence[str]) -> None:
    """
    ``rl_zoo3.train.train()`` with :class:`~sb3_adc.zoo.experiment_manager.SafeExperimentManager` and
    :class:`~sb3_adc.zoo.safe_io.SafeStoreDict`.

    :param argv: The Zoo's ``train`` options
    """
    import rl_zoo3.train as zoo_train

    from sb3_adc.zoo.experiment_manager import SafeExperimentManager
    from sb3_adc.zoo.safe_io import SafeStoreDict

    register_algorithms()
    with _patched(zoo_train, ExperimentManager=SafeExperimentManager, StoreDict=SafeStoreDict), _argv(
        ["python -m sb3_adc.zoo train", *argv]
    ):
        zoo_train.train()


def run_enjoy(argv: Sequence[str]) -> None:
    """
    ``rl_zoo3.enjoy.enjoy()`` reading the run's ``config.yml``/``args.yml`` safely.

    :param argv: The Zoo's ``enjoy`` options
    """
    import rl_zoo3.enjoy as zoo_enjoy

    from sb3_adc.zoo.safe_io import SAFE_YAML, SafeStoreDict, safe_get_saved_hyperparams

    register_algorithms()
    with _patched(zoo_enjoy, StoreDict=SafeStoreDict, get_saved_hyperparams=safe_get_saved_hyperparams, yaml=SAFE_YAML), _argv(
        ["python -m sb3_adc.zoo enjoy", *argv]
    ):
        zoo_enjoy.enjoy()


def main(argv: Sequence[str] | None = None) -> int:
    """
    ``python -m sb3_adc.zoo {train,enjoy} ...``.

    :param argv: The arguments (default: ``sys.argv[1:]``)
    :return: The exit status
    """
    arguments = list(sys.argv[1:] if argv is None else argv)
    if arguments[:1] in (["-h"], ["--help"]):
        print(USAGE)
        return 0
    if arguments[:1] not in (["train"], ["enjoy"]):
        print(USAGE, file=sys.stderr)
        return 2
    try:
        import rl_zoo3  # noqa: F401
    except ImportError:
        print("python -m sb3_adc.zoo needs the RL Zoo: pip install 'sb3-adc[zoo]'", file=sys.stderr)
        return 2
    if arguments[0] == "train":
        run_train(arguments[1:])
    else:
        run_enjoy(arguments[1:])
    return 0
