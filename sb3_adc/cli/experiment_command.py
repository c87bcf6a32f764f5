"""``sb3-adc experiment``: run an experiment file (configurations x environments x seeds), resumable."""

from __future__ import annotations

import argparse
import contextlib
import os

from sb3_adc.cli.benchmark_command import add_backend_arguments, apply_grid_arguments, run_with_progress
from sb3_adc.cli.common import CommandError
from sb3_adc.config import check_env_id
from sb3_adc.experiment.experiments import Experiment, read_experiment, run_experiment
from sb3_adc.experiment.layout import FolderLock
from sb3_adc.experiment.tuning_grid import run_tuning, summarise

HELP = "run an experiment file (configurations x environments x seeds), write its tables and figures"
DESCRIPTION = """\
Run the experiment a YAML file describes (its format: sb3_adc.experiment.experiments, and the files
of benchmarks/experiments/): every configuration x environment x seed, one run per process (local
backend) or per Ray task, resumable like `sb3-adc benchmark`; then write to its results folder the
merged tables (final.csv, evaluations.csv, episodes.csv), the summary (summary.csv, summary.md,
summary_table.csv: IQM [95% CI], across-seed std, AUC, P(reference > configuration)) and the
figures; with test_sets, each finished run's final model scored on its held-out episodes
(test_episodes.csv, test_runs.csv, test_summary.{csv,md}), resumably. A file with tuning: runs one
Optuna study per configuration instead (--workers: each study's worker processes; results: trials.csv,
the winners' hyperparams/, summary.md). A bad file stops the command with exit status 2 before
anything is trained.

examples:
  sb3-adc experiment benchmarks/experiments/noisy_pendulum_shipped.yml --workers 2
  sb3-adc experiment benchmarks/experiments/noisy_pendulum_shipped.yml --report   # redraw, no training
  sb3-adc experiment benchmarks/experiments/noisy_pendulum_shipped.yml --tiny     # does the file run?
  sb3-adc experiment benchmarks/experiments/fair_tuning.yml --workers 2          # equal-budget tuning
"""


PARSER = argparse.ArgumentParser(add_help=False)
PARSER.add_argument("file", help="the experiment file (YAML)")
_mode = PARSER.add_mutually_exclusive_group()
_mode.add_argument("--report", action="store_true", help="only rewrite the summary and figures from its tables")
_mode.add_argument(
    "--tiny", action="store_true", help="a check: one seed, one environment, a few hundred steps, in a temporary folder"
)
add_backend_arguments(PARSER)
PARSER.set_defaults(device="cpu", num_threads=1, gym_packages=[])


def _report_lock(experiment: Experiment) -> contextlib.AbstractContextManager[object]:
    """The results folder's lock, held by a run of the experiment too (a folder that does not exist: nothing to lock)."""
    if not os.path.isdir(experiment.results):
        return contextlib.nullcontext()
    return FolderLock(experiment.results, "running the experiment or writing its report")


def run(args: argparse.Namespace) -> int:
    """
    Run the sub-command.

    :param args: The parsed command line
    :return: The exit status (1 if some runs failed)
    """
    apply_grid_arguments(args)
    experiment = read_experiment(args.file)
    for env_id in experiment.envs:
        check_env_id(env_id)
    if experiment.tuning is not None:
        return run_tuning_file(experiment, args)
    if args.report:
        from sb3_adc.experiment.summary import write_report  # rliable: only the commands that need it import it

        with _report_lock(experiment):
            write_report(experiment, experiment.results, figures=experiment.figures)
        print(f"Wrote the summary and figures of {experiment.name} in {experiment.results}")
        return 0
    experiment.resolved()  # every configuration's entries, checked before anything runs
    n_runs = len(experiment.configs) * (1 if args.tiny else len(experiment.envs) * len(experiment.seeds))
    print(f"Experiment {experiment.name}: {experiment.description}")
    print(f"{len(experiment.configs)} configurations, {n_runs} runs ({args.backend} backend)")
    outcomes = run_with_progress(
        n_runs,
        lambda report: run_experiment(experiment, args.workers, args.backend, args.address, report, tiny=args.tiny),
        name_runs=True,
    )
    if outcomes is None:
        return 130
    failures = [outcome for outcome in outcomes if outcome.status == "failed"]
    if failures:
        print(f"{len(failures)} of {n_runs} runs failed; re-run the same command to retry them.")
        return 1
    if args.tiny:
        print(f"{experiment.name} runs: {n_runs} tiny runs and its report passed (nothing kept)")
    else:
        print(f"Wrote the tables and figures of {experiment.name} in {experiment.results}")
        with open(os.path.join(experiment.results, "summary.md"), encoding="utf-8") as stream:
            print(stream.read())
    return 0


def run_tuning_file(experiment: Experiment, args: argparse.Namespace) -> int:
    """
    Run a file with ``tuning:`` (:mod:`sb3_adc.experiment.tuning_grid`), or only rewrite its summary (``--report``).

    :param experiment: The file
    :param args: The parsed command line
    :return: The exit status
    """
    if args.backend != "local":
        raise CommandError("a tuning file runs on the local backend (--workers: each study's worker processes)")
    if args.report:
        with _report_lock(experiment):
            summary, _ = summarise(experiment, experiment.results, experiment.seeds)
        print("\n".join(summary))
        return 0
    print(f"Experiment {experiment.name}: {experiment.description}")
    print(f"{len(experiment.configs)} studies ({'tiny' if args.tiny else experiment.tuning.trials} trials each)")  # type: ignore[union-attr]
    summary = run_tuning(experiment, args.workers, tiny=args.tiny)
    print("\n".join(summary))
    if args.tiny:
        print(f"{experiment.name} runs: {len(experiment.configs)} tiny studies and their summary passed (nothing kept)")
    else:
        print(f"Wrote the trials, winners and summary of {experiment.name} in {experiment.results}")
    return 0
