"""``sb3-adc plot``: the figures and tables of :func:`~sb3_adc.experiment.plots.plot_results` from benchmark CSVs."""

from __future__ import annotations

import argparse
import glob
import os
import sys

import pandas as pd

from sb3_adc.cli.common import CommandError, check_positive
from sb3_adc.experiment.benchmark import EPISODES_CSV, EVALUATIONS_CSV, FINAL_CSV
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.results import (
    EPISODE_COLUMNS,
    EVALUATION_COLUMNS,
    FINAL_COLUMNS,
    Row,
    episode_rows,
    evaluation_rows,
    final_row,
    read_table,
)
from sb3_adc.experiment.settings import TrainSettings

#: What ``--csv`` accepts, for error messages.
CSV_ACCEPTS = (
    "--csv accepts the evaluations.csv written by sb3-adc benchmark, the folder holding it, a run folder of "
    "sb3-adc train (e.g. logs/adc/Pendulum-v1_1, or its evaluations.npz) or a folder of such runs (e.g. logs)"
)

HELP = "learning curves, reward variance, IQM/mean, performance profiles, P(X > Y) with bootstrap CIs (rliable)"
DESCRIPTION = """\
Plot the results of `sb3-adc benchmark` with rliable statistics (95% stratified-bootstrap CIs):

  learning_curves.png     mean evaluation return across runs per algorithm, with its CI
  reward_variance.png     across-run variance of the rewards (the ADC paper's Figures 5 and 8): of the
                          evaluation returns and, from episodes.csv, of the training-episode returns
  final_performance.png   IQM and mean of the final returns with their CIs (one x range for all panels)
  performance_profiles.png        fraction of runs whose final return exceeds each threshold, with its CI
  probability_of_improvement.png  P(X > Y) that a run of X ends above a run of Y, per pair of algorithms
  final_performance.csv/.md, curves.csv, episode_variance.csv, performance_profiles.csv,
  probability_of_improvement.csv   the numbers behind the figures

final.csv and episodes.csv are read from the folder of --csv when present. --csv may also be the folder of a
benchmark, a run folder of `sb3-adc train` or a folder of runs (their evaluations.npz, monitor files and final
evaluations are read as the benchmark tables are). Confidence intervals and P(X > Y) need at least 2 runs of
each algorithm on each environment.

examples:
  sb3-adc plot --csv benchmark/evaluations.csv -o benchmark/plots
  sb3-adc plot --csv logs/adc/Pendulum-v1_1
"""


PARSER = argparse.ArgumentParser(add_help=False)
PARSER.add_argument(
    "--csv",
    required=True,
    help="evaluation curves written by sb3-adc benchmark (evaluations.csv, or its folder), or a run folder of "
    "sb3-adc train, or a folder of runs",
)
PARSER.add_argument("--final-csv", help="final evaluations (default: final.csv next to --csv, else the last evaluations)")
PARSER.add_argument("--episodes-csv", help="training episodes (default: episodes.csv next to --csv, if present)")
PARSER.add_argument("-o", "--output-dir", help="where to write (default: a plots folder next to --csv)")
PARSER.add_argument("--algos", nargs="+", metavar="ALGO", help="only these algorithms")
PARSER.add_argument("--envs", nargs="+", metavar="ENV", help="only these environments")
PARSER.add_argument("--reps", type=int, default=2000, help="bootstrap replications (default: 2000)")
PARSER.add_argument("--window", type=int, default=10, help="episodes of the variance moving average (default: 10)")
PARSER.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default: 0)")

#: The columns ``--final-csv`` and ``--episodes-csv`` need.
_FINAL_NEEDS = ("algo", "env", "seed", "mean_return")
_EPISODES_NEEDS = ("algo", "env", "seed", "episode", "return")


def _read(path: str | None, default: str, required_columns: tuple[str, ...], option: str = "--csv") -> pd.DataFrame | None:
    path = path or (default if os.path.isfile(default) else None)
    if path is None:
        return None
    if not os.path.isfile(path):
        raise CommandError(f"{option}: {path} does not exist" + (f"; {CSV_ACCEPTS}" if option == "--csv" else ""))
    try:
        table = read_table(path)
    except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as error:
        accepts = CSV_ACCEPTS if option == "--csv" else f"{option} accepts a CSV table written by sb3-adc benchmark"
        raise CommandError(f"{option}: {path} is not a CSV table ({type(error).__name__}); {accepts}") from None
    if missing := [column for column in required_columns if column not in table.columns]:
        lacks = f"lacks the columns {', '.join(missing)}"
        raise CommandError(f"{option}: {path} {lacks} (is it a table written by sb3-adc benchmark?)")
    return table


def _is_run(folder: str) -> bool:
    return bool(glob.glob(os.path.join(glob.escape(folder), "*", "args.yml")))


def _run_folders(folder: str) -> list[str]:
    """The run folders of ``sb3-adc train`` or ``benchmark`` in ``folder``: itself, or up to two levels below."""
    if _is_run(folder):
        return [folder]
    escaped = glob.escape(folder)
    candidates = [path for depth in ("*", "*/*") for path in sorted(glob.glob(os.path.join(escaped, depth, "")))]
    return [os.path.normpath(candidate) for candidate in candidates if _is_run(candidate)]


