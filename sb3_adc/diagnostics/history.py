"""The history of :class:`~sb3_adc.diagnostics.CriticDiagnosticsCallback`: saved, loaded and drawn."""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping, Sequence
from typing import IO, Any

import numpy as np

from sb3_adc.common.atomic import write_atomically

#: One record per log time: ``timesteps``, the scalar keys measured then, and for ADC the arrays
#: :data:`INTERVAL_VISITS_KEY` and :data:`ADVANTAGE_PROFILE_KEY`.
History = list[dict[str, Any]]
#: History key of the visit counts, ``(action_dim, n_intervals)``.
INTERVAL_VISITS_KEY = "interval_visits"
#: History key of the centred advantage across intervals averaged over a replay batch, ``(branches, n_intervals)``.
ADVANTAGE_PROFILE_KEY = "advantage_profile"
#: The array-valued history keys (kept in the ``.npz`` file only).
ARRAY_KEYS = (INTERVAL_VISITS_KEY, ADVANTAGE_PROFILE_KEY)
#: File names written by :func:`save_history` in its folder.
HISTORY_NPZ, HISTORY_CSV = "critic_diagnostics.npz", "critic_diagnostics.csv"


def _scalar_keys(history: History) -> list[str]:
    return list(dict.fromkeys(key for record in history for key in record if key != "timesteps" and key not in ARRAY_KEYS))


def save_history(history: History, folder: str) -> tuple[str, str]:
    """
    Write a history to ``folder``, each file atomically: ``critic_diagnostics.npz`` (``timesteps``, each scalar key
    over all records with NaN where a record lacks it, each array key stacked over the records that have it with
    their ``<key>_timesteps`` and indices ``<key>_records``) and ``critic_diagnostics.csv`` (the scalars).

    :param history: The records (:attr:`CriticDiagnosticsCallback.history`)
    :param folder: The folder (created if needed)
    :return: The paths of the ``.npz`` and ``.csv`` files
    """
    os.makedirs(folder, exist_ok=True)
    keys = _scalar_keys(history)
    arrays: dict[str, Any] = {"timesteps": np.array([record["timesteps"] for record in history], dtype=np.int64)}
    arrays.update({key: np.array([record.get(key, np.nan) for record in history], dtype=np.float64) for key in keys})
    for key in ARRAY_KEYS:
        indices = [index for index, record in enumerate(history) if key in record]
        if indices:
            arrays[key] = np.stack([history[index][key] for index in indices])
            arrays[f"{key}_timesteps"] = arrays["timesteps"][indices]
            arrays[f"{key}_records"] = np.array(indices, dtype=np.int64)
    npz_path, csv_path = os.path.join(folder, HISTORY_NPZ), os.path.join(folder, HISTORY_CSV)
    write_atomically(npz_path, lambda stream: np.savez(stream, **arrays), binary=True)

    def write_csv(stream: IO[Any]) -> None:
        writer = csv.writer(stream)
        writer.writerow(["timesteps", *keys])
        writer.writerows(
            [int(step), *(repr(float(arrays[key][i])) for key in keys)] for i, step in enumerate(arrays["timesteps"])
        )

    write_atomically(csv_path, write_csv)
    return npz_path, csv_path


def load_history(path: str) -> History:
    """
    Read a history written by :func:`save_history`.

    :param path: The ``critic_diagnostics.npz`` file, or the folder that holds it
    :return: The records, with the keys each record had
    """
    if os.path.isdir(path):
        path = os.path.join(path, HISTORY_NPZ)
    with np.load(path) as data:
        arrays = {key: data[key] for key in data.files}
    history: History = [{"timesteps": int(step)} for step in arrays["timesteps"]]
    bookkeeping = {"timesteps", *(f"{key}_{part}" for key in ARRAY_KEYS for part in ("records", "timesteps"))}
    for key, values in arrays.items():
        if key in ARRAY_KEYS:
            for index, value in zip(arrays[f"{key}_records"], values, strict=True):
                history[int(index)][key] = value
        elif key not in bookkeeping:
            for record, value in zip(history, values, strict=True):
                if not np.isnan(value):
                    record[key] = float(value)
    return history


def _runs(value: History | Sequence[History]) -> list[History]:
    """One history, or several runs' histories, as a list of runs."""
    return [value] if len(value) > 0 and isinstance(value[0], dict) else list(value)  # type: ignore[list-item, arg-type]


