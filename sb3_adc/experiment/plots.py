"""
Figures and tables of benchmark results: learning curves with 95% bootstrap CIs, across-run reward-variance
curves (the ADC paper's Figures 5 and 8), final performance (IQM and mean with 95% stratified-bootstrap CIs),
rliable's performance profiles and probability of improvement.

Needs the ``experiment`` extra (matplotlib, pandas, rliable).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("experiment", "the benchmark figures"):
    import pandas as pd
    from matplotlib import colormaps
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from rliable import plot_utils

    from sb3_adc.experiment.statistics import (
        episode_variance,
        final_performance,
        has_wall_times,
        last_evaluations,
        learning_curves,
        markdown_table,
        performance_profiles,
        probability_of_improvement,
        wallclock_curves,
    )

#: Algorithm id (``--algo``) -> the name the figures give it, as the paper's text does.
ALGO_DISPLAY_NAMES: dict[str, str] = {
    "adc": "ADC",
    "ddpg": "DDPG",
    "td3": "TD3",
    "sac": "SAC",
    "vanilla_ac": "vanilla actor-critic",
    "dqn": "dueling DQN, 25 actions",
}

#: Legend of the final-performance figure: the marker of each statistic.
_METRIC_MARKERS = [
    Line2D([], [], marker="o", color="black", linestyle="none", label="IQM"),
    Line2D([], [], marker="s", color="black", linestyle="none", label="mean"),
]
#: The unit of a variance of returns.
VARIANCE_LABEL = "variance across runs (return²)"
#: Size of one panel (inches).
PANEL_WIDTH, PANEL_HEIGHT = 6.4, 4.0
#: Font sizes of rliable's figures.
_RLIABLE_FONTS = {"labelsize": "medium", "ticklabelsize": "small"}


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

    :param algo: The algorithm id (``adc``, ``dqn``, ...)
    """
    return ALGO_DISPLAY_NAMES.get(str(algo), str(algo))


def algo_colors(algos: list[str]) -> dict[str, tuple[float, float, float, float]]:
    """
    One color per algorithm, from the sorted names: the same for an algorithm in every figure of the same set.

    :param algos: The algorithms of the figure
    """
    cmap = colormaps["tab10"]
    return {str(algo): cmap(index % 10) for index, algo in enumerate(sorted(algos))}


def _shared_limits(low: np.ndarray, high: np.ndarray, margin: float = 0.05) -> tuple[float, float]:
    """One axis range for every panel of a figure: the span of all intervals, with a margin."""
    lowest, highest = float(np.nanmin(low)), float(np.nanmax(high))
    pad = margin * (highest - lowest) if highest > lowest else max(1.0, abs(highest) * margin)
    return lowest - pad, highest + pad


def _grid(n_panels: int) -> tuple[Figure, list[Axes]]:
    """A figure of ``n_panels`` panels, three to a row."""
    columns = min(n_panels, 3)
    figure = Figure(figsize=(PANEL_WIDTH * columns, PANEL_HEIGHT * math.ceil(n_panels / columns)), layout="constrained")
    return figure, list(figure.subplots(math.ceil(n_panels / columns), columns, squeeze=False).flat)


