"""
The results table of the README and ``docs/results/which_algorithm.rst``, generated from committed summaries.

One row per task (``TASKS``), one column per algorithm (ADC, DDPG, TD3, SAC; "—" where an algorithm was not run):
the final IQM [95% CI] over fresh seeds, formatted as the summary files format it (1 decimal for returns, 2 for
success rates), and a verdict generated from P(ADC > X), the probability that an ADC run beats a run of X, and
its 95% CI (``relation``). Writes ``docs/results/tables/tasks.{csv,md}`` (``tasks.md`` is what the README embeds)
and ``probabilities.{csv,md}`` (the P(ADC > X) [95% CI] behind each verdict). Trains nothing.

Usage::

    python benchmarks/tables.py
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS_DIR = ROOT / "benchmarks" / "results"
TABLES_DIR = ROOT / "docs" / "results" / "tables"
ALGOS = ("ADC", "DDPG", "TD3", "SAC")
MISSING = "—"
HELD_OUT = "held-out layouts"


@dataclass(frozen=True)
class Task:
    """
    One row: its ``label``; what the cells measure with the budget (``metric``); the ``summary`` file, relative to
    ``benchmarks/results``: an experiment's ``summary.csv`` (a row per ``config`` with P(ADC > config)) or, with
    ``env``, its ``test_summary.csv`` (a row per ``env``, test set and ``config``, with P(reference > config) on the
    ``test_set``); and ``configs``, algorithm -> configuration (an algorithm not run is absent).
    """

    label: str
    metric: str
    summary: str
    configs: dict[str, str]
    env: str = ""
    test_set: str = HELD_OUT


SHIPPED = {"ADC": "adc", "DDPG": "ddpg", "TD3": "td3", "SAC": "sac"}
WHEELED = {algo: f"{config}_wheeled" for algo, config in SHIPPED.items()}
LIDAR = "success on 100 held-out layouts (300,000 steps)"
GRIDS = "lidar_course_v1/test_summary.csv"
CLEAN, NOISY = "sb3_adc/LidarObstacleCourse-v1", "sb3_adc/LidarObstacleCourseNoisy-v1"
TASKS = (
    # TD3's and SAC's shipped Noisy Pendulum entries are the winners of the equal-budget tuning (experiments/fair_tuning.yml).
    Task(
        "Noisy Pendulum",
        "final return (20,000 steps)",
        "noisy_pendulum_shipped/summary.csv",
        {"ADC": "adc_shipped", "DDPG": "ddpg_shipped", "TD3": "td3_tuned", "SAC": "sac_tuned"},
    ),
    Task("Lidar course, kinematic robot", LIDAR, GRIDS, SHIPPED, CLEAN),
    Task("Lidar course, kinematic robot, noisy lidar", LIDAR, GRIDS, SHIPPED, NOISY),
    Task("Lidar course, wheeled robot", LIDAR, GRIDS, WHEELED, CLEAN),
    Task("Lidar course, wheeled robot, noisy lidar", LIDAR, GRIDS, WHEELED, NOISY),
    # Every entry of the steering-and-speed task is its -v1 entry, untuned there (experiments/speed_mechanisms.yml).
    Task(
        "Lidar course, steering and speed",
        "success on 100 held-out layouts (50,000 steps)",
        "speed_mechanisms/test_summary.csv",
        {"ADC": "adc_shipped", "DDPG": "ddpg", "TD3": "td3", "SAC": "sac"},
        "sb3_adc/LidarObstacleCourseSpeed-v1",
    ),
    # The highway entries are the winners of the equal-budget tuning (experiments/highway_obstacle_v1_tuning.yml, 8
    # trials each), trained by experiments/highway_obstacle_v1_tuned.yml. -v1 supersedes -v0 (16 rays, which no
    # entry learns: experiments/highway_obstacle.yml, which_algorithm.rst).
    Task(
        "Highway obstacles, 64-ray lidar",
        "success on 50 held-out roads (30,000 steps)",
        "highway_obstacle_v1_tuned/test_summary.csv",
        {algo: f"{config}_tuned" for algo, config in SHIPPED.items()},
        "sb3_adc/HighwayObstacle-v1",
        "held-out roads",
    ),
)

#: (estimate, CI low, CI high)
Interval = tuple[float, float, float]


def read_csv(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file as dictionaries."""
    with path.open(newline="") as file:
        return list(csv.DictReader(file))