def _last_array(runs: list[History], key: str) -> np.ndarray | None:
    """The mean over runs of the last value of an array key (None if no run has it)."""
    last = [next((record[key] for record in reversed(run) if key in record), None) for run in runs]
    found = [np.asarray(value, dtype=np.float64) for value in last if value is not None]
    return np.mean(found, axis=0) if found else None


def plot_diagnostics(
    histories: Mapping[str, History | Sequence[History]], path: str, title: str = "", reps: int = 2000
) -> str:
    """
    Draw the critic diagnostics of one or several models as a PNG (``experiment`` extra): the critic's bias and the
    actor-gradient norm against timesteps (mean over runs, with a 95% stratified-bootstrap band for several runs),
    and for ADC models the fraction of stored actions per interval and the advantage profile at the last record.

    :param histories: Label -> one history, or a list of histories (one per run), e.g. from :func:`load_history`
    :param path: The PNG file
    :param title: The figure's title
    :param reps: Bootstrap replications of the confidence bands
    :return: ``path``
    """
    import pandas as pd
    from matplotlib.figure import Figure

    from sb3_adc.experiment.plots import _curve
    from sb3_adc.experiment.statistics import learning_curves

    runs_by_label = {label: _runs(value) for label, value in histories.items()}
    colors = {label: f"C{index % 10}" for index, label in enumerate(runs_by_label)}
    last_visits = {label: _last_array(runs, INTERVAL_VISITS_KEY) for label, runs in runs_by_label.items()}
    visits = {label: counts for label, counts in last_visits.items() if counts is not None}
    figure = Figure(figsize=(6.4 * 2, 4.0 * (2 if visits else 1)), layout="constrained")
    axes = list(figure.subplots(2 if visits else 1, 2, squeeze=False).flat)
    for ax, key in zip(axes[:2], ("eval/critic_bias", "train/actor_grad_norm"), strict=True):
        for label, runs in runs_by_label.items():
            rows = [(seed, rec["timesteps"], rec[key]) for seed, run in enumerate(runs) for rec in run if key in rec]
            if rows:
                table = pd.DataFrame(rows, columns=["seed", "timesteps", "mean_return"]).assign(env=key, algo=label)
                curves = learning_curves(table, reps=reps)
                n_runs = int(curves["n_runs"].iloc[0])
                name = f"{label} ({n_runs} run{'s' * (n_runs > 1)})"
                _curve(ax, curves, "timesteps", "mean", colors[label], name, band=n_runs > 1)
    axes[0].axhline(0.0, color="black", linewidth=0.8, linestyle=":")

    def centres(n_intervals: int) -> np.ndarray:
        return -1.0 + (2.0 * np.arange(n_intervals) + 1.0) / n_intervals

    for label, counts in visits.items():
        fraction = (counts / counts.sum(axis=-1, keepdims=True)).mean(axis=0)
        n_intervals = fraction.shape[-1]
        name = f"{label} ({n_intervals} intervals)"
        axes[2].step(centres(n_intervals), fraction, where="mid", color=colors[label], label=name)
        axes[2].axhline(1.0 / n_intervals, color=colors[label], linewidth=0.8, linestyle=":")
        profile = _last_array(runs_by_label[label], ADVANTAGE_PROFILE_KEY)
        if profile is not None:
            axes[3].plot(centres(profile.shape[-1]), profile.mean(axis=0), color=colors[label], label=label)
    panels = (  # title and y label of each panel
        ("Critic bias on evaluation rollouts", "critic bias Q - G (return units)"),
        ("Actor-gradient norm on replay batches", "actor-loss gradient norm (L2)"),
        ("Replay-buffer actions per interval (last record; dotted: uniform)", "fraction of stored actions"),
        ("Advantage across intervals (last record, replay-batch mean)", "A(s, z) - mean_z A(s, z) (return units)"),
    )
    for index, (ax, (panel_title, ylabel)) in enumerate(zip(axes, panels, strict=False)):
        ax.set(title=panel_title, xlabel="timesteps" if index < 2 else "scaled action, interval centre", ylabel=ylabel)
        ax.grid(alpha=0.3)
        if ax.has_data():
            ax.legend(fontsize="small")
    figure.suptitle(title or "Critic diagnostics", fontsize="medium")
    figure.savefig(path, dpi=120)
    return path
