"""
Every committed grid of ``procedural_generalisation.py`` on one page: per grid and algorithm, the held-out layout
success and the success on the unseen course files, beside the memoryless reference planner and the 90% that
issue 9 asks of the shipped ADC entry. It reads the committed results and trains nothing.

Per grid (a folder of ``benchmarks/results/procedural_generalisation/`` with a ``success.csv``) and algorithm:

- the held-out layouts' IQM and mean with their 95% stratified-bootstrap CIs, as the grid's ``success_rates.csv``
  has them, and how many runs reach 0.90 there;
- the unseen course files (every shipped course file but ``training``) pooled per run: the share of a run's
  course-file episodes without a collision, then the IQM and mean over runs with 95% CIs (rliable, the grid's
  bootstrap replications, seed 0) and how many runs reach 0.90.

The reference planner (``reference_planner.py``) adds one row per observation, robot and lidar: one
deterministic policy, so a rate without a CI. For the pairs of grids in ``COMPARISONS`` (at most one change between
them, trained on the same seeds: a setting, the deployed policy, the algorithm given the same settings, the
algorithm with its own shipped entry, or none: the same configuration trained again), the probability that a run of
the first beats a run of the second on each test set (rliable, 95% stratified-bootstrap CI): ``comparisons.csv``
and a table in ``summary.md``. Writes ``summary.csv`` and ``summary.md`` beside the grids and the figure
``docs/_static/benchmarks/procedural_summary.png``.

Usage::

    python benchmarks/procedural_summary.py
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd
from procedural_generalisation import (
    ALGOS,
    DOCS_STATIC,
    HELD_OUT,
    RESULTS_DIR,
    SIGHTING,
    VALIDATION_BEST,
    held_out_courses,
)
from procedural_generalisation import HITS as HIT_KINDS

from sb3_adc.experiment.plots import algo_colors, display_name
from sb3_adc.experiment.results import read_table
from sb3_adc.experiment.statistics import FINAL_PERFORMANCE_COLUMNS, final_performance, probability_of_improvement
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS

FIGURE = DOCS_STATIC / "procedural_summary.png"
COURSE_FILES = "unseen course files"
#: What issue 9 asks of the shipped ADC entry on both test sets.
TARGET = 0.9
#: The statistics' columns (``env`` becomes the test set) between the grid's facts and the runs at the target.
STATISTICS = [column for column in FINAL_PERFORMANCE_COLUMNS if column not in ("env", "algo", "n_runs")]
#: What failed episodes hit (``success.csv``'s columns), summed over the runs; empty for grids scored before the
#: scoring recorded it.
HITS = [f"hit_{kind}" for kind in HIT_KINDS]
#: Of the failed episodes, those that ended against an obstacle and those whose obstacle the lidar did not show in
#: time (``procedural_generalisation.SIGHTING``); empty for grids scored before the scoring recorded it.
SIGHTINGS = ["hit_obstacle", "hit_unseen"]
#: A side of a comparison: a grid's folder name (a grid of one algorithm), or (folder name, algorithm): the runs of
#: one algorithm of a grid of several (the four shipped entries in one grid).
Side = str | tuple[str, str]
#: Pairs of grids to compare run against run: (changed, control), one algorithm each, the same seeds and test sets,
#: and one change between them: a setting or the deployed policy of one algorithm, the algorithm given the same
#: settings (ADC against TD3 with the same sensor, returns, budget and deployed policy), the algorithm with its own
#: shipped entry (two algorithms of the shipped grid, each with the entry a user gets), or none (the shipped entry's
#: grid against the earlier grid of the same configuration: a replication, trained again with its own periodic
#: evaluations, on whatever machine ran it).
AVERAGE_ADC = "LidarObstacleCourse-v1_n_step_150k_sectors_average_validation"
AVERAGE_TD3 = "LidarObstacleCourse-v1_n_step_td3_150k_sectors_average_validation"
AVERAGE_ADC_300K = "LidarObstacleCourse-v1_n_step_300k_sectors_average_validation"
AVERAGE_TD3_300K = "LidarObstacleCourse-v1_n_step_td3_300k_sectors_average_validation"
#: The grids of the four shipped ``-v1`` entries: clean and noisy observations with the kinematic robot, and clean
#: observations with the wheeled robot.
SHIPPED = "LidarObstacleCourse-v1"
SHIPPED_NOISY = "LidarObstacleCourseNoisy-v1"
SHIPPED_WHEELED = "LidarObstacleCourse-v1_wheeled"
SHIPPED_NOISY_WHEELED = "LidarObstacleCourseNoisy-v1_wheeled"
ACTOR_ITSELF = "_actor_itself"
BEST = "_best"


def adc_against_the_others(grid: str) -> list[tuple[Side, Side]]:
    """ADC's runs of a shipped grid against those of each other algorithm of the grid, in ``ALGOS`` order."""
    return [((grid, "adc"), (grid, algo)) for algo in ALGOS if algo != "adc"]