def interval(estimate: float, low: float, high: float, decimals: int) -> str:
    """``estimate [low, high]`` with ``decimals`` decimals."""
    return f"{estimate:.{decimals}f} [{low:.{decimals}f}, {high:.{decimals}f}]"


def only(rows: list[dict[str, str]], **values: str) -> dict[str, str]:
    """The one row of ``rows`` with these column values."""
    (row,) = [row for row in rows if all(row[column] == value for column, value in values.items())]
    return row


def triple(row: dict[str, str], *columns: str) -> Interval:
    """An estimate and its CI from three columns of ``row``."""
    estimate, low, high = (float(row[column]) for column in columns)
    return estimate, low, high


def task_numbers(task: Task, results: Path) -> tuple[dict[str, Interval], dict[str, Interval]]:
    """Per algorithm of ``task``: its final IQM with CI, and P(ADC > it) with CI (not for ADC itself)."""
    rows = read_csv(results / task.summary)
    scores: dict[str, Interval] = {}
    probabilities: dict[str, Interval] = {}
    for algo, config in task.configs.items():
        if task.env:
            row = only(rows, env=task.env, config=config, test_set=task.test_set)
            scores[algo] = triple(row, "iqm", "iqm_ci_low", "iqm_ci_high")
            if algo != "ADC":
                assert row["reference"] == task.configs["ADC"], f"{config} is compared with {row['reference']}"
                probabilities[algo] = triple(row, "p_reference", "p_reference_ci_low", "p_reference_ci_high")
        else:
            row = only(rows, config=config)
            scores[algo] = triple(row, "final_iqm", "final_iqm_ci_low", "final_iqm_ci_high")
            if algo != "ADC":
                probabilities[algo] = triple(row, "p_improvement_of_adc", "p_improvement_ci_low", "p_improvement_ci_high")
    return scores, probabilities


def relation(low: float, high: float) -> str:
    """ADC against X from the CI of P(ADC > X): ``"ahead of"``, ``"behind"`` or ``"level with"``."""
    if low > 0.5:
        return "ahead of"
    if high < 0.5:
        return "behind"
    return "level with"


def verdict(probabilities: dict[str, Interval]) -> str:
    """One line, e.g. ``"ADC ahead of SAC, level with DDPG, behind TD3"``, from P(ADC > X) [low, high] per X."""
    parts = []
    for kind in ("ahead of", "level with", "behind"):
        names = [algo for algo, (_, low, high) in probabilities.items() if relation(low, high) == kind]
        if names:
            listed = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
            parts.append(f"{kind} {listed}")
    return "ADC " + ", ".join(parts) if parts else MISSING


def tables(results: Path = RESULTS_DIR) -> tuple[list[list[str]], list[list[str]]]:
    """The tasks table and the probabilities table, header row first."""
    tasks = [["task", "metric (IQM [95% CI])", *ALGOS, "verdict from P(ADC > X)"]]
    probabilities = [["task", *(f"P(ADC > {algo}) [95% CI]" for algo in ALGOS[1:])]]
    for task in TASKS:
        decimals = 2 if task.env else 1
        scores, p_adc = task_numbers(task, results)
        cells = [interval(*scores[algo], decimals) if algo in scores else MISSING for algo in ALGOS]
        tasks.append([task.label, task.metric, *cells, verdict(p_adc)])
        probabilities.append([task.label, *(interval(*p_adc[a], 2) if a in p_adc else MISSING for a in ALGOS[1:])])
    return tasks, probabilities


def markdown(rows: list[list[str]]) -> str:
    """A GitHub markdown table."""
    lines = ["| " + " | ".join(row) + " |" for row in rows]
    lines.insert(1, "|" + "---|" * len(rows[0]))
    return "\n".join(lines) + "\n"


def write_tables(out_dir: Path = TABLES_DIR, results: Path = RESULTS_DIR) -> list[Path]:
    """Write ``tasks.{csv,md}`` and ``probabilities.{csv,md}`` into ``out_dir``; return their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, rows in zip(("tasks", "probabilities"), tables(results), strict=True):
        with (out_dir / f"{name}.csv").open("w", newline="") as file:
            csv.writer(file, lineterminator="\n").writerows(rows)
        (out_dir / f"{name}.md").write_text(markdown(rows))
        written += [out_dir / f"{name}.csv", out_dir / f"{name}.md"]
    return written


def main() -> None:
    """Regenerate the tables in ``docs/results/tables/``."""
    for path in write_tables():
        print(f"Wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
