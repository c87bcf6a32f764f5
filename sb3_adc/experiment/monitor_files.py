"""Reading and trimming the monitor CSVs of training runs (SB3's ``Monitor`` format)."""

from __future__ import annotations

import os

import pandas as pd

from sb3_adc.experiment.envs import TOTAL_STEPS_KEY


def read_monitor(path: str) -> pd.DataFrame:
    """
    The episodes of a monitor CSV: columns ``r`` (return), ``l`` (length), ``t`` (seconds) and, for runs of
    this package, ``total_steps`` (steps of that environment at the end of the episode).

    :param path: The ``*.monitor.csv`` file
    """
    return pd.read_csv(path, skiprows=1)


def truncate_monitor(path: str, steps: int) -> int:
    """
    Drop the episodes that ended after ``steps`` steps of the environment (work lost since a checkpoint).

    :param path: The ``*.monitor.csv`` file
    :param steps: The environment's step count at the checkpoint
    :return: The number of episodes dropped
    """
    with open(path, encoding="utf-8") as stream:
        lines = stream.read().splitlines(keepends=True)
    if len(lines) < 2:
        return 0
    header, columns, rows = lines[0], lines[1], lines[2:]
    names = columns.strip().split(",")
    if TOTAL_STEPS_KEY not in names:
        return 0
    column = names.index(TOTAL_STEPS_KEY)
    kept = [row for row in rows if row.strip() and int(float(row.split(",")[column])) <= steps]
    temporary = path + ".partial"
    with open(temporary, "w", encoding="utf-8") as stream:
        stream.writelines([header, columns, *kept])
    os.replace(temporary, path)
    return len(rows) - len(kept)