COMPARISONS: list[tuple[Side, Side]] = [
    ("LidarObstacleCourse-v1_n_step_150k_sectors_validation", "LidarObstacleCourse-v1_n_step_150k_validation"),
    ("LidarObstacleCourse-v1_n_step_150k_sectors_validation_best", "LidarObstacleCourse-v1_n_step_150k_validation_best"),
    (AVERAGE_ADC, AVERAGE_ADC + ACTOR_ITSELF),
    (AVERAGE_TD3, AVERAGE_TD3 + ACTOR_ITSELF),
    (AVERAGE_TD3 + ACTOR_ITSELF, "LidarObstacleCourse-v1_n_step_td3_150k"),
    (AVERAGE_ADC, AVERAGE_TD3),
    (AVERAGE_ADC + ACTOR_ITSELF, AVERAGE_TD3 + ACTOR_ITSELF),
    (AVERAGE_ADC_300K, AVERAGE_ADC),
    (AVERAGE_ADC_300K, AVERAGE_ADC_300K + ACTOR_ITSELF),
    (AVERAGE_ADC_300K, AVERAGE_ADC_300K + BEST),
    (AVERAGE_TD3_300K, AVERAGE_TD3),
    (AVERAGE_TD3_300K, AVERAGE_TD3_300K + ACTOR_ITSELF),
    (AVERAGE_ADC_300K, AVERAGE_TD3_300K),
    (AVERAGE_ADC_300K + ACTOR_ITSELF, AVERAGE_TD3_300K + ACTOR_ITSELF),
    ((SHIPPED, "adc"), AVERAGE_ADC_300K),
    ((SHIPPED, "adc"), (SHIPPED, "ddpg")),
    ((SHIPPED, "td3"), AVERAGE_TD3_300K),
    ((SHIPPED, "adc"), (SHIPPED, "td3")),
    ((SHIPPED, "adc"), (SHIPPED, "sac")),
    *adc_against_the_others(SHIPPED_NOISY),
    *adc_against_the_others(SHIPPED_WHEELED),
    *adc_against_the_others(SHIPPED_NOISY_WHEELED),
]
#: The test sets of the comparisons: the held-out layouts, the unseen course files pooled per run, the posts course.
POSTS = "unseen_posts"
#: Bootstrap replications of the comparisons (the grids' own tables use 5000).
COMPARISON_REPS = 5000
COMPARISON_COLUMNS = ["changed", "control", "test_set", "changed_mean", "control_mean", "probability", "ci_low", "ci_high"]
COLUMNS = [
    "grid",
    "env",
    "robot",
    "model",
    "algo",
    "timesteps",
    "n_runs",
    "test_set",
    *STATISTICS,
    "runs_at_target",
    "failed_episodes",
    *HITS,
    *SIGHTINGS,
]


def grids(results: Path) -> list[Path]:
    """The grids' folders: those with a ``success.csv``, in name order."""
    return sorted(path.parent for path in results.glob("*/success.csv"))


def unseen_files(success: pd.DataFrame) -> pd.DataFrame:
    """The rows of the unseen course files: every test set but the held-out layouts and the ``training`` file."""
    return success[~success["test_set"].isin([HELD_OUT, "training"])]


def failures(rows: pd.DataFrame) -> dict[str, float]:
    """
    The failed episodes of ``rows`` (one test set or several), what they hit and whether the lidar showed the
    obstacle in time, summed; NaN where the scoring did not record it.
    """
    counts: dict[str, float] = {"failed_episodes": int(rows["episodes"].sum() - rows["successes"].sum())}
    for columns in (HITS, SIGHTINGS):
        recorded = set(columns) <= set(rows.columns)
        counts |= {column: int(rows[column].sum()) if recorded else float("nan") for column in columns}
    return counts


def course_file_rates(success: pd.DataFrame) -> pd.DataFrame:
    """Per run, the share of its episodes on the unseen course files (all but ``training``) without a collision."""
    pooled = unseen_files(success).groupby(["algo", "seed"], sort=True)[["successes", "episodes"]].sum().reset_index()
    return pooled.assign(success_rate=pooled["successes"] / pooled["episodes"])


