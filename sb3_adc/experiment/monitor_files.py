"""Reading and trimming the monitor CSVs of training runs (SB3's ``Monitor`` format)."""

from __future__ import annotations

import io
import json
import time

import pandas as pd

from sb3_adc.common.atomic import write_atomically
from sb3_adc.experiment.envs import TOTAL_STEPS_KEY
from sb3_adc.experiment.layout import DamagedFileError


def read_monitor(path: str) -> pd.DataFrame:
    """
    The episodes of a monitor CSV: ``r`` (return), ``l`` (length), ``t`` (seconds), ``total_steps`` (sb3-adc's runs),
    without a last line cut short (which SB3's ``load_results``, reading a whole folder, would keep).

    :param path: The ``*.monitor.csv`` file
    """
    with open(path, encoding="utf-8", newline="") as stream:
        text = stream.read()
    complete = text[: text.rfind("\n") + 1]
    if complete.count("\n") < 2:  # killed while the header was written: no episode
        return pd.DataFrame({"r": [], "l": [], "t": []})
    return pd.read_csv(io.StringIO(complete), skiprows=1)


def truncate_monitor(path: str, steps: int) -> int:
    """
    Drop the episodes that ended after ``steps`` steps of the environment, and a last line cut short, rewriting the
    file atomically.

    :param path: The ``*.monitor.csv`` file
    :param steps: The environment's step count at the checkpoint
    :return: The number of episodes dropped
    :raises DamagedFileError: if the file does not start with a monitor header
    """
    with open(path, encoding="utf-8", newline="") as stream:
        lines = stream.read().splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines = lines[:-1]  # `Monitor` writes whole lines: a line without its end was cut short
    if len(lines) < 2:  # killed while `Monitor` wrote its header: write it again
        header_line = "#" + json.dumps({"t_start": time.time()}) + "\n"
        write_atomically(path, lambda stream: stream.writelines([header_line, f"r,l,t,{TOTAL_STEPS_KEY}\r\n"]))
        return 0
    if not lines[0].startswith("#"):
        raise DamagedFileError(path, "the first line is not a monitor header (`#{...}`)")
    header, columns, rows = lines[0], lines[1], lines[2:]
    names = columns.strip().split(",")
    if TOTAL_STEPS_KEY not in names:
        return 0
    column = names.index(TOTAL_STEPS_KEY)
    kept = [row for row in rows if _steps(row, column) <= steps]
    write_atomically(path, lambda stream: stream.writelines([header, columns, *kept]))
    return len(rows) - len(kept)


def _steps(row: str, column: int) -> float:
    """The ``total_steps`` of a monitor row; infinite (dropped) for a row that does not hold one."""
    fields = row.strip().split(",")
    try:
        return float(fields[column])
    except (IndexError, ValueError):
        return float("inf")
