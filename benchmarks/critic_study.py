"""
The critic study: does ADC's shipped default beat equally budgeted DDPG, TD3 and SAC, on seeds tuning never saw?

Every configuration is a ``sb3-adc benchmark`` grid (the one engine: resumable, one process per run) on the same
environments, seeds and budget, evaluated the same way; the tables are merged with the configuration's name in
the ``algo`` column and summarised with rliable: IQM of the final return with 95% stratified-bootstrap CIs, the
across-seed standard deviation, the area under the evaluation curve (mean evaluation return over the run, with
its IQM and CI), and the probability that the shipped ADC improves on each other configuration (with CI).

Configurations (:data:`CONFIGS`): the shipped ADC entry (its default critic design), the same entry with the
paper's critic (``critic_design: paper``) and the other designs, the shipped DDPG entry, TD3 and SAC with the
RL Zoo's Pendulum settings (``benchmarks/configs/rl_zoo/``), and the winners of the equal-budget tuning
(``*_tuned``, ``benchmarks/fair_tuning.py``). Every run gets the same budget (``--n-timesteps``, default 20 000
steps = 100 episodes of 200 steps).

The runs go to ``benchmarks/runs/critic_study/`` (not committed); the tables to
``benchmarks/results/critic_study/{grid}/`` and the figures to ``docs/_static/benchmarks/critic_study_*.png``.

Usage::

    python benchmarks/critic_study.py --workers 2                       # the evidence grid, seeds 1000-1009
    python benchmarks/critic_study.py --grid pendulum --workers 2       # the same on the noise-free Pendulum
    python benchmarks/critic_study.py --grid screen --workers 2         # the design screen on tuning seeds 0-4
    python benchmarks/critic_study.py --grid tuned --workers 2          # the equally tuned algorithms, fresh seeds
    python benchmarks/critic_study.py --grid warmup --workers 2         # two warm-ups each, tuning seeds 0-4
    python benchmarks/critic_study.py --grid shipped --workers 2        # the shipped entries after it, fresh seeds
    python benchmarks/critic_study.py --grid lidar --workers 2          # the lidar courses, fresh seeds
    python benchmarks/critic_study.py --grid lidar_plain --workers 2    # the plain lidar course alone
    python benchmarks/critic_study.py --grid wallclock --workers 2      # the shipped entries against wall-clock time
    python benchmarks/critic_study.py --grid recipe --workers 2         # ADC's critic in TD3's recipe, seeds 0-4
    python benchmarks/critic_study.py --grid intervals --workers 2      # 20-140 intervals, shipped entries
    python benchmarks/critic_study.py --grid intervals_paper --workers 2  # the same with the paper's Table 3
    python benchmarks/critic_study.py --grid pendulum_paper --workers 2   # Figures 4-5 with the paper's Table 1
    python benchmarks/critic_study.py --configs adc ddpg --workers 2    # a subset (its tables hold only these)
    python benchmarks/critic_study.py --quick                           # a smoke run
"""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch as th
from rliable import library as rly
from rliable import metrics

from sb3_adc.config import packaged_hyperparams_file
from sb3_adc.experiment.benchmark import (
    EPISODES_CSV,
    EVALUATIONS_CSV,
    FINAL_CSV,
    BenchmarkSettings,
    RunOutcome,
    run_benchmark,
    run_script,
)
from sb3_adc.experiment.plots import plot_results
from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.results import read_table
from sb3_adc.experiment.statistics import CONFIDENCE, time_to_threshold

ROOT = Path(__file__).resolve().parent
RUNS_DIR = ROOT / "runs" / "critic_study"
RESULTS_DIR = ROOT / "results" / "critic_study"
DOCS_STATIC = ROOT.parent / "docs" / "_static" / "benchmarks"

#: The winners of the equal-budget tuning (``benchmarks/fair_tuning.py``), one ``{algo}.yml`` each.
TUNED = ROOT / "results" / "fair_tuning" / "hyperparams"
#: The RL Zoo's published Pendulum settings (rl_zoo3 2.9.2), one ``{algo}.yml`` each.
ZOO = ROOT / "configs" / "rl_zoo"