def summarise_grid(folder: Path) -> pd.DataFrame:
    """The rows of one grid (see the module's docstring)."""
    metadata = json.loads((folder / "metadata.json").read_text())
    success = read_table(folder / "success.csv")
    timesteps = read_table(folder / "final.csv").groupby("algo")["timesteps"].max()
    held_out = read_table(folder / "success_rates.csv")
    held_out = held_out[held_out["test_set"] == HELD_OUT]
    files = course_file_rates(success)
    performance = final_performance(
        files.assign(env=COURSE_FILES).rename(columns={"success_rate": "mean_return"}),
        reps=int(metadata["bootstrap_reps"]),
    ).rename(columns={"env": "test_set"})
    per_run = success_rates_per_run(success)
    rates = {
        test_set: per_run[per_run["env"] == test_set].set_index(["algo", "seed"])["mean_return"]
        for test_set in (HELD_OUT, COURSE_FILES)
    }
    episodes = {HELD_OUT: success[success["test_set"] == HELD_OUT], COURSE_FILES: unseen_files(success)}
    # Grids written before --model existed scored the final models.
    described = metadata.get("model", "final")
    if described == VALIDATION_BEST:
        model = "best on validation"
    else:
        model = "best" if described.startswith("each run's best") else "final"
    if metadata.get("actor_itself"):  # scored with --actor-itself: the averaged actor dropped
        model += ", actor itself"
    rows = []
    for table in (held_out, performance):
        for row in table.to_dict("records"):
            algo, test_set = row["algo"], row["test_set"]
            rows.append(
                {
                    **row,
                    "grid": folder.name,
                    "env": metadata["env"],
                    "robot": metadata["robot"],
                    "model": model,
                    "timesteps": int(timesteps[algo]),
                    "runs_at_target": int((rates[test_set].loc[algo] >= TARGET).sum()),
                    **failures(episodes[test_set][episodes[test_set]["algo"] == algo]),
                }
            )
    return pd.DataFrame(rows, columns=COLUMNS)


def planner_rows(results: Path) -> pd.DataFrame:
    """The reference planner's rates on both test sets, one row per observation, robot and lidar."""
    planner = read_table(results / "reference_planner.csv")
    rows = []
    for (env, robot, rays_per_reading), group in planner.groupby(["env", "robot", "rays_per_reading"], sort=True):
        lidar = "" if rays_per_reading == 1 else f", {rays_per_reading} rays per reading"
        for test_set, episodes in ((HELD_OUT, group[group["test_set"] == HELD_OUT]), (COURSE_FILES, unseen_files(group))):
            rate = episodes["successes"].sum() / episodes["episodes"].sum()
            rows.append(
                {
                    "grid": f"reference_planner ({'noisy' if 'Noisy' in env else 'clean'}, {robot}{lidar})",
                    "env": env,
                    "robot": robot,
                    "model": "planner",
                    "algo": "planner",
                    "n_runs": 1,
                    "test_set": test_set,
                    **dict.fromkeys(STATISTICS, rate),
                    "runs_at_target": int(rate >= TARGET),
                    **failures(episodes),
                }
            )
    return pd.DataFrame(rows, columns=COLUMNS)


def side_name(side: Side) -> str:
    """The side as ``comparisons.csv`` names it: the grid, and the algorithm where the side picks one."""
    return side if isinstance(side, str) else f"{side[0]} ({display_name(side[1])})"


def side_rates(results: Path, side: Side) -> pd.DataFrame | None:
    """
    :func:`success_rates_per_run` of the side's runs, or ``None`` where its grid is not committed or holds no run of
    its algorithm (a grid scored for some of its algorithms so far).

    :raises ValueError: A side named by its grid alone whose grid holds several algorithms
    """
    grid, algo = (side, None) if isinstance(side, str) else side
    if not (results / grid / "success.csv").exists():
        return None
    rates = success_rates_per_run(read_table(results / grid / "success.csv"))
    if algo is None:
        algos = sorted(set(rates["algo"]))
        if len(algos) > 1:
            raise ValueError(f"comparison side {grid!r} holds {', '.join(algos)}: name one, as ({grid!r}, algo)")
        return rates
    rates = rates[rates["algo"] == algo]
    return None if rates.empty else rates


def success_rates_per_run(success: pd.DataFrame) -> pd.DataFrame:
    """
    Per run of a grid (``algo``, ``seed``), its success rate (``mean_return``, the statistics' column) on each
    comparison test set (``env``): the held-out layouts, the unseen course files pooled, the posts course.

    :param success: The grid's ``success.csv``
    """
    held_out = success[success["test_set"] == HELD_OUT][["algo", "seed", "success_rate"]].assign(env=HELD_OUT)
    files = course_file_rates(success)[["algo", "seed", "success_rate"]].assign(env=COURSE_FILES)
    posts = success[success["test_set"] == POSTS][["algo", "seed", "success_rate"]].assign(env=POSTS)
    rates = pd.concat([held_out, files, posts], ignore_index=True)
    return rates.rename(columns={"success_rate": "mean_return"})


