"""Tidy tables of runs' results: ``evaluations.csv`` (per run and evaluation), ``episodes.csv`` (per run and training
episode) and ``final.csv`` (per run)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pandas as pd

from sb3_adc.common.atomic import write_atomically
from sb3_adc.experiment.callbacks import EvaluationHistory
from sb3_adc.experiment.envs import TOTAL_STEPS_KEY
from sb3_adc.experiment.evaluation import FinalEvaluation
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.monitor_files import read_monitor

EVALUATION_COLUMNS: tuple[str, ...] = ("algo", "env", "seed", "timesteps", "mean_return", "std_return", "min_return")
EVALUATION_COLUMNS += ("max_return", "mean_ep_length", "n_episodes", "success_rate")
EPISODE_COLUMNS = ("algo", "env", "seed", "episode", "timesteps", "return", "length", "wall_time_s")
FINAL_COLUMNS = ("algo", "env", "seed", "timesteps", "mean_return", "std_return", "n_episodes")

Row = dict[str, Any]


def _run_keys(layout: RunLayout, algo: str, seed: int) -> Row:
    return {"algo": algo, "env": layout.env_id, "seed": seed}


def evaluation_rows(layout: RunLayout, algo: str, seed: int) -> list[Row]:
    """
    The periodic evaluations of a run (columns :data:`EVALUATION_COLUMNS`); ``success_rate`` is SB3's
    ``eval/success_rate`` (the share of episodes ending with ``info["is_success"]``; empty where none report it).

    :param layout: The run's paths
    :param algo: The algorithm's name
    :param seed: The run's seed
    """
    history = EvaluationHistory.load(layout.evaluations)
    rates = history.success_rates() or [None for _ in history.timesteps]
    rows = []
    for step, returns, lengths, rate in zip(history.timesteps, history.results, history.ep_lengths, rates, strict=True):
        values = np.asarray(returns, dtype=np.float64)
        row = {**_run_keys(layout, algo, seed), "timesteps": int(step)}
        row.update({f"{stat}_return": float(getattr(values, stat)()) for stat in ("mean", "std", "min", "max")})
        rows.append({**row, "mean_ep_length": float(np.mean(lengths)), "n_episodes": len(values), "success_rate": rate})
    return rows


def episode_rows(layout: RunLayout, algo: str, seed: int) -> list[Row]:
    """
    The training episodes of a run, in the order they ended (columns :data:`EPISODE_COLUMNS`): ``timesteps`` (the
    environment's steps times the number of environments) and ``wall_time_s`` (:func:`training_seconds`) at its end.

    :param layout: The run's paths
    :param algo: The algorithm's name
    :param seed: The run's seed
    """
    files = layout.monitor_files()
    frames = []
    for path in files:
        frame = read_monitor(path)
        steps = frame[TOTAL_STEPS_KEY] if TOTAL_STEPS_KEY in frame else frame["l"].cumsum()
        columns = {"timesteps": steps * len(files), "return": frame["r"], "length": frame["l"]}
        frames.append(pd.DataFrame({**columns, "wall_time_s": training_seconds(frame["t"].to_numpy(np.float64))}))
    if not frames:
        return []
    episodes = pd.concat(frames).sort_values("timesteps", kind="stable").reset_index(drop=True)
    episodes = episodes.astype({"timesteps": int, "return": float, "length": int, "wall_time_s": float})
    episodes.insert(0, "episode", episodes.index + 1)
    return [{**_run_keys(layout, algo, seed), **row} for row in episodes.to_dict("records")]


def training_seconds(monitor_times: np.ndarray) -> np.ndarray:
    """
    Seconds of training (evaluations included) at the end of each episode of a monitor file, across resumes: SB3's
    ``Monitor`` clock restarts at zero, so each restart continues from the last episode recorded before it.

    :param monitor_times: The monitor's ``t`` column, in file order
    """
    times = np.asarray(monitor_times, dtype=np.float64)
    previous = np.concatenate([[0.0], times[:-1]])
    # A restart (the clock going back) adds the time reached before it to every later episode.
    return times + np.cumsum(np.where(times < previous, previous, 0.0))


def final_row(layout: RunLayout, algo: str, seed: int) -> Row | None:
    """
    The final evaluation of a finished run (columns :data:`FINAL_COLUMNS`), ``None`` if it has not finished.

    :param layout: The run's paths
    :param algo: The algorithm's name
    :param seed: The run's seed
    """
    if not layout.is_finished():
        return None
    final = FinalEvaluation.load(layout.final_evaluation)
    stats = {"timesteps": final.timesteps, "mean_return": final.mean_return, "std_return": final.std_return}
    return {**_run_keys(layout, algo, seed), **stats, "n_episodes": len(final.returns)}


def read_table(path: str | os.PathLike[str]) -> pd.DataFrame:
    """
    Read a results table (CSV, or ``.csv.gz``) with its floats exactly as written: pandas' default parser can read
    them one unit in the last place off (0.925 -> 0.9249999999999999), and a statistic then prints differently.

    :param path: The table
    :return: The table
    """
    return pd.read_csv(path, float_precision="round_trip")


def write_table(rows: list[Row], columns: tuple[str, ...], path: str) -> pd.DataFrame:
    """
    Write rows as a CSV with the given columns, sorted by algorithm, environment, seed and the next column.

    :param rows: The rows
    :param columns: The columns, in order
    :param path: The CSV file (written atomically)
    :return: The table
    """
    table = pd.DataFrame(rows, columns=list(columns))
    if not table.empty:
        table = table.sort_values(list(columns[:4]), kind="stable").reset_index(drop=True)
    if os.path.dirname(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
    write_atomically(path, lambda stream: table.to_csv(stream, index=False))
    return table
