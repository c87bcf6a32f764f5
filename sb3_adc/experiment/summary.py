"""An experiment's report: merged tables, summary, time to threshold and critic diagnostics (``experiment`` extra)."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sb3_adc.common.atomic import write_atomically
from sb3_adc.diagnostics import ARRAY_KEYS, HISTORY_CSV, load_history, plot_diagnostics
from sb3_adc.experiment.benchmark import EPISODES_CSV, EVALUATIONS_CSV, FINAL_CSV
from sb3_adc.experiment.invocations import read_invocations
from sb3_adc.experiment.plots import plot_results
from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.results import read_table
from sb3_adc.experiment.statistics import (
    final_performance,
    interval_estimates,
    iqm_and_mean,
    probability_of_improvement_metric,
    time_to_threshold,
)
from sb3_adc.experiment.test_sets import write_summary as write_test_summary
from sb3_adc.extras import requires_extra

if TYPE_CHECKING:
    from sb3_adc.experiment.experiments import Experiment

with requires_extra("experiment", "the experiment summaries"):
    import pandas as pd

#: Columns of the formatted summary but the last, which names the reference.
_DISPLAY_COLUMNS = ["env", "configuration", "runs", "final IQM [95% CI]", "final mean", "across-seed std", "AUC IQM [95% CI]"]


def _area(curve: pd.DataFrame) -> float:
    """The mean evaluation return over a run: the area under its curve (trapezoidal in timesteps) over its span."""
    x, y = curve["timesteps"].to_numpy(np.float64), curve["mean_return"].to_numpy(np.float64)
    return float(np.trapezoid(y, x) / (x[-1] - x[0])) if len(x) > 1 else np.nan


def _iqm_and_mean(prefix: str, point: np.ndarray, interval: np.ndarray) -> dict[str, Any]:
    """The columns of :func:`~sb3_adc.experiment.statistics.iqm_and_mean`'s estimates: IQM with CI, and mean."""
    iqm = f"{prefix}_iqm"
    return {iqm: point[0], f"{iqm}_ci_low": interval[0, 0], f"{iqm}_ci_high": interval[1, 0], f"{prefix}_mean": point[1]}


def summary(
    final: pd.DataFrame, evaluations: pd.DataFrame, reps: int, reference: str | None, episodes: pd.DataFrame | None = None
) -> pd.DataFrame:
    """
    Per environment and configuration (``algo``): final-return IQM and mean with CIs, across-seed std, area under
    the evaluation curve with IQM and CI, P(``reference`` > configuration) with CI (``p_improvement_of_adc``, as
    the committed tables name it), and, with episode wall-clock times, the median seconds a run trained.

    :param final: The final evaluations (``final.csv``)
    :param evaluations: The evaluation curves (``evaluations.csv``)
    :param reps: Bootstrap replications
    :param reference: The configuration whose improvement on the others is measured (``None``: none)
    :param episodes: The training episodes (``episodes.csv``), for the run times
    """
    run_areas = {run: _area(curve.sort_values("timesteps")) for run, curve in evaluations.groupby(["env", "algo", "seed"])}
    rows = []
    for env, env_final in final.groupby("env", sort=True):
        scores: dict[str, np.ndarray] = {}
        areas: dict[str, np.ndarray] = {}
        for name, group in env_final.groupby("algo", sort=False):
            ordered = group.sort_values("seed")
            scores[str(name)] = ordered["mean_return"].to_numpy(np.float64).reshape(-1, 1)
            per_run = [run_areas.get((env, name, seed), np.nan) for seed in ordered["seed"]]
            areas[str(name)] = np.asarray(per_run, dtype=np.float64).reshape(-1, 1)
        final_points, final_intervals = interval_estimates(scores, iqm_and_mean, reps, 0)
        area_points, area_intervals = interval_estimates(areas, iqm_and_mean, reps, 1)
        base = scores.get(reference) if reference is not None else None
        pairs = {} if base is None else {n: (base, s) for n, s in scores.items() if n != reference and s.shape == base.shape}
        improvement = interval_estimates(pairs, probability_of_improvement_metric, reps, 2) if pairs else ({}, {})
        for name in scores:
            n_runs = scores[name].shape[0]
            row: dict[str, Any] = {"env": env, "config": name, "n_runs": n_runs}
            row |= _iqm_and_mean("final", final_points[name], final_intervals[name])
            row["final_std"] = float(scores[name].std(ddof=1)) if n_runs > 1 else np.nan
            row |= _iqm_and_mean("auc", area_points[name], area_intervals[name])
            if episodes is not None and "wall_time_s" in episodes.columns:
                runs = episodes[(episodes["env"] == env) & (episodes["algo"] == name)]
                row["run_time_s_median"] = float(runs.groupby("seed")["wall_time_s"].max().median())
            if name in improvement[0]:
                row["p_improvement_of_adc"] = float(np.asarray(improvement[0][name]).reshape(-1)[0])
                low, high = np.asarray(improvement[1][name]).reshape(2, -1)[:, 0]
                row["p_improvement_ci_low"], row["p_improvement_ci_high"] = float(low), float(high)
            rows.append(row)
    return pd.DataFrame(rows)