def compare(results: Path, pairs: list[tuple[Side, Side]], reps: int) -> pd.DataFrame:
    """
    For each pair of committed grids (changed, control), per test set of :func:`success_rates_per_run`: the mean
    success of each side's runs and the probability that a run of the changed side beats one of the control (ties
    count one half), with its 95% CI. Pairs whose sides are not both committed (:func:`side_rates`) are left out.
    """
    rows = []
    for changed, control in pairs:
        changed_rates, control_rates = side_rates(results, changed), side_rates(results, control)
        if changed_rates is None or control_rates is None:
            continue
        rates = pd.concat([changed_rates.assign(algo="changed"), control_rates.assign(algo="control")])
        for test_set in (HELD_OUT, COURSE_FILES, POSTS):
            table = rates[rates["env"] == test_set]
            improvement = probability_of_improvement(table, reps=reps).iloc[0]
            means = table.groupby("algo")["mean_return"].mean()
            rows.append(
                {
                    "changed": side_name(changed),
                    "control": side_name(control),
                    "test_set": test_set,
                    "changed_mean": float(means["changed"]),
                    "control_mean": float(means["control"]),
                    "probability": float(improvement["probability"]),
                    "ci_low": float(improvement["ci_low"]),
                    "ci_high": float(improvement["ci_high"]),
                }
            )
    return pd.DataFrame(rows, columns=COMPARISON_COLUMNS)


def comparisons_markdown(comparisons: pd.DataFrame) -> str:
    """The table of the comparisons for ``summary.md`` (empty when there is none)."""
    if comparisons.empty:
        return ""
    lines = [
        "",
        "Pairs of grids with one change between them, run against run (the probability that a run of the changed grid "
        "has the higher success rate, ties one half, with its 95% stratified-bootstrap CI):",
        "",
        "| changed | control | test set | mean success, changed | mean success, control | P(changed > control) [95% CI] |",
        "|---|---|---|---:|---:|---|",
    ]
    for row in comparisons.itertuples(index=False):
        lines.append(
            f"| {row.changed} | {row.control} | {row.test_set} | {row.changed_mean:.2f} | {row.control_mean:.2f} "
            f"| {row.probability:.2f} [{row.ci_low:.2f}, {row.ci_high:.2f}] |"
        )
    return "\n".join(lines) + "\n"


def held_out_obstacles(env_id: str = "sb3_adc/LidarObstacleCourse-v1", n_layouts: int = 100) -> dict[str, int]:
    """How many obstacles of each kind the first ``n_layouts`` held-out layouts hold together (the kinematic robot's)."""
    counts = dict.fromkeys(["box", "cylinder", "stub"], 0)
    for course in held_out_courses(env_id, {}, [TEST_LAYOUT_SEEDS[0] + k for k in range(n_layouts)]).values():
        for obstacle in course.obstacles:
            counts["stub" if obstacle.shape == "wall" else obstacle.shape] += 1
    return counts


def summarise(results: Path) -> pd.DataFrame:
    """Every grid's rows, then the planner's."""
    return pd.concat([*(summarise_grid(folder) for folder in grids(results)), planner_rows(results)], ignore_index=True)