#: ``hyperparams/{adc,ddpg}.yml`` as shipped until the warm-up ablation (``learning_starts: 5000`` on the noisy
#: Pendulum): the grids run before it train these copies, so their committed results stay reproducible.
WARMUP5000 = ROOT / "configs" / "warmup5000"

#: The paper's hyperparameter files (``hyperparams/paper/{algo}.yml``: Table 3 for the noisy Pendulum).
PAPER = Path(packaged_hyperparams_file("paper/adc")).parent

#: ADC with TD3's tuned entry and TD3's additions (twin critics, target smoothing, delayed actor updates).
TD3_RECIPE = ROOT / "configs" / "td3_recipe"

#: Configuration name -> (algorithm, hyperparameter overrides, folder of ``{algo}.yml`` files: ``None`` for the
#: shipped ones).
CONFIGS: dict[str, tuple[str, dict[str, Any], Path | None]] = {
    "adc": ("adc", {}, WARMUP5000),
    "adc_paper": ("adc", {"critic_design": "paper"}, WARMUP5000),
    "adc_state_value": ("adc", {"critic_design": "state_value"}, WARMUP5000),
    "adc_legendre": ("adc", {"critic_design": "legendre"}, WARMUP5000),
    "adc_action_network": ("adc", {"critic_design": "action_network", "n_intervals": 16}, WARMUP5000),
    "ddpg": ("ddpg", {}, WARMUP5000),
    # The entries shipped now.
    "adc_shipped": ("adc", {}, None),
    "ddpg_shipped": ("ddpg", {}, None),
    # The RL Zoo's published Pendulum settings (shipped for the noisy Pendulum too until the equal-budget tuning).
    "td3": ("td3", {}, ZOO),
    "sac": ("sac", {}, ZOO),
    "adc_tuned": ("adc", {}, TUNED),
    "ddpg_tuned": ("ddpg", {}, TUNED),
    "td3_tuned": ("td3", {}, TUNED),
    "sac_tuned": ("sac", {}, TUNED),
    # The RL Zoo's published DDPG Pendulum settings: the bar the shipped DDPG entry must clear.
    "ddpg_zoo": ("ddpg", {}, ZOO),
    "td3_shipped": ("td3", {}, None),
    "sac_shipped": ("sac", {}, None),
    # The warm-up ablation: every algorithm at the other warm-up of the two that the tuned entries use.
    "adc_warmup1000": ("adc", {"learning_starts": 1000}, WARMUP5000),
    "ddpg_warmup1000": ("ddpg", {"learning_starts": 1000}, WARMUP5000),
    "td3_tuned_warmup5000": ("td3", {"learning_starts": 5000}, TUNED),
    "sac_tuned_warmup5000": ("sac", {"learning_starts": 5000}, TUNED),
    # ADC's dueling critic inside TD3's tuned recipe.
    "adc_td3_recipe": ("adc", {}, TD3_RECIPE),
    # The paper's interval counts (Figures 9-10): the shipped entry, and the paper's Table 3 (its critic).
    **{f"adc_shipped_n{n}": ("adc", {"n_intervals": n}, None) for n in (20, 60, 140)},
    **{f"adc_table3_n{n}": ("adc", {"n_intervals": n}, PAPER) for n in (20, 60, 100, 140)},
    "ddpg_table3": ("ddpg", {}, PAPER),
    # The paper's Table 1 on Pendulum (Figures 4-5): ADC with its critic, DDPG, the vanilla actor-critic and the
    # dueling DQN over 25 actions.
    **{f"{algo}_table1": (algo, {}, PAPER) for algo in ("adc", "ddpg", "vanilla_ac", "dqn")},
    # The paper's Table 2 on the navigation task (Figures 7-8): ADC with its critic, and DDPG.
    **{f"{algo}_table2": (algo, {}, PAPER) for algo in ("adc", "ddpg")},
}

