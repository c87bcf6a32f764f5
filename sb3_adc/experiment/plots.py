"""Figures and tables of benchmark results (:mod:`~sb3_adc.experiment.statistics`; ``experiment`` extra)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("experiment", "the benchmark figures"):
    import pandas as pd
    from matplotlib import colormaps
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from rliable import plot_utils

    from sb3_adc.experiment import statistics as stats

#: Algorithm id (``--algo``) -> the name the figures give it, as the paper's text does.
ALGO_DISPLAY_NAMES: dict[str, str] = dict(
    adc="ADC", ddpg="DDPG", td3="TD3", sac="SAC", vanilla_ac="vanilla actor-critic", dqn="dueling DQN, 25 actions"
)

#: Legend of the final-performance figure: the marker of each statistic.
_METRIC_MARKERS = [
    Line2D([], [], marker=m, color="black", linestyle="none", label=name) for m, name in (("o", "IQM"), ("s", "mean"))
]
#: The unit of a variance of returns.
VARIANCE_LABEL = "variance across runs (return²)"
#: Size of one panel (inches).
PANEL_WIDTH, PANEL_HEIGHT = 6.4, 4.0
#: Font sizes of rliable's figures.
_RLIABLE_FONTS: dict[str, Any] = {"labelsize": "medium", "ticklabelsize": "small"}


@dataclass
class PlotOutputs:
    """
    The files written by :func:`plot_results`.

    :param figures: PNG files
    :param tables: CSV and Markdown files
    """

    figures: list[str] = field(default_factory=list)
    tables: list[str] = field(default_factory=list)


def display_name(algo: str) -> str:
    """
    The name of an algorithm in figures: :data:`ALGO_DISPLAY_NAMES`, else the id itself.

    :param algo: The algorithm id
    """
    return ALGO_DISPLAY_NAMES.get(str(algo), str(algo))


def algo_colors(algos: list[str]) -> dict[str, tuple[float, float, float, float]]:
    """
    One color per algorithm, from the sorted names: the same for an algorithm in every figure of the same set.

    :param algos: The algorithms of the figure
    """
    cmap = colormaps["tab10"]
    return {str(algo): cmap(index % 10) for index, algo in enumerate(sorted(algos))}


def _save(figure: Figure, path: str, title: str, unused: Sequence[Axes] = ()) -> str:
    """Hide the ``unused`` panels, title the figure and write it to ``path``; return ``path``."""
    for ax in unused:
        ax.set_visible(False)
    figure.suptitle(title, fontsize="medium")
    figure.savefig(path, dpi=120)
    return path


def _per_env(table: pd.DataFrame, path: str, title: str, draw: Callable[[Axes, str, pd.DataFrame, dict], None]) -> str:
    """One panel per environment of ``table``, three to a row, drawn by ``draw(ax, env, its rows, algo_colors)``."""
    envs = sorted(table["env"].unique())
    colors = algo_colors(list(table["algo"].unique()))
    columns = min(len(envs), 3)
    figure = Figure(figsize=(PANEL_WIDTH * columns, PANEL_HEIGHT * math.ceil(len(envs) / columns)), layout="constrained")
    axes = list(figure.subplots(math.ceil(len(envs) / columns), columns, squeeze=False).flat)
    for ax, env in zip(axes, envs, strict=False):
        draw(ax, env, table[table["env"] == env], colors)
    return _save(figure, path, title, axes[len(envs) :])


def _label(algo: Any, rows: pd.DataFrame) -> str:
    """An algorithm's name in a legend, with its number of runs."""
    return f"{display_name(str(algo))} ({int(rows['n_runs'].iloc[0])} runs)"


def _curve(ax: Axes, table: pd.DataFrame, x: str, y: str, color: Any, label: str, band: bool = True) -> None:
    """Column ``y`` of ``table`` against column ``x`` and, with ``band``, its CI (``{y}_ci_low`` to ``{y}_ci_high``)."""
    ax.plot(table[x], table[y], color=color, label=label)
    if band:
        ax.fill_between(table[x], table[f"{y}_ci_low"], table[f"{y}_ci_high"], color=color, alpha=0.2)