def _save(figure: Figure, path: str, title: str, unused: Sequence[Axes] = ()) -> str:
    """Hide the ``unused`` panels, title the figure and write it to ``path``; return ``path``."""
    for ax in unused:
        ax.set_visible(False)
    figure.suptitle(title, fontsize="medium")
    figure.savefig(path, dpi=120)
    return path


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
    envs = sorted(curves["env"].unique())
    colors = algo_colors(list(curves["algo"].unique()))
    figure, axes = _grid(len(envs))
    for ax, env in zip(axes, envs, strict=False):
        for algo, group in curves[curves["env"] == env].groupby("algo", sort=True):
            color = colors[str(algo)]
            runs = int(group["n_runs"].iloc[0])
            ax.plot(group[x], group["mean"], color=color, label=f"{display_name(str(algo))} ({runs} runs)")
            ax.fill_between(group[x], group["mean_ci_low"], group["mean_ci_high"], color=color, alpha=0.2)
        _decorate(ax, env, xlabel, ylabel)
    return _save(figure, path, title, axes[len(envs) :])


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
    One panel per environment: the learning curves of :func:`plot_learning_curves` against the seconds of
    training (evaluations included) instead of timesteps, so that a slower algorithm pays for its speed.

    :param curves: The output of :func:`~sb3_adc.experiment.statistics.wallclock_curves`
    :param path: The PNG file
    """
    labels = ("wall-clock time of training (s)", "latest evaluation return")
    title = "Mean evaluation return against wall-clock time (95% bootstrap CI)"
    return _plot_mean_curves(curves, path, "wall_time_s", *labels, title)


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
    colors = algo_colors(list(curves["algo"].unique()))
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
            ax.plot(group["timesteps"], group["variance"], color=color, label=display_name(str(algo)))
            ax.fill_between(group["timesteps"], group["variance_ci_low"], group["variance_ci_high"], color=color, alpha=0.2)
        _decorate(ax, f"{env}: evaluation returns", "timesteps", VARIANCE_LABEL)
        if rows == 2:
            assert per_episode is not None
            ax = axes[1, column]
            for algo, group in per_episode[per_episode["env"] == env].groupby("algo", sort=True):
                label = display_name(str(algo))
                ax.plot(group["episode"], group["variance_smoothed"], color=colors.get(str(algo), "k"), label=label)
            _decorate(ax, f"{env}: training episodes", f"episode ({window}-episode moving average)", VARIANCE_LABEL)
    return _save(figure, path, "Across-run variance of the rewards (as the ADC paper's Figures 5 and 8)")


def plot_final_performance(performance: pd.DataFrame, path: str, quantity: str = "final return") -> str:
    """
    One panel per environment: IQM and mean of the final returns per algorithm, with 95% CIs, on one x range
    for all panels (so that panels compare at a glance).

    :param performance: The output of :func:`~sb3_adc.experiment.statistics.final_performance`
    :param path: The PNG file
    :param quantity: What the values are, for the axis labels and the title (e.g. ``"success rate"``)
    """
    envs = sorted(performance["env"].unique())
    colors = algo_colors(list(performance["algo"].unique()))
    limits = _shared_limits(
        performance[["iqm_ci_low", "mean_ci_low"]].to_numpy(dtype=np.float64),
        performance[["iqm_ci_high", "mean_ci_high"]].to_numpy(dtype=np.float64),
    )
    figure, axes = _grid(len(envs))
    for ax, env in zip(axes, envs, strict=False):
        table = performance[performance["env"] == env].sort_values("algo")
        positions = np.arange(len(table))
        for offset, metric, marker in ((-0.15, "iqm", "o"), (0.15, "mean", "s")):
            for position, row in zip(positions, table.itertuples(index=False), strict=True):
                value, low, high = getattr(row, metric), getattr(row, f"{metric}_ci_low"), getattr(row, f"{metric}_ci_high")
                xerr = [[value - low], [high - value]]
                ax.errorbar(value, position + offset, xerr=xerr, fmt=marker, color=colors[row.algo], capsize=3)
        ax.set_yticks(positions, [display_name(algo) for algo in table["algo"]])
        ax.set(title=env, xlabel=f"{quantity} (95% CI)", xlim=limits)
        ax.grid(alpha=0.3, axis="x")
        ax.legend(handles=_METRIC_MARKERS, fontsize="small")
    title = f"{quantity.capitalize()}: IQM (o) and mean (s), 95% stratified-bootstrap CIs"
    return _save(figure, path, title, axes[len(envs) :])


def plot_performance_profiles(profiles: pd.DataFrame, path: str) -> str:
    """
    One panel per environment: rliable's performance profile of each algorithm, the fraction of runs whose
    final return exceeds tau, with its 95% stratified-bootstrap CI band. A profile above another's is better
    over the whole range of returns, not just on average.

    :param profiles: The output of :func:`~sb3_adc.experiment.statistics.performance_profiles`
    :param path: The PNG file
    """
    envs = sorted(profiles["env"].unique())
    colors = algo_colors(list(profiles["algo"].unique()))
    figure, axes = _grid(len(envs))
    for ax, env in zip(axes, envs, strict=False):
        table = profiles[profiles["env"] == env]
        curves, bands, names = {}, {}, {}
        for algo, group in table.groupby("algo", sort=True):
            name = f"{display_name(str(algo))} ({int(group['n_runs'].iloc[0])} runs)"
            names[name] = colors[str(algo)]
            curves[name] = group["fraction"].to_numpy()
            bands[name] = group[["fraction_ci_low", "fraction_ci_high"]].to_numpy().T
        plot_utils.plot_performance_profiles(
            curves,
            table.groupby("algo", sort=True)["tau"].apply(np.asarray).iloc[0],
            performance_profile_cis=bands,
            ax=ax,
            colors=names,
            xlabel=r"final return $\tau$",
            ylabel=r"fraction of runs with return $> \tau$",
            **_RLIABLE_FONTS,
            legend=True,
            legendsize="small",
        )
        ax.set_title(env)
    return _save(figure, path, "Performance profiles of the final returns (95% stratified-bootstrap CIs)", axes[len(envs) :])


def plot_probability_of_improvement(improvement: pd.DataFrame, path: str) -> str:
    """
    rliable's probability-of-improvement figure: for each pair of algorithms, P(X > Y) that a run of X ends
    with a higher return than a run of Y (averaged over the environments both ran), with its 95% CI. Above 0.5,
    X tends to do better; a CI that contains 0.5 shows no clear difference.

    :param improvement: The output of :func:`~sb3_adc.experiment.statistics.probability_of_improvement`
    :param path: The PNG file
    """
    algos = sorted(set(improvement["algo_x"]) | set(improvement["algo_y"]))
    colors = algo_colors(algos)
    n_pairs = max(len(improvement), 1)
    figure = Figure(figsize=(PANEL_WIDTH, 1.6 + 0.5 * n_pairs), layout="constrained")
    ax = figure.subplots()
    separator = "|"
    points, intervals = {}, {}
    for row in improvement.itertuples(index=False):
        key = f"{display_name(row.algo_x)}{separator}{display_name(row.algo_y)}"
        points[key] = row.probability
        intervals[key] = np.array([row.ci_low, row.ci_high])
    plot_utils.plot_probability_of_improvement(
        points,
        intervals,
        pair_separator=separator,
        ax=ax,
        colors=[colors[algo] for algo in improvement["algo_x"]],
        xticks=[0.0, 0.25, 0.5, 0.75, 1.0],
        xlabel="P(X > Y): probability that a run of X (left) ends above a run of Y (right)",
        left_ylabel="",
        right_ylabel="",
        **_RLIABLE_FONTS,
    )
    ax.axvline(0.5, color="grey", linestyle="--", linewidth=1)
    # A point estimate with a zero-width interval (P = 0 or 1 with few runs) stays visible.
    ax.plot(list(points.values()), range(len(points)), "o", color="black", markersize=4, clip_on=False)
    ax.set_xlim(0.0, 1.0)
    n_envs = sorted(set(improvement["n_envs"]))
    environments = "environment" if n_envs == [1] else "environments"
    over = f"over {' or '.join(map(str, n_envs))} {environments}"
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
    Write the figures and tables of a benchmark.

    Files: ``learning_curves.png``, ``reward_variance.png``, ``final_performance.png``, ``curves.csv``
    (mean, IQM and variance across runs at each timestep, with CIs), ``final_performance.csv`` and
    ``final_performance.md`` (IQM and mean with 95% CIs), ``episode_variance.csv`` when episodes are given, and
    ``wallclock_curves.png`` and ``.csv`` when they hold their wall-clock times.
    :func:`plot_comparisons` adds rliable's performance profiles and probability of improvement.

    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param output_dir: Where to write
    :param final: Final evaluations (``final.csv``); ``None``: the last evaluation of each run
    :param episodes: Training episodes (``episodes.csv``) for the per-episode variance; ``None``: skipped
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    :param window: Episodes of the moving average of the per-episode variance
    """
    outputs, out = _prepare(evaluations, output_dir, "no evaluations to plot (is the evaluation CSV empty?).")
    curves = learning_curves(evaluations, reps=reps, seed=seed)
    _write_table(outputs, curves, out("curves.csv"))
    finals = final if final is not None and not final.empty else last_evaluations(evaluations)
    performance = final_performance(finals, reps=reps, seed=seed)
    _write_table(outputs, performance, out("final_performance.csv"))
    with open(out("final_performance.md"), "w", encoding="utf-8") as stream:
        stream.write(markdown_table(performance))
    outputs.tables.append(out("final_performance.md"))
    if episodes is not None and not episodes.empty:
        _write_table(outputs, episode_variance(episodes, window), out("episode_variance.csv"))
    outputs.figures.append(plot_learning_curves(curves, out("learning_curves.png")))
    outputs.figures.append(plot_reward_variance(curves, episodes, out("reward_variance.png"), window))
    outputs.figures.append(plot_final_performance(performance, out("final_performance.png")))
    if has_wall_times(episodes):
        assert episodes is not None
        timed = wallclock_curves(evaluations, episodes, reps=reps, seed=seed)
        if not timed.empty:
            _write_table(outputs, timed, out("wallclock_curves.csv"))
            outputs.figures.append(plot_wallclock_curves(timed, out("wallclock_curves.png")))
    return outputs