def display_table(table: pd.DataFrame, reference: str | None) -> pd.DataFrame:
    """
    The summary with rounded numbers and CIs in brackets, one string per cell: one decimal where an environment's
    IQMs reach 10 in size, three where they stay below.

    :param table: The output of :func:`summary`
    :param reference: The reference configuration
    """
    # Returns of order one (the lidar and highway tasks) need more decimals than the Pendulum's hundreds.
    scale = table.groupby("env")[["final_iqm", "auc_iqm"]].transform(lambda column: column.abs().max()).max(axis=1)
    rows = []
    for row, row_scale in zip(table.itertuples(), scale, strict=True):
        improvement = "—"
        if not pd.isna(getattr(row, "p_improvement_of_adc", np.nan)):
            improvement = f"{row.p_improvement_of_adc:.2f} [{row.p_improvement_ci_low:.2f}, {row.p_improvement_ci_high:.2f}]"
        d = 1 if row_scale >= 10 else 3
        final_iqm = f"{row.final_iqm:.{d}f} [{row.final_iqm_ci_low:.{d}f}, {row.final_iqm_ci_high:.{d}f}]"
        auc_iqm = f"{row.auc_iqm:.{d}f} [{row.auc_iqm_ci_low:.{d}f}, {row.auc_iqm_ci_high:.{d}f}]"
        spread = [f"{row.final_mean:.{d}f}", f"{row.final_std:.{d}f}"]
        rows.append([row.env, row.config, str(row.n_runs), final_iqm, *spread, auc_iqm, improvement])
    return pd.DataFrame(rows, columns=[*_DISPLAY_COLUMNS, f"P({reference} > configuration) [95% CI]"])


