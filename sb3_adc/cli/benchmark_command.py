"""``sb3-adc benchmark``: a grid of algorithms x environments x seeds, in parallel, resumable."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable
from typing import TypeVar

from tqdm import tqdm

from sb3_adc.cli.common import CommandError, apply_runtime_arguments, check_positive, key_values
from sb3_adc.config import ALGORITHMS, check_env_id
from sb3_adc.experiment.benchmark import INTERRUPTED, BenchmarkSettings, RunOutcome, run_benchmark

Result = TypeVar("Result")
#: What a grid calls as each run finishes: (outcome, runs done, runs in total).
Reporter = Callable[[RunOutcome, int, int], None]

HELP = "train a grid of algorithms x environments x seeds in parallel (resumable), write tidy CSVs"
DESCRIPTION = """\
Train every algorithm on every environment with every seed, one run per process (local backend)
or per Ray task (--backend ray), and write three tidy CSVs to the log folder:

  evaluations.csv  one row per run and evaluation: algo, env, seed, timesteps, mean_return,
                   std_return, min_return, max_return, mean_ep_length, n_episodes
  episodes.csv     one row per run and training episode: algo, env, seed, episode, timesteps,
                   return, length
  final.csv        one row per run: the final evaluation

Runs live in LOG_FOLDER/ALGO/ENV_seedSEED/. Re-running the same command keeps finished runs (they
are skipped), resumes interrupted ones from their last checkpoint and starts the rest. Runs on disk
trained with other settings (-n, -params, --conf-folder, evaluation) stop the command with exit
status 2 before anything is trained; the CSVs keep the rows of every finished run in the folder.
Then: sb3-adc plot --csv LOG_FOLDER/evaluations.csv

examples:
  sb3-adc benchmark --algos adc ddpg --envs Pendulum-v1 sb3_adc/NoisyPendulum-v1 --seeds 0 1 2 3 4
  sb3-adc benchmark --algos adc ddpg --envs Pendulum-v1 --n-seeds 10 --backend ray --address auto