def plot_comparisons(final: pd.DataFrame, output_dir: str, reps: int = 2000, seed: int = 0) -> PlotOutputs:
    """
    Write rliable's comparisons of the final returns: ``performance_profiles.png`` and ``.csv`` (the fraction of
    runs above each return, per environment) and, with two algorithms or more, ``probability_of_improvement.png``
    and ``.csv`` (P(X > Y) for each pair), all with 95% stratified-bootstrap CIs.

    :param final: One row per run, with columns ``env``, ``algo``, ``seed`` and ``mean_return`` (``final.csv``,
        or :func:`~sb3_adc.experiment.statistics.last_evaluations` of the evaluation curves)
    :param output_dir: Where to write
    :param reps: Bootstrap replications
    :param seed: Seed of the bootstrap
    """
    outputs, out = _prepare(final, output_dir, "no final returns to compare (is the final CSV empty?).")
    profiles = performance_profiles(final, reps=reps, seed=seed)
    _write_table(outputs, profiles, out("performance_profiles.csv"))
    outputs.figures.append(plot_performance_profiles(profiles, out("performance_profiles.png")))
    improvement = probability_of_improvement(final, reps=reps, seed=seed)
    if not improvement.empty:
        _write_table(outputs, improvement, out("probability_of_improvement.csv"))
        outputs.figures.append(plot_probability_of_improvement(improvement, out("probability_of_improvement.png")))
    return outputs