def _decorate(ax: Axes, title: str, xlabel: str, ylabel: str) -> None:
    """Title and label a panel, with a light grid and a legend."""
    ax.set(title=title, xlabel=xlabel, ylabel=ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")


def _prepare(table: pd.DataFrame, output_dir: str, empty: str) -> tuple[PlotOutputs, Callable[..., str]]:
    """Refuse an empty ``table`` (ValueError: ``empty``), create ``output_dir``: the outputs, and a name's path in it."""
    if table.empty:
        raise ValueError(empty)
    os.makedirs(output_dir, exist_ok=True)
    return PlotOutputs(), partial(os.path.join, output_dir)


def _write_table(outputs: PlotOutputs, table: pd.DataFrame, path: str) -> None:
    """Write ``table`` to the CSV file ``path``, listed in ``outputs``."""
    table.to_csv(path, index=False)
    outputs.tables.append(path)


def _plot_mean_curves(curves: pd.DataFrame, path: str, x: str, xlabel: str, ylabel: str, title: str) -> str:
    """One panel per environment: the mean across runs against column ``x``, with its 95% CI, per algorithm."""

    def draw(ax: Axes, env: str, table: pd.DataFrame, colors: dict) -> None:
        for algo, group in table.groupby("algo", sort=True):
            _curve(ax, group, x, "mean", colors[str(algo)], _label(algo, group))
        _decorate(ax, env, xlabel, ylabel)

    return _per_env(curves, path, title, draw)


def plot_learning_curves(curves: pd.DataFrame, path: str, title: str = "", ylabel: str = "evaluation return") -> str:
    """
    One panel per environment: mean evaluation return across runs, with its 95% bootstrap CI, per algorithm.

    :param curves: The output of :func:`~sb3_adc.experiment.statistics.learning_curves`
    :param path: The PNG file
    :param title: The figure's title
    :param ylabel: What the curves' ``mean_return`` holds (a success rate, for instance), with its unit
    """
    title = title or "Mean evaluation return across runs (95% bootstrap CI)"
    return _plot_mean_curves(curves, path, "timesteps", "timesteps", ylabel, title)


def plot_wallclock_curves(curves: pd.DataFrame, path: str) -> str:
    """
    One panel per environment: the learning curves of :func:`plot_learning_curves` against the seconds of training.

    :param curves: The output of :func:`~sb3_adc.experiment.statistics.wallclock_curves`
    :param path: The PNG file
    """
    title = "Mean evaluation return against wall-clock time (95% bootstrap CI)"
    xlabel = "wall-clock time of training (s)"
    return _plot_mean_curves(curves, path, "wall_time_s", xlabel, "latest evaluation return", title)


def plot_reward_variance(curves: pd.DataFrame, episodes: pd.DataFrame | None, path: str, window: int = 10) -> str:
    """
    Across-run variance of the evaluation returns (95% CI) and training-episode returns (the paper's Figures 5, 8).

    :param curves: The output of :func:`~sb3_adc.experiment.statistics.learning_curves`
    :param episodes: The training episodes (``episodes.csv``), or ``None``
    :param path: The PNG file
    :param window: Episodes of the moving average
    """
    envs = sorted(curves["env"].unique())
    colors = algo_colors(list(curves["algo"].unique()))
    per_episode = stats.episode_variance(episodes, window) if episodes is not None and not episodes.empty else None
    rows = 2 if per_episode is not None and not per_episode.empty else 1
    figure = Figure(figsize=(PANEL_WIDTH * len(envs), PANEL_HEIGHT * rows), layout="constrained")
    axes = figure.subplots(rows, len(envs), squeeze=False)
    for column, env in enumerate(envs):
        for algo, group in curves[curves["env"] == env].groupby("algo", sort=True):
            if not group["variance"].isna().all():
                _curve(axes[0, column], group, "timesteps", "variance", colors[str(algo)], display_name(str(algo)))
        _decorate(axes[0, column], f"{env}: evaluation returns", "timesteps", VARIANCE_LABEL)
        if per_episode is not None and rows == 2:
            for algo, group in per_episode[per_episode["env"] == env].groupby("algo", sort=True):
                color = colors.get(str(algo), "k")
                _curve(axes[1, column], group, "episode", "variance_smoothed", color, display_name(str(algo)), band=False)
            xlabel = f"episode ({window}-episode moving average)"
            _decorate(axes[1, column], f"{env}: training episodes", xlabel, VARIANCE_LABEL)
    return _save(figure, path, "Across-run variance of the rewards (as the ADC paper's Figures 5 and 8)")


def plot_final_performance(performance: pd.DataFrame, path: str, quantity: str = "final return") -> str:
    """
    One panel per environment: IQM and mean of the final returns per algorithm, with 95% CIs, on one x range.

    :param performance: The output of :func:`~sb3_adc.experiment.statistics.final_performance`
    :param path: The PNG file
    :param quantity: What the values are, for the axis labels and the title (e.g. ``"success rate"``)
    """
    # One x range for every panel: the span of all intervals, with a margin.
    lowest = float(np.nanmin(performance[["iqm_ci_low", "mean_ci_low"]].to_numpy(dtype=np.float64)))
    highest = float(np.nanmax(performance[["iqm_ci_high", "mean_ci_high"]].to_numpy(dtype=np.float64)))
    pad = 0.05 * (highest - lowest) if highest > lowest else max(1.0, abs(highest) * 0.05)

    def draw(ax: Axes, env: str, table: pd.DataFrame, colors: dict) -> None:
        table = table.sort_values("algo")
        positions = np.arange(len(table))
        for offset, metric, marker in ((-0.15, "iqm", "o"), (0.15, "mean", "s")):
            bounds = table[["algo", metric, f"{metric}_ci_low", f"{metric}_ci_high"]].itertuples(index=False)
            for position, (algo, value, low, high) in zip(positions, bounds, strict=True):
                error = [[value - low], [high - value]]
                ax.errorbar(value, position + offset, xerr=error, fmt=marker, color=colors[algo], capsize=3)
        ax.set_yticks(positions, [display_name(algo) for algo in table["algo"]])
        ax.set(title=env, xlabel=f"{quantity} (95% CI)", xlim=(lowest - pad, highest + pad))
        ax.grid(alpha=0.3, axis="x")
        ax.legend(handles=_METRIC_MARKERS, fontsize="small")

    return _per_env(performance, path, f"{quantity.capitalize()}: IQM (o) and mean (s), 95% stratified-bootstrap CIs", draw)


def plot_performance_profiles(profiles: pd.DataFrame, path: str) -> str:
    """
    One panel per environment: rliable's performance profile of each algorithm, with its 95% CI band.

    :param profiles: The output of :func:`~sb3_adc.experiment.statistics.performance_profiles`
    :param path: The PNG file
    """

    labels = dict(xlabel=r"final return $\tau$", ylabel=r"fraction of runs with return $> \tau$", **_RLIABLE_FONTS)

    def draw(ax: Axes, env: str, table: pd.DataFrame, colors: dict) -> None:
        groups = {_label(algo, rows): (str(algo), rows) for algo, rows in table.groupby("algo", sort=True)}
        fractions = {name: rows["fraction"].to_numpy() for name, (_, rows) in groups.items()}
        cis = {name: rows[["fraction_ci_low", "fraction_ci_high"]].to_numpy().T for name, (_, rows) in groups.items()}
        taus = next(iter(groups.values()))[1]["tau"].to_numpy()
        hues = {name: colors[algo] for name, (algo, _) in groups.items()}
        plot_utils.plot_performance_profiles(
            fractions, taus, performance_profile_cis=cis, ax=ax, colors=hues, legend=True, legendsize="small", **labels
        )
        ax.set_title(env)

    return _per_env(profiles, path, "Performance profiles of the final returns (95% stratified-bootstrap CIs)", draw)


def plot_probability_of_improvement(improvement: pd.DataFrame, path: str) -> str:
    """
    rliable's probability-of-improvement figure: P(X > Y) for each pair of algorithms, with its 95% CI.

    :param improvement: The output of :func:`~sb3_adc.experiment.statistics.probability_of_improvement`
    :param path: The PNG file
    """
    colors = algo_colors(sorted(set(improvement["algo_x"]) | set(improvement["algo_y"])))
    figure = Figure(figsize=(PANEL_WIDTH, 1.6 + 0.5 * max(len(improvement), 1)), layout="constrained")
    ax = figure.subplots()
    pairs = zip(improvement["algo_x"], improvement["algo_y"], strict=True)
    keys = [f"{display_name(x)}|{display_name(y)}" for x, y in pairs]
    points = dict(zip(keys, improvement["probability"], strict=True))
    intervals = dict(zip(keys, improvement[["ci_low", "ci_high"]].to_numpy(), strict=True))
    xlabel = "P(X > Y): probability that a run of X (left) ends above a run of Y (right)"
    style = dict(xticks=[0.0, 0.25, 0.5, 0.75, 1.0], xlabel=xlabel, left_ylabel="", right_ylabel="", **_RLIABLE_FONTS)
    colored = [colors[algo] for algo in improvement["algo_x"]]
    plot_utils.plot_probability_of_improvement(points, intervals, pair_separator="|", ax=ax, colors=colored, **style)
    ax.axvline(0.5, color="grey", linestyle="--", linewidth=1)
    # A point estimate with a zero-width interval (P = 0 or 1 with few runs) stays visible.
    ax.plot(list(points.values()), range(len(points)), "o", color="black", markersize=4, clip_on=False)
    ax.set_xlim(0.0, 1.0)
    n_envs = sorted(set(improvement["n_envs"]))
    over = f"over {' or '.join(map(str, n_envs))} environment{'' if n_envs == [1] else 's'}"
    return _save(figure, path, f"Probability of improvement of the final returns, {over} (95% CIs)")


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
    Write the figures and tables of a benchmark: ``learning_curves.png``, ``reward_variance.png``,
    ``final_performance.png``, ``curves.csv``, ``final_performance.csv`` and ``.md``, ``episode_variance.csv`` with
    episodes, and ``wallclock_curves.png`` and ``.csv`` when the episodes hold their wall-clock times.

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param output_dir: Where to write
    :param final: Final evaluations (``final.csv``); ``None``: the last evaluation of each run
    :param episodes: Training episodes (``episodes.csv``) for the per-episode variance; ``None``: skipped
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :param window: Episodes of the moving average of the per-episode variance
    """
    outputs, out = _prepare(evaluations, output_dir, "no evaluations to plot (is the evaluation CSV empty?).")
    curves = stats.learning_curves(evaluations, reps=reps, seed=seed)
    _write_table(outputs, curves, out("curves.csv"))
    finals = final if final is not None and not final.empty else stats.last_evaluations(evaluations)
    performance = stats.final_performance(finals, reps=reps, seed=seed)
    _write_table(outputs, performance, out("final_performance.csv"))
    Path(out("final_performance.md")).write_text(stats.markdown_table(performance), encoding="utf-8")
    outputs.tables.append(out("final_performance.md"))
    if episodes is not None and not episodes.empty:
        _write_table(outputs, stats.episode_variance(episodes, window), out("episode_variance.csv"))
    outputs.figures.append(plot_learning_curves(curves, out("learning_curves.png")))
    outputs.figures.append(plot_reward_variance(curves, episodes, out("reward_variance.png"), window))
    outputs.figures.append(plot_final_performance(performance, out("final_performance.png")))
    # Tables of older runs have no wall_time_s.
    if episodes is not None and "wall_time_s" in episodes.columns and episodes["wall_time_s"].notna().any():
        timed = stats.wallclock_curves(evaluations, episodes, reps=reps, seed=seed)
        if not timed.empty:
            _write_table(outputs, timed, out("wallclock_curves.csv"))
            outputs.figures.append(plot_wallclock_curves(timed, out("wallclock_curves.png")))
    return outputs


def plot_comparisons(final: pd.DataFrame, output_dir: str, reps: int = 2000, seed: int = 0) -> PlotOutputs:
    """
    Write ``performance_profiles.{png,csv}`` and, with two algorithms or more, ``probability_of_improvement.{png,csv}``.

    :param final: One row per run, with columns ``env``, ``algo``, ``seed`` and ``mean_return`` (``final.csv``)
    :param output_dir: Where to write
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    """
    outputs, out = _prepare(final, output_dir, "no final returns to compare (is the final CSV empty?).")
    profiles = stats.performance_profiles(final, reps=reps, seed=seed)
    _write_table(outputs, profiles, out("performance_profiles.csv"))
    outputs.figures.append(plot_performance_profiles(profiles, out("performance_profiles.png")))
    improvement = stats.probability_of_improvement(final, reps=reps, seed=seed)
    if not improvement.empty:
        _write_table(outputs, improvement, out("probability_of_improvement.csv"))
        outputs.figures.append(plot_probability_of_improvement(improvement, out("probability_of_improvement.png")))
    return outputs