def _read_runs(runs: list[str]) -> tuple[pd.DataFrame, pd.DataFrame | None, pd.DataFrame | None]:
    """The evaluation, final and episode tables (``None``: no run has any) of run folders, as the benchmark's."""
    evaluations: list[Row] = []
    finals: list[Row] = []
    episodes: list[Row] = []
    layouts: dict[tuple[str, str], list[tuple[RunLayout, int]]] = {}
    for run_dir in runs:
        try:
            settings = TrainSettings.of_run(run_dir)
        except (FileNotFoundError, ValueError, TypeError) as error:
            print(f"sb3-adc plot: warning: {run_dir} is left out: {error}", file=sys.stderr)
            continue
        layouts.setdefault((settings.algo, settings.env_id), []).append((RunLayout(run_dir, settings.env_id), settings.seed))
    for (algo, env_id), group in layouts.items():
        seeds = [seed for _, seed in group]
        if len(set(seeds)) < len(seeds):  # a run trained twice: the runs are numbered instead
            print(f"note: several runs of {algo} on {env_id} have the same seed; they are numbered 0..{len(seeds) - 1}")
            seeds = list(range(len(seeds)))
        for (layout, _), seed in zip(group, seeds, strict=True):
            if not os.path.isfile(layout.evaluations):
                print(f"sb3-adc plot: warning: {layout.run_dir} has no evaluations yet; left out", file=sys.stderr)
                continue
            evaluations += evaluation_rows(layout, algo, seed)
            episodes += episode_rows(layout, algo, seed)
            finals += [row for row in [final_row(layout, algo, seed)] if row is not None]
    if not evaluations:
        raise CommandError(f"--csv: no evaluations in {', '.join(runs)}; {CSV_ACCEPTS}")
    return (
        pd.DataFrame(evaluations, columns=list(EVALUATION_COLUMNS)),
        pd.DataFrame(finals, columns=list(FINAL_COLUMNS)) if finals else None,
        pd.DataFrame(episodes, columns=list(EPISODE_COLUMNS)) if episodes else None,
    )


def _read_inputs(args: argparse.Namespace) -> tuple[pd.DataFrame, pd.DataFrame | None, pd.DataFrame | None, str]:
    """The tables that ``--csv``, ``--final-csv`` and ``--episodes-csv`` name, and the folder of the default output."""
    path = args.csv
    if os.path.basename(path) == "evaluations.npz" and os.path.isfile(path):
        path = os.path.dirname(os.path.abspath(path))  # a run's own evaluations: its run folder
    if os.path.isdir(path) and not os.path.isfile(os.path.join(path, EVALUATIONS_CSV)):
        if not (runs := _run_folders(path)):
            raise CommandError(f"--csv: {path} holds neither {EVALUATIONS_CSV} nor runs; {CSV_ACCEPTS}")
        evaluations, final, episodes = _read_runs(runs)
        final = _read(args.final_csv, "", _FINAL_NEEDS, "--final-csv") if args.final_csv else final
        episodes = _read(args.episodes_csv, "", _EPISODES_NEEDS, "--episodes-csv") if args.episodes_csv else episodes
        return evaluations, final, episodes, path
    if os.path.isdir(path):
        path = os.path.join(path, EVALUATIONS_CSV)
    folder = os.path.dirname(os.path.abspath(path))
    evaluations_table = _read(path, path, EVALUATION_COLUMNS[:5])
    assert evaluations_table is not None
    final_table = _read(args.final_csv, os.path.join(folder, FINAL_CSV), _FINAL_NEEDS, "--final-csv")
    episodes_table = _read(args.episodes_csv, os.path.join(folder, EPISODES_CSV), _EPISODES_NEEDS, "--episodes-csv")
    return evaluations_table, final_table, episodes_table, folder


def _warn_single_runs(final: pd.DataFrame) -> None:
    """Warn where an algorithm has fewer than 2 runs on an environment: its CIs and P(X > Y) mean nothing."""
    counts = final.groupby(["algo", "env"])["seed"].nunique()
    single = [f"{algo} on {env}" for (algo, env), count in counts.items() if count < 2]
    if single:
        print(
            f"sb3-adc plot: warning: one run only of {', '.join(single)}: confidence intervals and P(X > Y) need at "
            "least 2 runs of each algorithm on each environment (e.g. sb3-adc benchmark --n-seeds 5); with one run "
            "an interval is a single point and P(X > Y) compares two single runs (0 or 1).",
            file=sys.stderr,
        )


def _select(table: pd.DataFrame | None, args: argparse.Namespace) -> pd.DataFrame | None:
    for column, chosen in (("algo", args.algos), ("env", args.envs)):
        if table is not None and chosen:
            table = table[table[column].isin(chosen)]
    return table


def run(args: argparse.Namespace) -> int:
    """
    Run the sub-command.

    :param args: The parsed command line
    :return: The exit status
    """
    # rliable, SciPy and matplotlib take a second to import: only for this sub-command.
    from sb3_adc.experiment.plots import plot_comparisons, plot_results
    from sb3_adc.experiment.statistics import last_evaluations

    check_positive(args.reps, "--reps")
    check_positive(args.window, "--window")
    evaluations, final, episodes, folder = _read_inputs(args)
    evaluations = _select(evaluations, args)
    assert evaluations is not None
    if evaluations.empty:
        raise CommandError(f"no evaluations to plot in {args.csv} (after --algos/--envs)")
    output_dir = args.output_dir or os.path.join(folder, "plots")
    final, episodes = _select(final, args), _select(episodes, args)
    outputs = plot_results(evaluations, output_dir, final, episodes, reps=args.reps, seed=args.seed, window=args.window)
    compared = final if final is not None and not final.empty else last_evaluations(evaluations)
    _warn_single_runs(compared)
    comparisons = plot_comparisons(compared, output_dir, reps=args.reps, seed=args.seed)
    outputs.figures += comparisons.figures
    outputs.tables += comparisons.tables
    with open(os.path.join(output_dir, "final_performance.md"), encoding="utf-8") as stream:
        print(stream.read())
    for path in outputs.figures + outputs.tables:
        print(f"Wrote {path}")
    return 0
