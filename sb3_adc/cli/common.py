"""Pieces shared by the sub-commands of ``sb3-adc``."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import re
from collections.abc import Iterator
from typing import Any

import torch as th

from sb3_adc.common.safe_load import UnsafeModelFileError
from sb3_adc.config import parse_expression, parse_overrides
from sb3_adc.config.allowlists import AllowList
from sb3_adc.experiment.settings import check_device


class CommandError(Exception):
    """A problem with the command line that ends the command with a message (exit status 2)."""


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


def check_positive(value: int, option: str) -> None:
    """
    Check that an option is at least 1.

    :param value: Its value
    :param option: The option's name
    :raises CommandError: when ``value`` is below 1
    """
    if value < 1:
        raise CommandError(f"{option} must be >= 1, got {value}")


@contextlib.contextmanager
def refusing_unsafe_files() -> Iterator[None]:
    """Turn a safe load's refusal of a model file or run-folder pickle into a command error (exit status 2)."""
    try:
        yield
    except UnsafeModelFileError as error:
        raise CommandError(f"{error} (with --trust-model-file the file is unpickled: do so only if you trust it)") from error


#: A number with an exponent as YAML 1.2 writes it, which PyYAML (YAML 1.1) reads as a string: ``1e300``, ``1e-3``
#: (without a dot) and ``2.5e3`` (without the exponent's sign).
_YAML_12_EXPONENT = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)[eE][-+]?[0-9]+")


def _numbers_as_numbers(value: Any) -> Any:
    """``value`` with every string written as a number read as a float, in nested lists and maps."""
    if isinstance(value, str) and _YAML_12_EXPONENT.fullmatch(value):
        return float(value)
    if isinstance(value, list):
        return [_numbers_as_numbers(element) for element in value]
    if isinstance(value, dict):
        return {key: _numbers_as_numbers(element) for key, element in value.items()}
    return value


#: Names an environment's keyword arguments may use: none (literals and ``dict(...)`` only).
_NO_NAMES = AllowList("name", {})


def key_values(items: list[str] | None, option: str, dict_calls: bool = False) -> dict[str, Any]:
    """
    ``key:value`` items of an option, each value read as YAML, numbers as numbers (YAML 1.2's reading:
    ``learning_rate:1e-3`` gives a float).

    :param items: The items (``None``: none given)
    :param option: The option's name, for error messages
    :param dict_calls: Also read a value written ``dict(key=value, ...)`` as the RL Zoo's ``--env-kwargs`` does
        (with :func:`~sb3_adc.config.parse_expression`, literals only): ``config:"dict(lanes_count=4)"``. Off for
        ``-params``, whose expression-valued keys the hyperparameter loader reads itself.
    """
    source = f"command line {option}"
    values = _numbers_as_numbers(parse_overrides(items or [], source=source))
    if dict_calls:
        for key, value in values.items():
            if isinstance(value, str) and value.lstrip().startswith("dict("):
                values[key] = parse_expression(value, source, key, names=_NO_NAMES)
    return values


def train_options(args: argparse.Namespace) -> dict[str, Any]:
    """
    The settings that a training run (:class:`~sb3_adc.experiment.settings.TrainSettings`) and a tuning study
    (:class:`~sb3_adc.experiment.tuning.TuneSettings`) take alike from the options of ``sb3-adc train``.

    :param args: The parsed command line
    """
    same = ("conf_file", "n_timesteps", "log_folder", "eval_episodes", "final_eval_episodes", "device", "verbose")
    return {
        "algo": args.algo,
        "env_id": args.env,
        "overrides": key_values(args.hyperparams, "-params"),
        "env_kwargs": key_values(args.env_kwargs, "--env-kwargs", dict_calls=True),
        "eval_env_kwargs": key_values(args.eval_env_kwargs, "--eval-env-kwargs", dict_calls=True),
        **{name: getattr(args, name) for name in same},
    }