def markdown(table: pd.DataFrame, reference: str | None) -> str:
    """
    :func:`display_table` as a Markdown table.

    :param table: The output of :func:`summary`
    :param reference: The reference configuration
    """
    display = display_table(table, reference)
    lines = ["| " + " | ".join(display.columns) + " |", "|---|---|---:|---|---:|---:|---|---|"]
    lines += ["| " + " | ".join(row) + " |" for row in display.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def threshold_markdown(converged: pd.DataFrame, threshold: float) -> str:
    """
    Per configuration: runs that stay above ``threshold`` by the end, and the median episodes until they do (a run
    that never does counts as beyond its budget).

    :param converged: The output of :func:`~sb3_adc.experiment.statistics.time_to_threshold`
    :param threshold: The return
    """
    lines = [
        f"| env | configuration | runs at or above {threshold:g} by the end | median episodes until they stay there |",
        "|---|---|---:|---:|",
    ]
    for (env, name), group in converged.groupby(["env", "algo"], sort=False):
        median = float(np.median(group["episodes"].fillna(np.inf).to_numpy(np.float64)))
        shown = f"> {int(group['budget_episodes'].max())}" if np.isinf(median) else f"{median:.0f}"
        lines.append(f"| {env} | {name} | {int(group['reached'].sum())} of {len(group)} | {shown} |")
    return "\n".join(lines) + "\n"


def merge_tables(tables: Mapping[str, Mapping[str, str]], output: str) -> None:
    """
    Merge the tables of an experiment's grids into ``output``, with the configuration's name in ``algo``.

    :param tables: Configuration name -> its grid's table name -> path
    :param output: The experiment's results folder
    """
    os.makedirs(output, exist_ok=True)
    for table in (FINAL_CSV, EVALUATIONS_CSV, EPISODES_CSV):
        frames = [read_table(paths[table]).assign(algo=name) for name, paths in tables.items()]
        pd.concat(frames, ignore_index=True).to_csv(os.path.join(output, table), index=False)


def write_report(experiment: Experiment, output: str, figures: str | None = None, grids: Sequence[str] | None = None) -> None:
    """
    Write an experiment's statistics and figures from its merged tables in ``output``: ``summary.csv``, ``.md``
    and ``summary_table.csv``, ``time_to_threshold.{csv,md}`` with a threshold, the figures and tables of
    :func:`~sb3_adc.experiment.plots.plot_results` (by the configurations' labels), ``metadata.json`` after training,
    and with test sets ``test_summary.{csv,md}`` (only that where the training curves were not kept).

    :param experiment: The experiment
    :param output: Its results folder
    :param figures: Where to move the figures, as ``{name}_{figure}.png`` (``None``: none is kept)
    :param grids: The log folders of the grids just trained, whose ``invocations.json`` give the wall time of every
        invocation, interrupted ones included (``None``: no training, ``metadata.json`` is left as it is)
    """
    write_test_summary(output, experiment.references(), experiment.bootstrap_reps)
    out = partial(os.path.join, output)
    if not os.path.isfile(out(EVALUATIONS_CSV)):  # results kept without their training curves
        return
    final, evaluations, episodes = (read_table(out(name)) for name in (FINAL_CSV, EVALUATIONS_CSV, EPISODES_CSV))
    reps = experiment.bootstrap_reps
    table = summary(final, evaluations, reps, experiment.reference, episodes)
    table.to_csv(out("summary.csv"), index=False)
    Path(out("summary.md")).write_text(markdown(table, experiment.reference), encoding="utf-8")
    display_table(table, experiment.reference).to_csv(out("summary_table.csv"), index=False)
    if experiment.threshold is not None:
        converged = time_to_threshold(evaluations, episodes, experiment.threshold)
        converged.to_csv(out("time_to_threshold.csv"), index=False)
        Path(out("time_to_threshold.md")).write_text(threshold_markdown(converged, experiment.threshold), encoding="utf-8")
    labels = {name: config.label for name, config in experiment.configs.items() if config.label}
    # The figures name the configurations by their labels; the tables keep the configurations' names.
    relabel = {"algo": labels}
    plots = plot_results(
        evaluations.replace(relabel), output, final=final.replace(relabel), episodes=episodes.replace(relabel), reps=reps
    )
    inverse = {label: name for name, label in labels.items()}
    for path in plots.tables:
        if inverse and path.endswith(".csv"):
            read_table(path).replace({"algo": inverse}).to_csv(path, index=False)
    for figure in plots.figures:
        if figures is None:
            os.remove(figure)
        else:
            os.makedirs(figures, exist_ok=True)
            os.replace(figure, os.path.join(figures, f"{experiment.name}_{os.path.basename(figure)}"))
    if grids is not None:
        _write_metadata(experiment, output, grids)


#: The critic diagnostics summarised with CIs over runs: the critic's bias, and ADC's advantage roughness.
DIAGNOSTICS_CI_KEYS = ("eval/critic_bias", "eval/critic_bias_abs", "train/advantage_roughness")


def diagnostics_summary(last_records: pd.DataFrame, reps: int) -> pd.DataFrame:
    """
    IQM and mean of each of :data:`DIAGNOSTICS_CI_KEYS` per configuration, with CIs over runs.

    :param last_records: One row per run: ``config``, ``seed`` and the last value of each diagnostic
    :param reps: Bootstrap replications
    :return: Columns ``metric``, ``config``, ``n_runs``, ``iqm``, ``iqm_ci_low`` ... ``mean_ci_high``
    """
    frames = []
    for key in (key for key in DIAGNOSTICS_CI_KEYS if key in last_records.columns):  # ADC's are absent for DDPG
        runs = last_records[["config", "seed", key]].dropna()
        scores = runs.rename(columns={"config": "algo", key: "mean_return"}).assign(env=key)
        frames.append(final_performance(scores, reps=reps).rename(columns={"env": "metric", "algo": "config"}))
    return pd.concat(frames, ignore_index=True)


def write_diagnostics(experiment: Experiment, runs: str, output: str, figures: str | None) -> None:
    """
    Collect the critic diagnostics of an experiment's runs into ``output``: ``diagnostics/{config}_seed{seed}.csv``,
    ``diagnostics_last_records.csv``, ``diagnostics_summary.csv`` and the figure ``{figures}/{name}_diagnostics.png``.

    :param experiment: The experiment
    :param runs: Folder of its runs
    :param output: Its results folder
    :param figures: Folder of the figure (``None``: none is drawn)
    """
    os.makedirs(os.path.join(output, "diagnostics"), exist_ok=True)
    histories: dict[str, list[Any]] = {}
    rows = []
    for name in experiment.configs:
        for seed in experiment.seeds:
            folder = os.path.join(runs, name, "diagnostics", f"seed{seed}")
            if not os.path.isfile(os.path.join(folder, HISTORY_CSV)):
                continue  # a run that failed, or the seeds a tiny run leaves out
            history = load_history(folder)
            histories.setdefault(name, []).append(history)
            shutil.copy(os.path.join(folder, HISTORY_CSV), os.path.join(output, "diagnostics", f"{name}_seed{seed}.csv"))
            last = {key: value for record in history for key, value in record.items() if key not in ARRAY_KEYS}
            rows.append({"config": name, "seed": seed, **last})
    table = pd.DataFrame(rows)
    table.to_csv(os.path.join(output, "diagnostics_last_records.csv"), index=False)
    summary_path = os.path.join(output, "diagnostics_summary.csv")
    diagnostics_summary(table, experiment.bootstrap_reps).to_csv(summary_path, index=False)
    if figures is not None:
        os.makedirs(figures, exist_ok=True)
        title = f"Critic diagnostics on {experiment.envs[0]} (seeds {experiment.seeds[0]}-{experiment.seeds[-1]})"
        plot_diagnostics(histories, os.path.join(figures, f"{experiment.name}_diagnostics.png"), title=title)


def read_metadata(path: str) -> dict[str, Any]:
    """
    A results folder's ``metadata.json`` (empty where there is none yet).

    :param path: The file
    """
    return json.loads(Path(path).read_text(encoding="utf-8")) if os.path.isfile(path) else {}


def write_metadata(path: str, metadata: Mapping[str, Any]) -> None:
    """
    Write a results folder's ``metadata.json`` atomically (it accumulates the wall time of every invocation).

    :param path: The file
    :param metadata: Its content
    """
    write_atomically(path, lambda stream: stream.write(json.dumps(metadata, indent=2) + "\n"))


def _write_metadata(experiment: Experiment, output: str, grids: Sequence[str]) -> None:
    from sb3_adc.experiment.experiments import repository_root

    path = os.path.join(output, "metadata.json")
    previous = read_metadata(path)
    # From the grids' journals, not counted here: an invocation stopped before its report keeps its time.
    wall_times = {str(index): entry["wall_time_s"] for index, entry in enumerate(read_invocations(grids))}
    metadata = {
        **experiment.record(repository_root(experiment)),
        "wall_time_s_per_invocation": wall_times,
        "bootstrap_reps": experiment.bootstrap_reps,
        **{key: previous[key] for key in ("notes",) if key in previous},
        **machine_metadata(),
    }
    write_metadata(path, metadata)
