"""Pieces shared by the sub-commands of ``sb3-adc``."""

from __future__ import annotations

import argparse
import importlib
import random
import re
from collections.abc import Callable
from typing import Any

import torch as th

from sb3_adc.config import ALGORITHMS, parse_overrides
from sb3_adc.experiment.settings import check_device


class CommandError(Exception):
    """A problem with the command line that ends the command with a message (exit status 2)."""


def add_command(
    subparsers: argparse._SubParsersAction,
    name: str,
    help: str,
    description: str,
    handler: Callable[[argparse.Namespace], int],
) -> argparse.ArgumentParser:
    """
    Add a sub-command: its parser, whose ``--help`` prints ``description`` as written (examples and tables keep
    their lines), and the function that runs it.

    :param subparsers: The ``sb3-adc`` sub-parsers
    :param name: The sub-command's name
    :param help: Its line in ``sb3-adc --help``
    :param description: Its ``--help`` text
    :param handler: Runs it with the parsed command line and returns the exit status
    """
    parser = subparsers.add_parser(
        name, help=help, description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.set_defaults(handler=handler)
    return parser


def add_algo_argument(parser: argparse.ArgumentParser, required: bool = True) -> None:
    """
    ``--algo``, one of the registered algorithms.

    :param parser: The sub-command's parser
    :param required: Whether the option is required
    """
    parser.add_argument("--algo", required=required, choices=ALGORITHMS.names(), help="algorithm")


def add_runtime_arguments(parser: argparse.ArgumentParser) -> None:
    """
    ``--device``, ``--num-threads`` and ``--gym-packages``.

    :param parser: The sub-command's parser
    """
    parser.add_argument("--device", default="auto", help="PyTorch device: auto, cpu, cuda (default: auto)")
    parser.add_argument(
        "--num-threads",
        type=int,
        default=1,
        help="PyTorch CPU threads (default: 1, the fastest for small networks; -1: PyTorch's choice)",
    )
    parser.add_argument(
        "--gym-packages",
        nargs="+",
        default=[],
        metavar="MODULE",
        help="modules to import first, to register their Gymnasium environments",
    )


def apply_runtime_arguments(args: argparse.Namespace) -> None:
    """
    Check ``--device``, set the number of threads and import the ``--gym-packages``.

    :param args: The parsed command line
    :raises SettingsError: for a ``--device`` PyTorch does not know
    :raises CommandError: for a ``--gym-packages`` module that does not exist
    """
    check_device(args.device)
    if args.num_threads > 0:
        th.set_num_threads(args.num_threads)
    for module in args.gym_packages:
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as error:
            if error.name is None or not (module == error.name or module.startswith(error.name + ".")):
                raise  # a module the package itself imports (its extra's, reported as such)
            raise CommandError(
                f"--gym-packages: no module named {error.name!r}; give importable modules that register Gymnasium "
                "environments when imported (e.g. sb3_adc_envs)"
            ) from None


#: A number with an exponent as YAML 1.2 writes it, which PyYAML (YAML 1.1) reads as a string: ``1e300``, ``1e-3``
#: (without a dot) and ``2.5e3`` (without the exponent's sign). Other numbers YAML 1.1 reads as numbers already.
_YAML_12_EXPONENT = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)[eE][-+]?[0-9]+")


def _numbers_as_numbers(value: Any) -> Any:
    """``value`` with every string written as a number (``1e300``, ``1e-3``) read as a float, in nested lists and maps."""
    if isinstance(value, str) and _YAML_12_EXPONENT.fullmatch(value):
        return float(value)
    if isinstance(value, list):
        return [_numbers_as_numbers(element) for element in value]
    if isinstance(value, dict):
        return {key: _numbers_as_numbers(element) for key, element in value.items()}
    return value


def key_values(items: list[str] | None, option: str) -> dict[str, Any]:
    """
    ``key:value`` items of an option, each value read as YAML, numbers as numbers: ``speed:1e300`` and
    ``learning_rate:1e-3`` give floats (YAML 1.2's reading; PyYAML's YAML 1.1 gives strings without a dot).

    :param items: The items (``None``: none given)
    :param option: The option's name, for error messages
    """
    return {
        key: _numbers_as_numbers(value) for key, value in parse_overrides(items or [], source=f"command line {option}").items()
    }


#: Options of ``sb3-adc train`` that a run's and a study's settings take under the same names.
_SHARED_TRAIN_OPTIONS = ("conf_file", "n_timesteps", "log_folder", "eval_episodes", "final_eval_episodes", "device", "verbose")


def train_options(args: argparse.Namespace) -> dict[str, Any]:
    """
    The settings that a training run (:class:`~sb3_adc.experiment.settings.TrainSettings`) and a tuning study
    (:class:`~sb3_adc.experiment.tuning.TuneSettings`) take alike from the options of ``sb3-adc train``: the
    algorithm, environment, hyperparameter file and overrides, budget, environment keywords, log folder, evaluation
    episodes, device and verbosity.

    :param args: The parsed command line
    """
    return {
        "algo": args.algo,
        "env_id": args.env,
        "overrides": key_values(args.hyperparams, "-params"),
        "env_kwargs": key_values(args.env_kwargs, "--env-kwargs"),
        "eval_env_kwargs": key_values(args.eval_env_kwargs, "--eval-env-kwargs"),
        **{name: getattr(args, name) for name in _SHARED_TRAIN_OPTIONS},
    }


def resolve_seed(seed: int) -> int:
    """
    The seed to use: ``seed``, or a random one for a negative ``seed`` (as the RL Zoo).

    :param seed: The ``--seed`` value
    """
    return seed if seed >= 0 else random.SystemRandom().randrange(2**31 - 1)
