"""
Figures and tables of benchmark results: learning curves with 95% bootstrap CIs, across-run reward-variance
curves (the ADC paper's Figures 5 and 8) and final performance (IQM and mean with 95% stratified-bootstrap CIs).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from sb3_adc.experiment.statistics import (
    episode_variance,
    final_performance,
    last_evaluations,
    learning_curves,
    markdown_table,
)

#: Legend of the final-performance figure: the marker of each statistic.
_METRIC_MARKERS = [
    Line2D([], [], marker="o", color="black", linestyle="none", label="IQM"),
    Line2D([], [], marker="s", color="black", linestyle="none", label="mean"),
]
#: Size of one panel (inches).
PANEL_WIDTH, PANEL_HEIGHT = 6.4, 4.0


@dataclass
class PlotOutputs:
    """
    The files written by :func:`plot_results`.

    :param figures: PNG files
    :param tables: CSV and Markdown files
    """

    figures: list[str] = field(default_factory=list)
    tables: list[str] = field(default_factory=list)


def _colors(algos: list[str]) -> dict[str, tuple[float, float, float, float]]:
    """The same color for an algorithm in every figure."""
    cmap = colormaps["tab10"]
    return {str(algo): cmap(index % 10) for index, algo in enumerate(sorted(algos))}


def _grid(n_panels: int, rows_per_panel: int = 1) -> tuple[Figure, list[Axes]]:
    columns = min(n_panels, 3)
    rows = math.ceil(n_panels / columns) * rows_per_panel
    figure = Figure(figsize=(PANEL_WIDTH * columns, PANEL_HEIGHT * rows), layout="constrained")
    axes = figure.subplots(rows, columns, squeeze=False)
    return figure, list(axes.flat)


def plot_learning_curves(curves: pd.DataFrame, path: str, title: str = "") -> str:
    """
    One panel per environment: mean evaluation return across runs, with its 95% bootstrap CI, per algorithm.

    :param curves: The output of :func:`~sb3_adc.experiment.statistics.learning_curves`
    :param path: The PNG file
    :param title: The figure's title
    """
    envs = sorted(curves["env"].unique())
    colors = _colors(list(curves["algo"].unique()))
    figure, axes = _grid(len(envs))
    for ax, env in zip(axes, envs, strict=False):
        for algo, group in curves[curves["env"] == env].groupby("algo", sort=True):
            color = colors[str(algo)]
            runs = int(group["n_runs"].iloc[0])
            ax.plot(group["timesteps"], group["mean"], color=color, label=f"{algo} ({runs} runs)")
            ax.fill_between(group["timesteps"], group["mean_ci_low"], group["mean_ci_high"], color=color, alpha=0.2)
        ax.set(title=env, xlabel="timesteps", ylabel="evaluation return")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small")
    for ax in axes[len(envs) :]:
        ax.set_visible(False)
    figure.suptitle(title or "Mean evaluation return across runs (95% bootstrap CI)", fontsize="medium")
    figure.savefig(path, dpi=120)
    return path


def plot_reward_variance(curves: pd.DataFrame, episodes: pd.DataFrame | None, path: str, window: int = 10) -> str:
    """
    Across-run variance of the rewards, per environment: of the evaluation returns at each evaluation (with its
    95% bootstrap CI) and, when training episodes are given, of the training-episode returns at each episode
    (moving average over ``window`` episodes; the x axis of the paper's Figures 5 and 8).

    :param curves: The output of :func:`~sb3_adc.experiment.statistics.learning_curves`
    :param episodes: The training episodes (``episodes.csv``), or ``None``
    :param path: The PNG file
    :param window: Episodes of the moving average
    """
    envs = sorted(curves["env"].unique())
    colors = _colors(list(curves["algo"].unique()))
    per_episode = episode_variance(episodes, window) if episodes is not None and not episodes.empty else None
    rows = 2 if per_episode is not None and not per_episode.empty else 1
    figure = Figure(figsize=(PANEL_WIDTH * len(envs), PANEL_HEIGHT * rows), layout="constrained")
    axes = figure.subplots(rows, len(envs), squeeze=False)
    for column, env in enumerate(envs):
        ax = axes[0, column]
        for algo, group in curves[curves["env"] == env].groupby("algo", sort=True):
            if group["variance"].isna().all():
                continue
            color = colors[str(algo)]
            ax.plot(group["timesteps"], group["variance"], color=color, label=str(algo))
            ax.fill_between(group["timesteps"], group["variance_ci_low"], group["variance_ci_high"], color=color, alpha=0.2)
        ax.set(title=f"{env}: evaluation returns", xlabel="timesteps", ylabel="variance across runs")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small")
        if rows == 2:
            assert per_episode is not None
            ax = axes[1, column]
            for algo, group in per_episode[per_episode["env"] == env].groupby("algo", sort=True):
                ax.plot(group["episode"], group["variance_smoothed"], color=colors.get(str(algo), "k"), label=str(algo))
            ax.set(
                title=f"{env}: training episodes",
                xlabel=f"episode ({window}-episode moving average)",
                ylabel="variance across runs",
            )
            ax.grid(alpha=0.3)
            ax.legend(fontsize="small")
    figure.suptitle("Across-run variance of the rewards (as the ADC paper's Figures 5 and 8)", fontsize="medium")
    figure.savefig(path, dpi=120)
    return path


def plot_final_performance(performance: pd.DataFrame, path: str) -> str:
    """
    One panel per environment: IQM and mean of the final returns per algorithm, with 95% CIs.

    :param performance: The output of :func:`~sb3_adc.experiment.statistics.final_performance`
    :param path: The PNG file
    """
    envs = sorted(performance["env"].unique())
    colors = _colors(list(performance["algo"].unique()))
    figure, axes = _grid(len(envs))
    for ax, env in zip(axes, envs, strict=False):
        table = performance[performance["env"] == env].sort_values("algo")
        positions = np.arange(len(table))
        for offset, metric, marker in ((-0.15, "iqm", "o"), (0.15, "mean", "s")):
            for position, row in zip(positions, table.itertuples(index=False), strict=True):
                value, low, high = getattr(row, metric), getattr(row, f"{metric}_ci_low"), getattr(row, f"{metric}_ci_high")
                ax.errorbar(
                    value,
                    position + offset,
                    xerr=[[value - low], [high - value]],
                    fmt=marker,
                    color=colors[row.algo],
                    capsize=3,
                )
        ax.set_yticks(positions, list(table["algo"]))
        ax.set(title=env, xlabel="final return (95% CI)")
        ax.grid(alpha=0.3, axis="x")
        ax.legend(handles=_METRIC_MARKERS, fontsize="small")
    for ax in axes[len(envs) :]:
        ax.set_visible(False)
    figure.suptitle("Final return: IQM (o) and mean (s), 95% stratified-bootstrap CIs", fontsize="medium")
    figure.savefig(path, dpi=120)
    return path


def plot_results(
    evaluations: pd.DataFrame,
    output_dir: str,
    final: pd.DataFrame | None = None,
    episodes: pd.DataFrame | None = None,
    reps: int = 2000,
    seed: int = 0,
    window: int = 10,
) -> PlotOutputs:
    """
    Write the figures and tables of a benchmark.

    Files: ``learning_curves.png``, ``reward_variance.png``, ``final_performance.png``, ``curves.csv``
    (mean, IQM and variance across runs at each timestep, with CIs), ``final_performance.csv`` and
    ``final_performance.md`` (IQM and mean with 95% CIs), and ``episode_variance.csv`` when episodes are given.

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param output_dir: Where to write
    :param final: Final evaluations (``final.csv``); ``None``: the last evaluation of each run
    :param episodes: Training episodes (``episodes.csv``) for the per-episode variance; ``None``: skipped
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :param window: Episodes of the moving average of the per-episode variance
    """
    if evaluations.empty:
        raise ValueError("no evaluations to plot (is the evaluation CSV empty?).")
    os.makedirs(output_dir, exist_ok=True)
    outputs = PlotOutputs()

    def out(name: str) -> str:
        return os.path.join(output_dir, name)

    curves = learning_curves(evaluations, reps=reps, seed=seed)
    curves.to_csv(out("curves.csv"), index=False)
    outputs.tables.append(out("curves.csv"))
    finals = final if final is not None and not final.empty else last_evaluations(evaluations)
    performance = final_performance(finals, reps=reps, seed=seed)
    performance.to_csv(out("final_performance.csv"), index=False)
    with open(out("final_performance.md"), "w", encoding="utf-8") as stream:
        stream.write(markdown_table(performance))
    outputs.tables += [out("final_performance.csv"), out("final_performance.md")]
    if episodes is not None and not episodes.empty:
        episode_variance(episodes, window).to_csv(out("episode_variance.csv"), index=False)
        outputs.tables.append(out("episode_variance.csv"))
    outputs.figures.append(plot_learning_curves(curves, out("learning_curves.png")))
    outputs.figures.append(plot_reward_variance(curves, episodes, out("reward_variance.png"), window))
    outputs.figures.append(plot_final_performance(performance, out("final_performance.png")))
    return outputs
