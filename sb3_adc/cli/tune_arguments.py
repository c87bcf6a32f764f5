"""``sb3-adc train -optimize``: the RL Zoo's tuning options, run by :func:`sb3_adc.experiment.tuning.tune`."""

from __future__ import annotations

import argparse
import os

from sb3_adc.cli.common import CommandError, train_options

TUNING_HELP = """\
tuning (-optimize): Optuna studies whose first trial is the shipped entry; a trial's value is its mean final
return (or success rate, --objective success) over --tuning-seeds. The study resumes when the command is run
again; the best entry is written to LOG_FOLDER/tuning/STUDY/best_hyperparams.yml (use it with -conf).
--eval-env-kwargs evaluates on other environment settings than training (a validation split); --search-space
FILE gives choices per hyperparameter (a YAML mapping such as "buffer_size: [50000, 200000]").
  sb3-adc train --algo adc --env sb3_adc/NoisyPendulum-v1 -optimize --n-trials 20 --n-jobs 2 --tuning-seeds 0 1
  sb3-adc train --algo td3 --env sb3_adc/LidarObstacleCourse-v1 -optimize --objective success \
      --eval-env-kwargs layout_seeds:[2000000,2000100] --search-space space.yml
"""


def add_tuning_arguments(parser: argparse.ArgumentParser) -> None:
    """
    The tuning options of ``sb3-adc train`` (the RL Zoo's names).

    :param parser: The ``train`` parser
    """
    from sb3_adc.experiment.tuning_settings import OBJECTIVE_NAMES, PRUNER_NAMES, SAMPLER_NAMES

    group = parser.add_argument_group("tuning (-optimize)")
    group.add_argument(
        "-optimize", "--optimize-hyperparameters", dest="optimize", action="store_true", help="tune hyperparameters"
    )
    group.add_argument(
        "--n-trials", type=int, default=10, help="finished trials of the study, shipped entry included (default: 10)"
    )
    group.add_argument("--n-jobs", type=int, default=1, help="worker processes, at most 2 per CPU (default: 1)")
    group.add_argument("--sampler", default="tpe", help=f"sampler: {', '.join(SAMPLER_NAMES)} (default: tpe)")
    group.add_argument("--pruner", default="median", help=f"pruner: {', '.join(PRUNER_NAMES)} (default: median)")
    group.add_argument(
        "--n-startup-trials", type=int, default=5, help="random trials before TPE and before pruning (default: 5)"
    )
    group.add_argument("--n-evaluations", type=int, default=5, help="evaluations per run reported to the pruner (default: 5)")
    group.add_argument(
        "--tuning-seeds",
        type=int,
        nargs="+",
        default=None,
        metavar="SEED",
        help="seeds of every trial (default: --seed, or 0)",
    )
    group.add_argument(
        "--storage",
        default=None,
        help="Optuna storage shared by workers and machines: a journal file (*.log) or a database URL, sqlite:///FILE, "
        "mysql://... or postgresql://... (default: LOG_FOLDER/tuning/STUDY/study.log)",
    )
    group.add_argument("--study-name", default=None, help="study name (default: ALGO-ENV)")
    group.add_argument("--sampler-seed", type=int, default=0, help="seed of the sampler (default: 0)")
    group.add_argument(
        "--objective",
        default="return",
        help=f"a trial's value: the evaluations' {' or '.join(OBJECTIVE_NAMES)} (success: share of episodes ending "
        "with info['is_success']; default: return)",
    )
    group.add_argument(
        "--search-space",
        default=None,
        metavar="FILE",
        help="YAML mapping of hyperparameters to lists of choices, drawn in every trial beside (or instead of) the "
        "algorithm's own space",
    )


def run_tuning(args: argparse.Namespace) -> int:
    """
    Run ``sb3-adc train -optimize``.

    :param args: The parsed command line
    :return: The exit status
    """
    from sb3_adc.config import check_env_id
    from sb3_adc.config.loader import read_yaml_file
    from sb3_adc.experiment.tuning import TuneSettings, tune

    if args.resume is not None:
        raise CommandError("-optimize and --resume do not combine: run the same -optimize command again to continue a study")
    if args.algo is None or args.env is None:
        raise CommandError("-optimize needs --algo and --env")
    check_env_id(args.env)
    seeds = args.tuning_seeds if args.tuning_seeds is not None else [max(args.seed, 0)]
    search_space = {}
    if args.search_space is not None:
        if not os.path.isfile(args.search_space):
            raise CommandError(f"--search-space: no file {args.search_space}")
        search_space = read_yaml_file(args.search_space)
    # The options named as TuneSettings' fields, beyond those it shares with a run's settings.
    same = "n_trials sampler pruner n_startup_trials n_evaluations n_jobs storage study_name sampler_seed objective"
    settings = TuneSettings(
        seeds=tuple(seeds),
        search_space=search_space,
        **train_options(args),
        **{name: getattr(args, name) for name in same.split()},
    )
    tune(settings)
    return 0