#: Grid name -> (environments, seeds, default configurations).
GRIDS: dict[str, tuple[list[str], list[int], list[str]]] = {
    # Fresh seeds that no tuning or design choice saw.
    "evidence": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc", "adc_paper", "ddpg", "td3"],
    ),
    # The same comparison on the noise-free Pendulum, the paper's Figures 4-5 task (fresh seeds too).
    "pendulum": (
        ["Pendulum-v1"],
        list(range(1000, 1010)),
        ["adc", "ddpg", "td3"],
    ),
    # The design screen, on the tuning seeds.
    "screen": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(5)),
        ["adc_legendre", "adc_action_network", "ddpg", "adc_state_value", "adc_paper"],
    ),
    # The equally tuned algorithms on fresh seeds (the paper's critic on the same seeds: the evidence grid).
    "tuned": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc_tuned", "ddpg_tuned", "td3_tuned", "sac_tuned", "ddpg_zoo"],
    ),
    # The warm-up ablation on the tuning seeds, the same two warm-ups (1000 and 5000 steps) for every algorithm:
    # the tuned ADC and DDPG start updating after 5000 steps, the tuned TD3 and SAC after 1000. Rule, fixed
    # before the run: an algorithm ships the warm-up with the higher mean area under the curve over seeds 0-4,
    # unless its mean final return is lower than the other warm-up's by more than 5.
    "warmup": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(5)),
        [
            "adc_tuned",
            "adc_warmup1000",
            "ddpg_tuned",
            "ddpg_warmup1000",
            "td3_tuned",
            "td3_tuned_warmup5000",
            "sac_tuned",
            "sac_tuned_warmup5000",
        ],
    ),
    # The entries shipped after the warm-up ablation (ADC and DDPG with its 1000-step warm-up; TD3 and SAC are the
    # tuned entries, trained as `*_tuned`), beside the tuned ADC and DDPG with their 5000-step warm-up, on fresh
    # seeds; the runs folder is the tuned grid's, so the runs they share are trained once.
    "shipped": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc_shipped", "ddpg_shipped", "td3_tuned", "sac_tuned", "adc_tuned", "ddpg_tuned"],
    ),
    # The paper's navigation task, plain and with noisy observations (Section 5.2), on fresh seeds, with every
    # algorithm's shipped entry (ADC's pins the paper's critic on these courses; `adc_legendre` is the default).
    "lidar": (
        ["sb3_adc/LidarObstacleCourse-v0", "sb3_adc/LidarObstacleCourseNoisy-v0"],
        list(range(1000, 1010)),
        ["adc_legendre", "adc", "ddpg", "td3_shipped"],
    ),
    # The plain course of the lidar grid on its own (that grid's first invocation finished the noisy course and 2 of
    # the plain course's 40 runs); the runs folder is the lidar grid's.
    "lidar_plain": (
        ["sb3_adc/LidarObstacleCourse-v0"],
        list(range(1000, 1010)),
        ["adc_legendre", "adc", "ddpg", "td3_shipped"],
    ),
    # Does ADC's dueling critic add to TD3's recipe? ADC's default critic with the tuned TD3 entry and TD3's
    # additions, against the tuned TD3, on the tuning seeds. Rule, fixed before the run: it goes on to fresh seeds
    # if its mean area under the curve over seeds 0-4 is at least TD3's and its mean final return is not lower
    # than TD3's by more than 5 (the warm-up rule).
    "recipe": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(5)),
        ["adc_td3_recipe", "td3_tuned"],
    ),
    # The paper's Figures 9-10: ADC with 20, 60, 100 and 140 intervals against DDPG on the noisy Pendulum, with
    # the shipped entries (the runs folder is the tuned grid's: the 100-interval ADC and DDPG are the wallclock
    # grid's runs) and with the paper's Table 3 for 300 episodes (60 000 steps; the paper's figures show the first
    # few hundred episodes).
    "intervals": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc_shipped_n20", "adc_shipped_n60", "adc_shipped", "adc_shipped_n140", "ddpg_shipped"],
    ),
    "intervals_paper": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc_table3_n20", "adc_table3_n60", "adc_table3_n100", "adc_table3_n140", "ddpg_table3"],
    ),
    # The paper's Figures 4-5 with its Table 1, on fresh seeds, for 300 episodes (60 000 steps: the window of
    # episodes 50-300 in which the paper reports ADC ahead of DDPG), with TD3 and SAC as modern references on
    # their shipped Pendulum-v1 entries (the RL Zoo's; the paper has no table for them).
    "pendulum_paper": (
        ["Pendulum-v1"],
        list(range(1000, 1010)),
        ["adc_table1", "ddpg_table1", "vanilla_ac_table1", "dqn_table1", "td3_shipped", "sac_shipped"],
    ),
    # The paper's Figures 7-8 with its Table 2 on the paper-style course, on fresh seeds, for the entries' budget
    # (30 000 steps; an episode lasts up to 500 steps, less after a collision; the paper trained 3500 episodes).
    "lidar_paper": (
        ["sb3_adc/LidarObstacleCourse-v0"],
        list(range(1000, 1010)),
        ["adc_table2", "ddpg_table2"],
    ),
    # The shipped ADC entry against DDPG's once more after the default critic's two output layers became one
    # (same function, initialisation and update rule; float rounding differs, so the runs are new): returns and
    # wall-clock time in the same run, in a runs folder of its own.
    "cost": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc_shipped", "ddpg_shipped"],
    ),
    # The shipped entries of the noisy Pendulum again, now that the tables hold each episode's wall-clock time:
    # learning curves against seconds of training, the cost side of the default critic (the runs folder is the
    # tuned grid's, so on a machine that kept the shipped grid's runs nothing is retrained).
    "wallclock": (
        ["sb3_adc/NoisyPendulum-v1"],
        list(range(1000, 1010)),
        ["adc_shipped", "ddpg_shipped", "td3_tuned", "sac_tuned"],
    ),
}