"""


def add_backend_arguments(parser: argparse.ArgumentParser) -> None:
    """
    ``--backend``, ``--workers`` and ``--address``: where the runs of a grid go (``benchmark`` and ``experiment``).

    :param parser: The sub-command's parser
    """
    parser.add_argument("--backend", choices=["local", "ray"], default="local", help="local process pool or Ray tasks")
    parser.add_argument("--workers", type=int, help="local backend: parallel processes (default: CPU count)")
    parser.add_argument("--address", help="Ray backend: cluster address (default: start a local Ray)")


PARSER = argparse.ArgumentParser(add_help=False)
PARSER.add_argument("--algos", nargs="+", required=True, choices=ALGORITHMS.names(), metavar="ALGO", help="algorithms")
PARSER.add_argument("--envs", nargs="+", required=True, metavar="ENV", help="environment ids")
_seeds = PARSER.add_mutually_exclusive_group()
_seeds.add_argument("--seeds", nargs="+", type=int, metavar="SEED", help="seeds (default: 0 1 2)")
_seeds.add_argument("--n-seeds", type=int, help="use seeds 0 .. N-1")
PARSER.add_argument("-n", "--n-timesteps", type=int, help="budget of every run (default: each entry's)")
PARSER.add_argument("-f", "--log-folder", default="benchmark", help="folder of the runs and CSVs (default: benchmark)")
PARSER.add_argument("--conf-folder", help="folder with {algo}.yml files to use instead of the shipped ones")
PARSER.add_argument("-params", "--hyperparams", nargs="+", metavar="KEY:VALUE", help="overrides applied to every run")
PARSER.add_argument("--eval-freq", type=int, help="evaluate every K timesteps (default: 20 per run)")
PARSER.add_argument("--eval-episodes", type=int, default=5, help="episodes per evaluation (default: 5)")
PARSER.add_argument("--final-eval-episodes", type=int, default=10, help="episodes of the final evaluation (default: 10)")
add_backend_arguments(PARSER)
PARSER.add_argument("--device", default="cpu", help="PyTorch device of the runs (default: cpu)")
PARSER.add_argument("--num-threads", type=int, default=1, help=argparse.SUPPRESS)
PARSER.add_argument("--gym-packages", nargs="+", default=[], metavar="MODULE", help="modules registering environments")


def apply_grid_arguments(args: argparse.Namespace) -> None:
    """
    Apply the runtime options (:func:`~sb3_adc.cli.common.apply_runtime_arguments`) and check those of
    :func:`add_backend_arguments`: ``--workers`` between 1 and four per CPU, and no ``--gym-packages`` with Ray.

    :param args: The parsed command line
    :raises CommandError: for a number of workers out of that range, or ``--gym-packages`` with ``--backend ray``
    """
    apply_runtime_arguments(args)
    most = (os.cpu_count() or 1) * 4
    if args.workers is not None and not 1 <= args.workers <= most:
        raise CommandError(f"--workers must be between 1 and {most}, got {args.workers}")
    if args.gym_packages and args.backend == "ray":
        raise CommandError("--gym-packages is not forwarded to Ray workers; register environments in an imported package")


def run_with_progress(n_runs: int, grid: Callable[[Reporter], Result], name_runs: bool = False) -> Result | None:
    """
    Run ``grid(report)`` behind a progress bar that prints each run as it finishes (and a failed run's traceback).

    :param n_runs: Runs in the grid
    :param grid: Runs the grid, calling the report it is given as each run finishes
    :param name_runs: Prefix each line with the run's grid (the last folder of its log folder: an experiment's
        configuration)
    :return: What ``grid`` returns; ``None`` after Ctrl-C, once the resume message is printed
    """

    def report(outcome: RunOutcome, done: int, total: int) -> None:
        final = outcome.final
        result = "" if final is None else f": final return {final['mean_return']:.2f} +/- {final['std_return']:.2f}"
        name = f"{os.path.basename(os.path.normpath(outcome.log_folder))}: " if name_runs else ""
        progress.write(f"[{done}/{total}] {name}{outcome.spec} {outcome.status}{result}")
        if outcome.status == "failed":
            progress.write(outcome.error)
        progress.update(1)

    with tqdm(total=n_runs, unit="run") as progress, contextlib.suppress(KeyboardInterrupt):
        return grid(report)
    print(f"\n{INTERRUPTED}", file=sys.stderr)
    return None


def run(args: argparse.Namespace) -> int:
    """
    Run the sub-command.

    :param args: The parsed command line
    :return: The exit status (1 if some runs failed)
    """
    apply_grid_arguments(args)
    for env_id in args.envs:
        check_env_id(env_id)
    if args.n_seeds is not None:
        check_positive(args.n_seeds, "--n-seeds")
    seeds = list(range(args.n_seeds)) if args.n_seeds is not None else args.seeds or [0, 1, 2]
    same = ("log_folder", "n_timesteps", "conf_folder", "eval_freq", "eval_episodes", "final_eval_episodes", "device")
    settings = BenchmarkSettings(
        algos=list(dict.fromkeys(args.algos)),
        env_ids=list(dict.fromkeys(args.envs)),
        seeds=list(dict.fromkeys(seeds)),
        overrides=key_values(args.hyperparams, "-params"),
        **{name: getattr(args, name) for name in same},
    )
    n_runs = len(settings.grid())
    print(
        f"Benchmark: {len(settings.algos)} algorithms x {len(settings.env_ids)} environments x {len(settings.seeds)} seeds "
        f"= {n_runs} runs in {settings.log_folder} ({args.backend} backend)"
    )
    result = run_with_progress(
        n_runs,
        lambda report: run_benchmark(
            settings, backend=args.backend, workers=args.workers, address=args.address, report=report
        ),
    )
    if result is None:
        return 130
    for name, path in result.tables.items():
        print(f"Wrote {name}: {path}")
    if result.failures:
        failed = ", ".join(str(outcome.spec) for outcome in result.failures)
        print(f"{len(result.failures)} of {n_runs} runs failed ({failed}); re-run the same command to retry them.")
        return 1
    print(f"Next: sb3-adc plot --csv {os.path.join(settings.log_folder, 'evaluations.csv')}")
    return 0