def markdown(summary: pd.DataFrame, obstacles: dict[str, int]) -> str:
    """
    One line per grid and algorithm, both test sets side by side; then what the failed episodes hit.

    :param obstacles: The obstacles of the held-out layouts by kind (:func:`held_out_obstacles`)
    """
    lines = [
        f"| grid | observations | robot | model | algorithm | steps | runs | {HELD_OUT}: IQM [95% CI] | runs >= {TARGET:.2f} "
        f"| {COURSE_FILES}: IQM [95% CI] | runs >= {TARGET:.2f} |",
        "|---|---|---|---|---|---:|---:|---|---:|---|---:|",
    ]
    for (grid, algo), group in summary.groupby(["grid", "algo"], sort=False):
        cells = []
        for test_set in (HELD_OUT, COURSE_FILES):
            row = group[group["test_set"] == test_set].iloc[0]
            interval = "" if algo == "planner" else f" [{row.iqm_ci_low:.2f}, {row.iqm_ci_high:.2f}]"
            cells += [f"{row.iqm:.2f}{interval}", str(row.runs_at_target)]
        first = group.iloc[0]
        observations = "noisy" if "Noisy" in first["env"] else "clean"
        steps = "" if pd.isna(first["timesteps"]) else f"{int(first['timesteps']):,}"
        lines.append(
            f"| {grid} | {observations} | {first['robot']} | {first['model']} | {display_name(algo)} | {steps} "
            f"| {first['n_runs']} | " + " | ".join(cells) + " |"
        )
    lines += [
        "",
        "What the failed episodes ended against, summed over the runs (an episode against two kinds counts for both; "
        "grids scored before this was recorded are left out), and how many ended against an obstacle (not a wall of "
        "the corridor) and against one the lidar did not show in time (no reading on it from "
        f"{SIGHTING[1]} to {SIGHTING[0]} steps before the contact; '-': not recorded when the grid was scored):",
        "",
        "| grid | algorithm | test set | failed episodes | wall | box | cylinder | wall stub | obstacle | obstacle unseen |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in summary.dropna(subset=HITS).itertuples(index=False):
        counts = " | ".join(str(int(getattr(row, hit))) for hit in HITS)
        recorded = [getattr(row, column) for column in SIGHTINGS]
        sightings = " | ".join("-" if pd.isna(count) else str(int(count)) for count in recorded)
        lines.append(
            f"| {row.grid} | {display_name(row.algo)} | {row.test_set} | {row.failed_episodes} | {counts} | {sightings} |"
        )
    held = ", ".join(f"{count} {kind}{'es' if kind == 'box' else 's'}" for kind, count in obstacles.items())
    lines += ["", f"The 100 held-out layouts hold {held} (each run drives one episode per layout)."]
    return "\n".join(lines) + "\n"


def plot(summary: pd.DataFrame, path: Path) -> None:
    """Both test sets side by side, one row per grid and algorithm, IQM with its 95% CI and the 90% target."""
    colors = algo_colors(ALGOS) | {"planner": (0.3, 0.3, 0.3, 1.0)}
    labels = list(dict.fromkeys(zip(summary["grid"], summary["algo"], strict=True)))
    # Constrained layout leaves the suptitle its own row (tight_layout drew it over the panels' titles).
    figure, axes = plt.subplots(1, 2, figsize=(13, 0.32 * len(labels) + 1.6), sharey=True, layout="constrained")
    for ax, test_set in zip(axes, (HELD_OUT, COURSE_FILES), strict=True):
        table = summary[summary["test_set"] == test_set].set_index(["grid", "algo"])
        for position, label in enumerate(labels):
            row = table.loc[label]
            errors = [[row.iqm - row.iqm_ci_low], [row.iqm_ci_high - row.iqm]]
            marker = "D" if label[1] == "planner" else "o"
            ax.errorbar(row.iqm, position, xerr=errors, fmt=marker, color=colors[label[1]], capsize=3)
        ax.axvline(TARGET, color="black", linestyle="--", linewidth=1)
        ax.set(
            title=test_set,
            xlabel="success rate, IQM over runs\n(share of collision-free episodes, 95% CI)",
            xlim=(-0.02, 1.02),
        )
        ax.grid(alpha=0.3, axis="x")
    axes[0].set_yticks(range(len(labels)), [f"{grid}: {display_name(algo)}" for grid, algo in labels], fontsize="small")
    axes[0].set_ylim(len(labels) - 0.5, -0.5)  # one row per label, the first at the top, no empty margin
    handles = [
        plt.Line2D(
            [], [], color=colors[algo], marker="D" if algo == "planner" else "o", linestyle="", label=display_name(algo)
        )
        for algo in [*ALGOS, "planner"]
    ] + [plt.Line2D([], [], color="black", linestyle="--", label=f"target {TARGET:.0%}")]
    axes[1].legend(handles=handles, fontsize="small", loc="center left")  # the rows there are all above 0.6
    figure.suptitle(
        "Procedural lidar course: success on layouts and course files never trained on (learners: 10 fresh seeds each)"
    )
    figure.savefig(path, dpi=120)
    plt.close(figure)


def main() -> None:
    summary = summarise(RESULTS_DIR)
    summary.to_csv(RESULTS_DIR / "summary.csv", index=False)
    comparisons = compare(RESULTS_DIR, COMPARISONS, reps=COMPARISON_REPS)
    comparisons.to_csv(RESULTS_DIR / "comparisons.csv", index=False)
    table = markdown(summary, held_out_obstacles()) + comparisons_markdown(comparisons)
    (RESULTS_DIR / "summary.md").write_text(table)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    plot(summary, FIGURE)
    print(table)
    print(f"wrote {RESULTS_DIR / 'summary.csv'}, {RESULTS_DIR / 'summary.md'} and {FIGURE}")


if __name__ == "__main__":
    main()