#: Grid -> the grid whose runs folder it shares (a finished run is then trained once for both).
SHARED_RUNS = {"shipped": "tuned", "lidar_plain": "lidar", "wallclock": "tuned", "recipe": "warmup", "intervals": "tuned"}

#: Grid -> budget of every run, when it is not ``DEFAULT_BUDGET`` (``None``: each entry's ``n_timesteps``).
BUDGETS: dict[str, int | None] = {
    "lidar": None,
    "lidar_plain": None,
    "lidar_paper": None,
    "intervals_paper": 60_000,
    "pendulum_paper": 60_000,
}
DEFAULT_BUDGET = 20_000

#: Grid -> the configuration whose improvement over the others is measured.
REFERENCES = {
    "evidence": "adc",
    "pendulum": "adc",
    "screen": "adc_legendre",
    "tuned": "adc_tuned",
    "warmup": "adc_warmup1000",
    "shipped": "adc_shipped",
    "lidar": "adc_legendre",
    "lidar_plain": "adc_legendre",
    "wallclock": "adc_shipped",
    "recipe": "adc_td3_recipe",
    "intervals": "adc_shipped",
    "intervals_paper": "adc_table3_n100",
    "pendulum_paper": "adc_table1",
    "lidar_paper": "adc_table2",
    "cost": "adc_shipped",
}

#: Grid -> the evaluation return a run must stay at or above to count as converged (the paper's "converges at
#: around the 120th episode"), fixed before the runs: a Pendulum policy above -300 swings up and holds the pole.
THRESHOLDS = {"intervals": -300.0, "intervals_paper": -300.0, "pendulum_paper": -300.0}


def report(outcome: RunOutcome, done: int, total: int) -> None:
    final = "" if outcome.final is None else f" final return {outcome.final['mean_return']:.1f}"
    print(f"[{done}/{total}] {outcome.spec}: {outcome.status}{final}", flush=True)
    if outcome.status == "failed":
        print(outcome.error, flush=True)


