"""``sb3-adc train``: train an algorithm on an environment, in the RL-Zoo log layout."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import time
from collections.abc import Iterator

import stable_baselines3 as sb3

import sb3_adc
from sb3_adc.cli.common import (
    CommandError,
    add_algo_argument,
    add_command,
    add_runtime_arguments,
    apply_runtime_arguments,
    resolve_seed,
    train_options,
)
from sb3_adc.cli.tune_arguments import TUNING_HELP, add_tuning_arguments, run_tuning
from sb3_adc.common.safe_load import UnsafeModelFileError
from sb3_adc.config import check_env_id
from sb3_adc.experiment import TrainSettings, find_run, resume, train
from sb3_adc.experiment.settings import BEST_MODEL_METRICS
from sb3_adc.extras import requires_extra

#: The line of ``sb3-adc train`` in ``sb3-adc --help``.
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

"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """
    Register the sub-command.

    :param subparsers: The ``sb3-adc`` sub-parsers
    """
    parser = add_command(subparsers, "train", HELP, DESCRIPTION + TUNING_HELP, run)
    add_algo_argument(parser, required=False)
    parser.add_argument("--env", help="environment id, e.g. Pendulum-v1 or sb3_adc/NoisyPendulum-v1")
    parser.add_argument("--seed", type=int, default=-1, help="random seed (default: -1, a random seed)")
    parser.add_argument("-n", "--n-timesteps", type=int, default=None, help="training budget, replacing n_timesteps")
    parser.add_argument(
        "-conf",
        "--conf-file",
        default=None,
        help="hyperparameter file, or the name of a shipped one such as paper/adc, the paper's tables "
        "(default: the shipped {algo}.yml)",
    )
    parser.add_argument("-f", "--log-folder", default="logs", help="log folder (default: logs)")
    parser.add_argument(
        "-params",
        "--hyperparams",
        nargs="+",
        metavar="KEY:VALUE",
        help="override hyperparameters, values read as YAML: learning_rate:0.001 train_freq:[1,episode]",
    )
    parser.add_argument("--env-kwargs", nargs="+", metavar="KEY:VALUE", help="keyword arguments of gym.make (YAML values)")
    parser.add_argument(
        "--eval-env-kwargs",
        nargs="+",
        metavar="KEY:VALUE",
        help="keyword arguments of gym.make for the evaluation environments only, replacing those keys of the "
        "training environments' (YAML values)",
    )
    parser.add_argument(
        "-tb",
        "--tensorboard-log",
        default=None,
        metavar="DIR",
        help="TensorBoard log folder: the run logs to DIR/ENV/ALGORITHM_N (default: none; with --track, "
        "LOG_FOLDER/tensorboard)",
    )
    parser.add_argument(
        "-i",
        "--trained-agent",
        default=None,
        metavar="ZIP",
        help="continue training a saved model of --algo in a new run: its weights and the replay buffer saved with "
        "it (a checkpoint's, or replay_buffer.pkl beside it), n_timesteps more",
    )
    parser.add_argument(
        "--eval-freq", type=int, default=None, help="evaluate every K timesteps (default: 20 evaluations per run; <= 0: never)"
    )
    parser.add_argument("--eval-episodes", type=int, default=5, help="episodes per periodic evaluation (default: 5)")
    parser.add_argument(
        "--best-model-metric",
        choices=BEST_MODEL_METRICS,
        default=None,
        help="what picks best_model.zip among the periodic evaluations: return (default, SB3's) or success (the "
        "success rate, each evaluation on the same episodes)",
    )
    parser.add_argument("--n-eval-envs", type=int, default=1, help="environments of the periodic evaluations (default: 1)")
    parser.add_argument(
        "--save-freq", type=int, default=None, help="checkpoint every K timesteps (default: at every evaluation; <= 0: never)"
    )
    parser.add_argument("--keep-checkpoints", type=int, default=2, help="checkpoints kept (default: 2, the latest)")
    parser.add_argument("--final-eval-episodes", type=int, default=10, help="episodes of the final evaluation (default: 10)")
    parser.add_argument(
        "--vec-env", choices=["dummy", "subproc"], default="dummy", help="vectorized env type (default: dummy)"
    )
    parser.add_argument("--verbose", type=int, default=0, help="SB3 verbosity: 0 quiet, 1 training logs (default: 0)")
    parser.add_argument("--no-progress-bar", action="store_true", help="do not show the progress bar")
    parser.add_argument(
        "--resume",
        nargs="?",
        const="latest",
        metavar="RUN_DIR",
        help="continue a run from its last checkpoint: RUN_DIR, or (without value) the latest run of --algo on --env",
    )
    parser.add_argument(
        "--trust-model-file",
        action="store_true",
        help="unpickle the model of -i (and the replay buffer saved with it) or, with --resume, the run's checkpoint "
        "as SB3 does, which runs any code they hold (default: a safe load that builds only known classes and refuses "
        "the rest)",
    )
    add_runtime_arguments(parser)
    tracking = parser.add_argument_group("tracking (--track, the track extra)")
    tracking.add_argument(
        "--track", action="store_true", help="track the run with Weights & Biases (uploads the TensorBoard logs)"
    )
    tracking.add_argument("--wandb-project-name", default="sb3-adc", help="Weights & Biases project (default: sb3-adc)")
    tracking.add_argument(
        "--wandb-entity", default=None, help="Weights & Biases entity (team) of the project (default: your own)"
    )
    add_tuning_arguments(parser)


#: Options of a new run (their settings are saved with it): --resume uses the saved ones.
_NEW_RUN_OPTIONS = {
    "trained_agent": "-i/--trained-agent",
    "tensorboard_log": "-tb/--tensorboard-log",
    "eval_env_kwargs": "--eval-env-kwargs",
    "track": "--track",
    "best_model_metric": "--best-model-metric",
}


def _given(args: argparse.Namespace) -> list[str]:
    """The options of :data:`_NEW_RUN_OPTIONS` given on the command line."""
    return [option for name, option in _NEW_RUN_OPTIONS.items() if getattr(args, name)]


@contextlib.contextmanager
def refusing_unsafe_files() -> Iterator[None]:
    """Turn a safe load's refusal of a model file or run-folder pickle into a command error (exit status 2)."""
    try:
        yield
    except UnsafeModelFileError as error:
        raise CommandError(f"{error} (with --trust-model-file the file is unpickled: do so only if you trust it)") from error


