"""``sb3-adc train``: train an algorithm on an environment, in the RL-Zoo log layout, or tune it (``-optimize``)."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import random
import time
from collections.abc import Iterator

import stable_baselines3 as sb3

import sb3_adc
from sb3_adc.cli.common import (
    CommandError,
    add_runtime_arguments,
    apply_runtime_arguments,
    refusing_unsafe_files,
    train_options,
)
from sb3_adc.config import ALGORITHMS, check_env_id
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.experiment import TrainSettings, find_run, resume, train
from sb3_adc.experiment.settings import BEST_MODEL_METRICS
from sb3_adc.experiment.tuning_settings import OBJECTIVE_NAMES, PRUNER_NAMES, SAMPLER_NAMES
from sb3_adc.extras import requires_extra

HELP = "train an algorithm on an environment (RL-Zoo log layout, checkpoints, resume)"
DESCRIPTION = """\
Train an algorithm on an environment with the hyperparameters of its YAML file (the shipped
{algo}.yml, or -conf FILE), evaluating it periodically and checkpointing it, then print the final
evaluation: mean +/- std return over deterministic episodes.

The run is written to LOG_FOLDER/ALGO/ENV_N/ (the RL-Zoo layout): evaluations.npz, monitor CSVs,
the final model ENV.zip, best_model.zip, checkpoints, and ENV/config.yml (the resolved
hyperparameters). Ctrl-C saves a checkpoint; --resume continues from the last one.

examples:
  sb3-adc train --algo adc --env sb3_adc/NoisyPendulum-v1
  sb3-adc train --algo ddpg --env Pendulum-v1 --seed 3 -n 5000 -params learning_rate:0.0005
  sb3-adc train --algo adc --env Pendulum-v1 --resume            # the latest run of adc on Pendulum-v1
  sb3-adc train --resume logs/adc/Pendulum-v1_2 -n 40000         # a given run, with a larger budget
  sb3-adc train --algo adc --env Pendulum-v1 -tb runs/           # TensorBoard logs in runs/Pendulum-v1/ADC_1
  sb3-adc train --algo adc --env Pendulum-v1 -n 20000 \
      -i logs/adc/Pendulum-v1_1/rl_model_20000_steps.zip         # 20000 more steps from a saved model
  sb3-adc train --algo adc --env Pendulum-v1 --track --wandb-project-name adc  # Weights & Biases (track extra)

tuning (-optimize): Optuna studies whose first trial is the shipped entry; a trial's value is its mean final
return (or success rate, --objective success) over --tuning-seeds. The study resumes when the command is run
again; the best entry is written to LOG_FOLDER/tuning/STUDY/best_hyperparams.yml (use it with -conf).
--eval-env-kwargs evaluates on other environment settings than training (a validation split); --search-space
FILE gives choices per hyperparameter (a YAML mapping such as "buffer_size: [50000, 200000]").
  sb3-adc train --algo adc --env sb3_adc/NoisyPendulum-v1 -optimize --n-trials 20 --n-jobs 2 --tuning-seeds 0 1
  sb3-adc train --algo td3 --env sb3_adc/LidarObstacleCourse-v1 -optimize --objective success \
      --eval-env-kwargs layout_seeds:[2000000,2000100] --search-space space.yml