def run_config(
    name: str, envs: list[str], seeds: list[int], folder: Path, n_timesteps: int | None, workers: int
) -> dict[str, str]:
    """Train (or resume, or skip when finished) one configuration's grid; return its tables."""
    algo, overrides, conf_folder = CONFIGS[name]
    settings = BenchmarkSettings(
        algos=[algo],
        env_ids=envs,
        seeds=seeds,
        log_folder=str(folder / name),
        n_timesteps=n_timesteps,
        overrides=dict(overrides),
        conf_folder=None if conf_folder is None else str(conf_folder),
        eval_episodes=5,
        final_eval_episodes=20,
        device="cpu",
    )
    result = run_benchmark(settings, workers=workers, report=report)
    if result.failures:
        raise SystemExit(f"{len(result.failures)} runs of {name} failed; re-run to retry them")
    return result.tables


def merge(tables: dict[str, dict[str, str]], table: str) -> pd.DataFrame:
    """One table of every configuration, with the configuration's name in the ``algo`` column."""
    frames = []
    for name, paths in tables.items():
        frame = read_table(paths[table])
        frame["algo"] = name
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def _interval(data: dict[str, Any], func: Any, reps: int, seed: int) -> tuple[dict[str, Any], dict[str, Any]]:
    # rliable draws its resamples from NumPy's global generator: seed it, and restore it afterwards.
    state = np.random.get_state()  # noqa: NPY002
    np.random.seed(seed)  # noqa: NPY002
    try:
        with warnings.catch_warnings():
            # rliable passes `random_state` to arch, which deprecates it.
            warnings.filterwarnings("ignore", category=FutureWarning, module="arch")
            points, intervals = rly.get_interval_estimates(
                data, func, reps=reps, confidence_interval_size=CONFIDENCE, random_state=np.random.RandomState(seed)
            )
    finally:
        np.random.set_state(state)  # noqa: NPY002
    return points, intervals


def summary(
    final: pd.DataFrame, evaluations: pd.DataFrame, reps: int, reference: str, episodes: pd.DataFrame | None = None
) -> pd.DataFrame:
    """
    Per environment and configuration: final-return IQM and mean with CIs, across-seed std, area under the
    evaluation curve (per run: the mean evaluation return over the run, trapezoidal in timesteps) with its IQM
    and CI, the probability that ``reference`` improves on the configuration (final return), with CI, and, when
    the episodes carry their wall-clock time, the median seconds a run trained (``run_time_s_median``).
    """
    rows = []
    for env, env_final in final.groupby("env", sort=True):
        scores: dict[str, np.ndarray] = {}
        areas: dict[str, np.ndarray] = {}
        for name, group in env_final.groupby("algo", sort=False):
            ordered = group.sort_values("seed")
            scores[str(name)] = ordered["mean_return"].to_numpy(np.float64).reshape(-1, 1)
            curves = evaluations[(evaluations["env"] == env) & (evaluations["algo"] == name)]
            per_run = []
            for seed in ordered["seed"]:
                curve = curves[curves["seed"] == seed].sort_values("timesteps")
                x, y = curve["timesteps"].to_numpy(np.float64), curve["mean_return"].to_numpy(np.float64)
                per_run.append(np.trapezoid(y, x) / (x[-1] - x[0]) if len(x) > 1 else np.nan)
            areas[str(name)] = np.asarray(per_run).reshape(-1, 1)
        iqm_mean = lambda x: np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x)])  # noqa: E731
        final_points, final_intervals = _interval(scores, iqm_mean, reps, 0)
        area_points, area_intervals = _interval(areas, iqm_mean, reps, 1)
        improvement: tuple[dict[str, Any], dict[str, Any]] = ({}, {})
        if reference in scores:
            pairs = {
                name: (scores[reference], other)
                for name, other in scores.items()
                if name != reference and other.shape == scores[reference].shape
            }
            if pairs:
                improvement = _interval(pairs, metrics.probability_of_improvement, reps, 2)
        for name in scores:
            row: dict[str, Any] = {
                "env": env,
                "config": name,
                "n_runs": scores[name].shape[0],
                "final_iqm": final_points[name][0],
                "final_iqm_ci_low": final_intervals[name][0, 0],
                "final_iqm_ci_high": final_intervals[name][1, 0],
                "final_mean": final_points[name][1],
                "final_std": float(scores[name].std(ddof=1)) if scores[name].shape[0] > 1 else np.nan,
                "auc_iqm": area_points[name][0],
                "auc_iqm_ci_low": area_intervals[name][0, 0],
                "auc_iqm_ci_high": area_intervals[name][1, 0],
                "auc_mean": area_points[name][1],
            }
            if episodes is not None and "wall_time_s" in episodes.columns:
                runs = episodes[(episodes["env"] == env) & (episodes["algo"] == name)]
                row["run_time_s_median"] = float(runs.groupby("seed")["wall_time_s"].max().median())
            if name in improvement[0]:
                row["p_improvement_of_adc"] = float(np.asarray(improvement[0][name]).reshape(-1)[0])
                low, high = np.asarray(improvement[1][name]).reshape(2, -1)[:, 0]
                row["p_improvement_ci_low"], row["p_improvement_ci_high"] = float(low), float(high)
            rows.append(row)
    return pd.DataFrame(rows)


