"""
The ``sb3-adc`` command (also ``python -m sb3_adc``): ``train``, ``enjoy``, ``benchmark``, ``experiment`` and
``plot``.

Run ``sb3-adc SUB-COMMAND --help`` for the options of each. The command needs the ``experiment`` extra
(``pip install "sb3-adc[experiment]"``); without it, or without an extra a run needs (``envs`` for the robot
environments, ``ray``, ``video``, ``track``), it prints which extra to install and exits with status 2.
"""

from __future__ import annotations

import argparse
import errno
import sys
from collections.abc import Sequence

import sb3_adc
from sb3_adc.config import HyperparamsError
from sb3_adc.extras import MissingExtraError, missing_extra, requires_extra

#: Errors of the machine's files that the user can act on (a full disk, a quota, no permission, a read-only file
#: system, too many open files): exit status 2 with the file's name, not a traceback.
FILE_SYSTEM_ERRNOS = frozenset(
    getattr(errno, name)
    for name in ("ENOSPC", "EDQUOT", "EFBIG", "EACCES", "EPERM", "EROFS", "EMFILE", "ENFILE", "ENAMETOOLONG", "EISDIR")
    if hasattr(errno, name)
)


def build_parser() -> argparse.ArgumentParser:
    """
    The parser of ``sb3-adc`` and its sub-commands.

    :raises MissingExtraError: When the ``experiment`` extra is not installed
    """
    with requires_extra("experiment", "the sb3-adc command"):
        from sb3_adc.cli import benchmark_command, enjoy_command, experiment_command, plot_command, train_command

    parser = argparse.ArgumentParser(
        prog="sb3-adc",
        description="Train, evaluate, benchmark and plot Actor-Dueling-Critic (ADC) and its baselines, RL-Zoo style.",
    )
    parser.add_argument("--version", action="version", version=f"sb3-adc {sb3_adc.__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="{train,enjoy,benchmark,experiment,plot}", required=True)
    for command in (train_command, enjoy_command, benchmark_command, experiment_command, plot_command):
        # Each module holds its options in PARSER (a parent), its --help texts and the function that runs it.
        subparsers.add_parser(
            command.__name__.rsplit(".", 1)[1].removesuffix("_command"),
            parents=[command.PARSER],
            help=command.HELP,
            description=command.DESCRIPTION,
            formatter_class=argparse.RawDescriptionHelpFormatter,  # examples and tables keep their lines
        ).set_defaults(handler=command.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run ``sb3-adc`` with the given arguments (default: ``sys.argv[1:]``).

    :param argv: The command-line arguments
    :return: The exit status: 0 on success, 1 if benchmark runs failed or training diverged (NaN or inf), 2 for
        invalid input, a missing extra, a full disk or another file-system error of :data:`FILE_SYSTEM_ERRNOS`
        (named with its file), or memory exhausted; 130 when interrupted (Ctrl-C, or SIGTERM, handled the same way)
    """
    try:
        parser = build_parser()
    except MissingExtraError as error:
        print(f"sb3-adc: error: {error}", file=sys.stderr)
        return 2
    # Imported once the parser exists: the experiment extra is there.
    from sb3_adc.cli.common import CommandError
    from sb3_adc.common.model_files import ModelFileError
    from sb3_adc.common.spaces import ActionSpaceError
    from sb3_adc.experiment import RunInterrupted, RunLocked
    from sb3_adc.experiment.benchmark import RunSettingsMismatch
    from sb3_adc.experiment.divergence import NonFiniteValue, TrainingDiverged
    from sb3_adc.experiment.settings import SettingsError
    from sb3_adc.experiment.training import sigterm_as_sigint

    try:  # a course file over a bound or malformed (the robot environments, when their extra is installed)
        from sb3_adc_envs.lidar_course.course import CourseError
    except ImportError:  # pragma: no cover - the envs extra is missing: no course can be read either
        CourseError = HyperparamsError  # type: ignore[misc,assignment]

    user_errors = (
        HyperparamsError,  # a hyperparameter file, -params or a run's config.yml / args.yml
        SettingsError,  # an option of the run (--n-eval-envs 0, --device foo, --env-kwargs foo:1, ...)
        CommandError,
        ModelFileError,  # a damaged model file, or one of another algorithm (sb3-adc enjoy, -i)
        ActionSpaceError,  # an environment whose action space the algorithm cannot act in
        FileNotFoundError,
        FileExistsError,
        RunSettingsMismatch,
        RunLocked,  # another process is training the run, or running a benchmark in the folder
        CourseError,  # a course file the lidar course refuses (names the file, field and limit)
    )
    args = parser.parse_args(argv)
    status = 2
    try:
        # A scheduler's SIGTERM (Slurm, Kubernetes) stops a run as Ctrl-C does: with a checkpoint, status 130.
        with sigterm_as_sigint():
            return int(args.handler(args))
    except user_errors as error:
        message: object = error
    except ModuleNotFoundError as error:
        # A package of an extra the run needs (pybullet when making the lidar course, ray for --backend ray, ...).
        message = missing_extra(error)
        if message is None:
            raise
    except RunInterrupted:
        return 130
    except MemoryError as error:  # after the bounds of the options that size memory: a machine too small for the run
        message = (
            f"out of memory ({error or 'MemoryError'}); the run needs more memory than is free: lower buffer_size, "
            "batch_size, n_envs or the networks' sizes (policy_kwargs), or free memory"
        )
    except OSError as error:
        if error.errno not in FILE_SYSTEM_ERRNOS:
            raise
        message = f"{'' if error.filename is None else f'{error.filename}: '}{error.strerror or error}"
    except (TrainingDiverged, NonFiniteValue) as error:  # NonFiniteValue: outside training (enjoy)
        message, status = error, 1
    print(f"sb3-adc {args.command}: error: {message}", file=sys.stderr)
    return status


__all__ = ["build_parser", "main"]
