"""
``sb3-adc plot``: learning curves, reward-variance curves, a final-performance table, performance profiles and
the probability of improvement from benchmark CSVs.
"""

from __future__ import annotations

import argparse
import os

import pandas as pd

from sb3_adc.cli.common import CommandError
from sb3_adc.experiment.benchmark import EPISODES_CSV, FINAL_CSV
from sb3_adc.experiment.results import EVALUATION_COLUMNS, read_table

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

final.csv and episodes.csv are read from the folder of --csv when present.

example:
  sb3-adc plot --csv benchmark/evaluations.csv -o benchmark/plots
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """
    Register the sub-command.

    :param subparsers: The ``sb3-adc`` sub-parsers
    """
    parser = subparsers.add_parser(
        "plot",
        help="learning curves, reward variance, IQM/mean, performance profiles, P(X > Y) with bootstrap CIs (rliable)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--csv", required=True, help="evaluation curves written by sb3-adc benchmark (evaluations.csv)")
    parser.add_argument("--final-csv", help="final evaluations (default: final.csv next to --csv, else the last evaluations)")
    parser.add_argument("--episodes-csv", help="training episodes (default: episodes.csv next to --csv, if present)")
    parser.add_argument("-o", "--output-dir", help="where to write (default: a plots folder next to --csv)")
    parser.add_argument("--algos", nargs="+", metavar="ALGO", help="only these algorithms")
    parser.add_argument("--envs", nargs="+", metavar="ENV", help="only these environments")
    parser.add_argument("--reps", type=int, default=2000, help="bootstrap replications (default: 2000)")
    parser.add_argument("--window", type=int, default=10, help="episodes of the variance moving average (default: 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default: 0)")
    parser.set_defaults(handler=run)


def _read(path: str | None, default: str, required_columns: tuple[str, ...]) -> pd.DataFrame | None:
    path = path or (default if os.path.isfile(default) else None)
    if path is None:
        return None
    if not os.path.isfile(path):
        raise CommandError(f"{path} does not exist")
    table = read_table(path)
    missing = [column for column in required_columns if column not in table.columns]
    if missing:
        raise CommandError(f"{path} lacks the columns {', '.join(missing)} (is it a table written by sb3-adc benchmark?)")
    return table


def _select(table: pd.DataFrame | None, args: argparse.Namespace) -> pd.DataFrame | None:
    if table is None:
        return None
    if args.algos:
        table = table[table["algo"].isin(args.algos)]
    if args.envs:
        table = table[table["env"].isin(args.envs)]
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

    if args.reps < 1:
        raise CommandError(f"--reps must be >= 1, got {args.reps}")
    if args.window < 1:
        raise CommandError(f"--window must be >= 1, got {args.window}")
    folder = os.path.dirname(os.path.abspath(args.csv))
    evaluations = _read(args.csv, args.csv, EVALUATION_COLUMNS[:5])
    assert evaluations is not None
    final = _read(args.final_csv, os.path.join(folder, FINAL_CSV), ("algo", "env", "seed", "mean_return"))
    episodes = _read(args.episodes_csv, os.path.join(folder, EPISODES_CSV), ("algo", "env", "seed", "episode", "return"))
    evaluations = _select(evaluations, args)
    assert evaluations is not None
    if evaluations.empty:
        raise CommandError(f"no evaluations to plot in {args.csv} (after --algos/--envs)")
    output_dir = args.output_dir or os.path.join(folder, "plots")
    final = _select(final, args)
    outputs = plot_results(
        evaluations,
        output_dir,
        final=final,
        episodes=_select(episodes, args),
        reps=args.reps,
        seed=args.seed,
        window=args.window,
    )
    comparisons = plot_comparisons(
        final if final is not None and not final.empty else last_evaluations(evaluations),
        output_dir,
        reps=args.reps,
        seed=args.seed,
    )
    outputs.figures += comparisons.figures
    outputs.tables += comparisons.tables
    with open(os.path.join(output_dir, "final_performance.md"), encoding="utf-8") as stream:
        print(stream.read())
    for path in outputs.figures + outputs.tables:
        print(f"Wrote {path}")
    return 0