def display_columns(reference: str) -> list[str]:
    """Columns of the formatted summary (``summary.md`` and ``summary_table.csv``, which the docs include)."""
    return [
        "env",
        "configuration",
        "runs",
        "final IQM [95% CI]",
        "final mean",
        "across-seed std",
        "AUC IQM [95% CI]",
        f"P({reference} > configuration) [95% CI]",
    ]


def display_table(table: pd.DataFrame, reference: str) -> pd.DataFrame:
    """The summary with rounded numbers and CIs in brackets, one string per cell."""
    rows = []
    for row in table.itertuples():
        improvement = "—"
        if not pd.isna(getattr(row, "p_improvement_of_adc", np.nan)):
            improvement = f"{row.p_improvement_of_adc:.2f} [{row.p_improvement_ci_low:.2f}, {row.p_improvement_ci_high:.2f}]"
        rows.append(
            [
                row.env,
                row.config,
                str(row.n_runs),
                f"{row.final_iqm:.1f} [{row.final_iqm_ci_low:.1f}, {row.final_iqm_ci_high:.1f}]",
                f"{row.final_mean:.1f}",
                f"{row.final_std:.1f}",
                f"{row.auc_iqm:.1f} [{row.auc_iqm_ci_low:.1f}, {row.auc_iqm_ci_high:.1f}]",
                improvement,
            ]
        )
    return pd.DataFrame(rows, columns=display_columns(reference))


