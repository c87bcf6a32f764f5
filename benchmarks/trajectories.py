"""
The paths driven on the lidar courses, drawn for the benchmark reports (``procedural_generalisation.py``).

Needs the ``experiment`` extra (matplotlib, pandas).
"""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from sb3_adc.experiment.plots import ALGO_DISPLAY_NAMES, display_name, draw_course
from sb3_adc_envs.lidar_course import Course


def plot_trajectories(trajectories: pd.DataFrame, courses: Mapping[str, Course], path: str, title: str = "") -> str:
    """
    One row per algorithm, one panel per course: the course and the path of every run on it, blue when the
    episode ended without a collision, red with a cross where it crashed.

    :param trajectories: One row per position: ``algo``, ``seed``, ``course``, ``step``, ``x``, ``y`` [m] and
        ``success`` (the episode's)
    :param courses: Each course of ``trajectories`` by name
    :param path: The PNG file
    :param title: The figure's title
    :return: ``path``
    """
    known = list(ALGO_DISPLAY_NAMES)
    algos = sorted(trajectories["algo"].unique(), key=lambda algo: (known.index(algo) if algo in known else len(known), algo))
    names = list(dict.fromkeys(trajectories["course"]))
    figure = Figure(figsize=(3.2 * len(names), 3.0 * len(algos)), layout="constrained")
    axes = figure.subplots(len(algos), len(names), squeeze=False)
    for row, algo in enumerate(algos):
        for ax, name in zip(axes[row], names, strict=True):
            runs = trajectories[(trajectories["algo"] == algo) & (trajectories["course"] == name)]
            successes = 0
            for _, run in runs.groupby("seed"):
                run = run.sort_values("step")
                success = bool(run["success"].iloc[0])
                successes += success
                color = "tab:blue" if success else "tab:red"
                ax.plot(run["x"], run["y"], color=color, linewidth=0.7, alpha=0.7)
                if not success:
                    ax.plot(run["x"].iloc[-1], run["y"].iloc[-1], marker="x", color="tab:red", markersize=6)
            n_runs = runs["seed"].nunique()
            draw_course(ax, courses[name], f"{display_name(algo)}, {name}\n{successes}/{n_runs} runs collision-free")
    handles = [
        Line2D([], [], color="tab:blue", label="no collision"),
        Line2D([], [], color="tab:red", marker="x", label="collision (x: where)"),
    ]
    figure.legend(handles=handles, loc="outside lower center", ncols=2, fontsize="small")
    if title:
        figure.suptitle(title, fontsize="medium")
    figure.savefig(path, dpi=100)
    return path