"""

PARSER = argparse.ArgumentParser(add_help=False)
PARSER.add_argument("--algo", choices=ALGORITHMS.names(), help="algorithm")
PARSER.add_argument("--env", help="environment id, e.g. Pendulum-v1 or sb3_adc/NoisyPendulum-v1")
PARSER.add_argument("--seed", type=int, default=-1, help="random seed (default: -1, a random seed)")
PARSER.add_argument("-n", "--n-timesteps", type=int, help="training budget, replacing n_timesteps")
PARSER.add_argument(
    "-conf",
    "--conf-file",
    help="hyperparameter file, or the name of a shipped one such as paper/adc, the paper's tables "
    "(default: the shipped {algo}.yml)",
)
PARSER.add_argument("-f", "--log-folder", default="logs", help="log folder (default: logs)")
PARSER.add_argument(
    "-params",
    "--hyperparams",
    nargs="+",
    metavar="KEY:VALUE",
    help="override hyperparameters, values read as YAML: learning_rate:0.001 train_freq:[1,episode]",
)
PARSER.add_argument("--env-kwargs", nargs="+", metavar="KEY:VALUE", help="keyword arguments of gym.make (YAML values)")
PARSER.add_argument(
    "--eval-env-kwargs",
    nargs="+",
    metavar="KEY:VALUE",
    help="keyword arguments of gym.make for the evaluation environments only, replacing those keys of the "
    "training environments' (YAML values)",
)
PARSER.add_argument(
    "-tb",
    "--tensorboard-log",
    metavar="DIR",
    help="TensorBoard log folder: the run logs to DIR/ENV/ALGORITHM_N (default: none; with --track, LOG_FOLDER/tensorboard)",
)
PARSER.add_argument(
    "-i",
    "--trained-agent",
    metavar="ZIP",
    help="continue training a saved model of --algo in a new run: its weights and the replay buffer saved with "
    "it (a checkpoint's, or replay_buffer.pkl beside it), n_timesteps more",
)
PARSER.add_argument("--eval-freq", type=int, help="evaluate every K timesteps (default: 20 evaluations per run; <= 0: never)")
PARSER.add_argument("--eval-episodes", type=int, default=5, help="episodes per periodic evaluation (default: 5)")
PARSER.add_argument(
    "--best-model-metric",
    choices=BEST_MODEL_METRICS,
    help="what picks best_model.zip among the periodic evaluations: return (default, SB3's) or success (the "
    "success rate, each evaluation on the same episodes)",
)
PARSER.add_argument("--n-eval-envs", type=int, default=1, help="environments of the periodic evaluations (default: 1)")
PARSER.add_argument("--save-freq", type=int, help="checkpoint every K timesteps (default: at every evaluation; <= 0: never)")
PARSER.add_argument("--keep-checkpoints", type=int, default=2, help="checkpoints kept (default: 2, the latest)")
PARSER.add_argument("--final-eval-episodes", type=int, default=10, help="episodes of the final evaluation (default: 10)")
PARSER.add_argument("--vec-env", choices=["dummy", "subproc"], default="dummy", help="vectorized env type (default: dummy)")
PARSER.add_argument("--verbose", type=int, default=0, help="SB3 verbosity: 0 quiet, 1 training logs (default: 0)")
PARSER.add_argument("--no-progress-bar", action="store_true", help="do not show the progress bar")
PARSER.add_argument(
    "--resume",
    nargs="?",
    const="latest",
    metavar="RUN_DIR",
    help="continue a run from its last checkpoint: RUN_DIR, or (without value) the latest run of --algo on --env",
)
PARSER.add_argument(
    "--trust-model-file",
    action="store_true",
    help="unpickle the model of -i (and the replay buffer saved with it) or, with --resume, the run's checkpoint "
    "as SB3 does, which runs any code they hold (default: a safe load that builds only known classes and refuses "
    "the rest)",
)
add_runtime_arguments(PARSER)
_tracking = PARSER.add_argument_group("tracking (--track, the track extra)")
_tracking.add_argument(
    "--track", action="store_true", help="track the run with Weights & Biases (uploads the TensorBoard logs)"
)
_tracking.add_argument("--wandb-project-name", default="sb3-adc", help="Weights & Biases project (default: sb3-adc)")
_tracking.add_argument("--wandb-entity", help="Weights & Biases entity (team) of the project (default: your own)")
_tuning = PARSER.add_argument_group("tuning (-optimize)")
_tuning.add_argument(
    "-optimize", "--optimize-hyperparameters", dest="optimize", action="store_true", help="tune hyperparameters"
)
_tuning.add_argument(
    "--n-trials", type=int, default=10, help="finished trials of the study, shipped entry included (default: 10)"
)
_tuning.add_argument("--n-jobs", type=int, default=1, help="worker processes, at most 2 per CPU (default: 1)")
_tuning.add_argument("--sampler", default="tpe", help=f"sampler: {', '.join(SAMPLER_NAMES)} (default: tpe)")
_tuning.add_argument("--pruner", default="median", help=f"pruner: {', '.join(PRUNER_NAMES)} (default: median)")
_tuning.add_argument(
    "--n-startup-trials", type=int, default=5, help="random trials before TPE and before pruning (default: 5)"
)
_tuning.add_argument("--n-evaluations", type=int, default=5, help="evaluations per run reported to the pruner (default: 5)")
_tuning.add_argument(
    "--tuning-seeds", type=int, nargs="+", metavar="SEED", help="seeds of every trial (default: --seed, or 0)"
)
_tuning.add_argument(
    "--storage",
    help="Optuna storage shared by workers and machines: a journal file (*.log) or a database URL, sqlite:///FILE, "
    "mysql://... or postgresql://... (default: LOG_FOLDER/tuning/STUDY/study.log)",
)
_tuning.add_argument("--study-name", help="study name (default: ALGO-ENV)")
_tuning.add_argument("--sampler-seed", type=int, default=0, help="seed of the sampler (default: 0)")
_tuning.add_argument(
    "--objective",
    default="return",
    help=f"a trial's value: the evaluations' {' or '.join(OBJECTIVE_NAMES)} (success: share of episodes ending "
    "with info['is_success']; default: return)",
)
_tuning.add_argument(
    "--search-space",
    metavar="FILE",
    help="YAML mapping of hyperparameters to lists of choices, drawn in every trial beside (or instead of) the "
    "algorithm's own space",
)

#: Options of a new run (their settings are saved with it): --resume uses the saved ones.
_NEW_RUN_OPTIONS = {
    "trained_agent": "-i/--trained-agent",
    "tensorboard_log": "-tb/--tensorboard-log",
    "eval_env_kwargs": "--eval-env-kwargs",
    "track": "--track",
    "best_model_metric": "--best-model-metric",
}


@contextlib.contextmanager
def tracking(settings: TrainSettings) -> Iterator[None]:
    """
    Track the run with Weights & Biases when ``settings.track``, as the RL Zoo's ``train.py`` does (``wandb.init``
    with ``sync_tensorboard``, which uploads what the model logs to TensorBoard).

    :param settings: The run's settings
    :raises MissingExtraError: when wandb is not installed (the ``track`` extra)
    """
    if not settings.track:
        yield
        return
    with requires_extra("track", "--track"):
        import wandb

    run = wandb.init(
        name=f"{settings.env_id}__{settings.algo}__{settings.seed}__{int(time.time())}",
        project=settings.wandb_project_name,
        entity=settings.wandb_entity,
        tags=[f"sb3-adc v{sb3_adc.__version__}", f"v{sb3.__version__}"],
        config=dataclasses.asdict(settings),
        sync_tensorboard=True,
        save_code=True,
    )
    try:
        yield
    finally:
        run.finish()


def run(args: argparse.Namespace) -> int:
    """
    Run the sub-command.

    :param args: The parsed command line
    :return: The exit status
    """
    apply_runtime_arguments(args)
    given = [option for name, option in _NEW_RUN_OPTIONS.items() if getattr(args, name)]
    if args.optimize:
        # A study's evaluations may use their own environment keywords (a validation split); the rest are a run's.
        refused = [option for option in given if option != _NEW_RUN_OPTIONS["eval_env_kwargs"]]
        if refused:
            raise CommandError(f"-optimize does not take {', '.join(refused)}")
        return run_tuning(args)
    if args.resume is not None:
        if given:
            raise CommandError(f"--resume continues a run with its saved settings: it does not take {', '.join(given)}")
        if args.resume != "latest":
            run_dir = args.resume
        elif args.algo is None or args.env is None:
            raise CommandError("--resume without RUN_DIR needs --algo and --env (the latest run of them is resumed)")
        else:
            run_dir = find_run(args.log_folder, args.algo, args.env)
        with refusing_unsafe_files(), tracking(TrainSettings.of_run(run_dir)):
            resume(
                run_dir,
                n_timesteps=args.n_timesteps,
                progress_bar=not args.no_progress_bar,
                verbose=args.verbose,
                trust_model_file=args.trust_model_file,
            )
        return 0
    if args.algo is None or args.env is None:
        raise CommandError("--algo and --env are required (or --resume RUN_DIR)")
    check_env_id(args.env)
    # The options named as TrainSettings' fields, beyond those it shares with a study's settings.
    same = "eval_freq n_eval_envs save_freq keep_checkpoints vec_env tensorboard_log trained_agent track"
    same += " wandb_project_name wandb_entity"
    settings = TrainSettings(
        seed=args.seed if args.seed >= 0 else random.SystemRandom().randrange(2**31 - 1),  # a random one, as the Zoo
        progress_bar=not args.no_progress_bar,
        best_model_metric=args.best_model_metric or "return",
        **train_options(args),
        **{name: getattr(args, name) for name in same.split()},
    )
    with refusing_unsafe_files(), tracking(settings):
        train(settings, trust_model_file=args.trust_model_file)
    return 0


def run_tuning(args: argparse.Namespace) -> int:
    """
    Run ``sb3-adc train -optimize`` (:func:`sb3_adc.experiment.tuning.tune`).

    :param args: The parsed command line
    :return: The exit status
    """
    from sb3_adc.experiment.tuning import TuneSettings, tune  # Optuna: only when tuning

    if args.resume is not None:
        raise CommandError("-optimize and --resume do not combine: run the same -optimize command again to continue a study")
    if args.algo is None or args.env is None:
        raise CommandError("-optimize needs --algo and --env")
    check_env_id(args.env)
    if args.search_space is not None and not os.path.isfile(args.search_space):
        raise CommandError(f"--search-space: no file {args.search_space}")
    # The options named as TuneSettings' fields, beyond those it shares with a run's settings.
    same = "n_trials sampler pruner n_startup_trials n_evaluations n_jobs storage study_name sampler_seed objective"
    settings = TuneSettings(
        seeds=tuple(args.tuning_seeds if args.tuning_seeds is not None else [max(args.seed, 0)]),
        search_space={} if args.search_space is None else read_yaml_file(args.search_space),
        **train_options(args),
        **{name: getattr(args, name) for name in same.split()},
    )
    tune(settings)
    return 0