def markdown(table: pd.DataFrame, reference: str) -> str:
    display = display_table(table, reference)
    lines = ["| " + " | ".join(display_columns(reference)) + " |", "|---|---|---:|---|---:|---:|---|---|"]
    lines += ["| " + " | ".join(row) + " |" for row in display.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def threshold_markdown(converged: pd.DataFrame, threshold: float) -> str:
    """Per configuration: runs that stay above ``threshold`` by the end, and the median episodes until they do
    (a run that never does counts as beyond its budget, so the median is a lower bound when it is one of them)."""
    lines = [
        f"| env | configuration | runs at or above {threshold:g} by the end | median episodes until they stay there |",
        "|---|---|---:|---:|",
    ]
    for (env, name), group in converged.groupby(["env", "algo"], sort=False):
        episodes = group["episodes"].fillna(np.inf).to_numpy(np.float64)
        median = float(np.median(episodes))
        budget = int(group["budget_episodes"].max())
        shown = f"> {budget}" if np.isinf(median) else f"{median:.0f}"
        lines.append(f"| {env} | {name} | {int(group['reached'].sum())} of {len(group)} | {shown} |")
    return "\n".join(lines) + "\n"


def _hyperparams_origin(folder: Path | None) -> str:
    return "shipped" if folder is None else str(folder.relative_to(ROOT.parent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--grid", choices=sorted(GRIDS), default="evidence")
    parser.add_argument("--configs", nargs="+", choices=sorted(CONFIGS), help="configurations (default: the grid's)")
    parser.add_argument("--envs", nargs="+", help="environments (default: the grid's)")
    parser.add_argument(
        "-n", "--n-timesteps", type=int, help=f"budget of every run (default: the grid's, else {DEFAULT_BUDGET})"
    )
    parser.add_argument("--workers", type=int, default=1, help="parallel runs")
    parser.add_argument("--reps", type=int, default=5000, help="bootstrap replications")
    parser.add_argument(
        "--reference", choices=sorted(CONFIGS), help="configuration whose improvement is measured (default: the grid's)"
    )
    parser.add_argument("--quick", action="store_true", help="smoke run: 2 seeds, 600 steps, results in *_quick")
    args = parser.parse_args()
    th.set_num_threads(1)
    envs, seeds, default_configs = GRIDS[args.grid]
    envs = args.envs or envs
    configs = args.configs or default_configs
    if args.n_timesteps is None:
        args.n_timesteps = BUDGETS.get(args.grid, DEFAULT_BUDGET)
    name = args.grid + ("_quick" if args.quick else "")
    if args.quick:
        seeds, args.n_timesteps, args.reps = seeds[:2], 600, 200
    folder = RUNS_DIR / (SHARED_RUNS.get(args.grid, args.grid) + ("_quick" if args.quick else ""))
    output = RESULTS_DIR / name
    output.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    tables = {config: run_config(config, envs, seeds, folder, args.n_timesteps, args.workers) for config in configs}
    elapsed = time.perf_counter() - start
    final, evaluations = merge(tables, FINAL_CSV), merge(tables, EVALUATIONS_CSV)
    final.to_csv(output / FINAL_CSV, index=False)
    evaluations.to_csv(output / EVALUATIONS_CSV, index=False)
    episodes = merge(tables, EPISODES_CSV)
    episodes.to_csv(output / EPISODES_CSV, index=False)
    reference = args.reference or REFERENCES[args.grid]
    table = summary(final, evaluations, args.reps, reference, episodes)
    table.to_csv(output / "summary.csv", index=False)
    (output / "summary.md").write_text(markdown(table, reference))
    display_table(table, reference).to_csv(output / "summary_table.csv", index=False)
    if args.grid in THRESHOLDS:
        threshold = THRESHOLDS[args.grid]
        converged = time_to_threshold(evaluations, episodes, threshold)
        converged.to_csv(output / "time_to_threshold.csv", index=False)
        (output / "time_to_threshold.md").write_text(threshold_markdown(converged, threshold))
    plots = plot_results(evaluations, str(output), final=final, episodes=episodes, reps=args.reps)
    if not args.quick:
        DOCS_STATIC.mkdir(parents=True, exist_ok=True)
        for figure in plots.figures:
            os.replace(figure, DOCS_STATIC / f"critic_study_{args.grid}_{Path(figure).name}")
    metadata_path = output / "metadata.json"
    previous = json.loads(metadata_path.read_text()) if metadata_path.is_file() else {}
    wall_times = dict(previous.get("wall_time_s_per_invocation", {}))
    wall_times[f"{len(wall_times)}: {' '.join(configs)}"] = round(elapsed, 1)
    metadata = {
        "grid": args.grid,
        "configs": {
            config: {
                "algo": CONFIGS[config][0],
                "overrides": CONFIGS[config][1],
                "hyperparams": _hyperparams_origin(CONFIGS[config][2]),
            }
            for config in tables
        },
        "reference": reference,
        "envs": envs,
        "seeds": seeds,
        "n_timesteps": args.n_timesteps,
        "eval": "20 evaluations of 5 deterministic episodes per run; final: 20 deterministic episodes",
        "wall_time_s_per_invocation": wall_times,
        "workers": args.workers,
        "bootstrap_reps": args.reps,
        **machine_metadata(),
    }
    metadata_path.write_text(json.dumps(metadata, indent=2) + "\n")
    budget = "each entry's n_timesteps" if args.n_timesteps is None else f"{args.n_timesteps} steps"
    print(f"\n{args.grid}: {len(seeds)} seeds x {len(configs)} configurations, {budget} per run")
    print(markdown(table, reference))


if __name__ == "__main__":
    run_script(main)