@contextlib.contextmanager
def tracking(settings: TrainSettings) -> Iterator[None]:
    """
    Track the run with Weights & Biases when ``settings.track`` (as the RL Zoo's ``train.py``: ``wandb.init`` with
    ``sync_tensorboard``, which uploads what the model logs to TensorBoard).

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
    if args.optimize:
        # A study's evaluations may use their own environment keywords (a validation split); the rest are a run's.
        refused = [option for option in _given(args) if option != _NEW_RUN_OPTIONS["eval_env_kwargs"]]
        if refused:
            raise CommandError(f"-optimize does not take {', '.join(refused)}")
        return run_tuning(args)
    progress_bar = not args.no_progress_bar
    if args.resume is not None:
        if _given(args):
            raise CommandError(f"--resume continues a run with its saved settings: it does not take {', '.join(_given(args))}")
        if args.resume == "latest":
            if args.algo is None or args.env is None:
                raise CommandError("--resume without RUN_DIR needs --algo and --env (the latest run of them is resumed)")
            run_dir = find_run(args.log_folder, args.algo, args.env)
        else:
            run_dir = args.resume
        with refusing_unsafe_files(), tracking(TrainSettings.of_run(run_dir)):
            resume(
                run_dir,
                n_timesteps=args.n_timesteps,
                progress_bar=progress_bar,
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
        seed=resolve_seed(args.seed),
        progress_bar=progress_bar,
        best_model_metric=args.best_model_metric or "return",
        **train_options(args),
        **{name: getattr(args, name) for name in same.split()},
    )
    with refusing_unsafe_files(), tracking(settings):
        train(settings, trust_model_file=args.trust_model_file)
    return 0
