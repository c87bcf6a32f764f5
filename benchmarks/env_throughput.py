"""Raw environment throughput: steps per second under random actions, on one CPU core.

Measures every sb3-adc environment next to Gymnasium's ``Pendulum-v1`` in the same run, the lidar course with
both its robots (the kinematic default and ``robot="wheeled"``, simulated with ``stepSimulation``) and with four
rays per lidar reading (``rays_per_reading=4``), at two levels:

- ``core``: the object the registered entry point returns (the environment class itself, or for the noisy
  lidar course the noise wrapper around it), stepped directly;
- ``gym.make``: the same behind the wrappers ``gym.make`` adds by default (``TimeLimit``,
  ``OrderEnforcing``, ``PassiveEnvChecker``), as RL libraries step it.

Actions are drawn before the timed loop; the loop calls ``reset()`` whenever an episode ends (collisions are
frequent under random steering), and those resets are part of the timing. The repeats go round all the
measurements in turn and each measurement keeps its best repeat. Then ``reset(seed=k)`` alone is timed
:data:`RESETS` times (``k = 0, 1, ...``: on ``-v1`` a new layout each time) and its median is reported. The
process is pinned to one core.

Usage::

    python benchmarks/env_throughput.py              # full run, writes benchmarks/results/env_throughput*
    python benchmarks/env_throughput.py --quick      # a short smoke run (results not written)
    python benchmarks/env_throughput.py --only sb3_adc/LidarObstacleCourse-v1 --suffix _before   # some, apart
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import load_env_creator

import sb3_adc
from sb3_adc.experiment.provenance import cpu_model

RESULTS_DIR = Path(__file__).resolve().parent / "results"
FIGURE_PATH = Path(__file__).resolve().parent.parent / "docs" / "_static" / "envs" / "env_throughput.png"

#: Wheeled robot: make kwargs, and the suffix of its measurements' names.
WHEELED = {"robot": "wheeled"}
WHEELED_SUFFIX = " (robot=wheeled)"
#: The lidar with four rays per reading (each reading the nearest hit over its sector, docs/envs/lidar_course.rst),
#: the sensor that shows the thin obstacles single rays miss: four times the rays of every scan.
FOUR_RAYS = {"rays_per_reading": 4}
FOUR_RAYS_SUFFIX = " (rays_per_reading=4)"
#: Measurement name -> (environment id, make kwargs, number of steps per repeat in a full run).
ENVIRONMENTS: dict[str, tuple[str, dict[str, Any], int]] = {
    "Pendulum-v1": ("Pendulum-v1", {}, 200_000),
    "sb3_adc/LidarObstacleCourse-v0": ("sb3_adc/LidarObstacleCourse-v0", {}, 200_000),
    "sb3_adc/LidarObstacleCourseNoisy-v0": ("sb3_adc/LidarObstacleCourseNoisy-v0", {}, 200_000),
    # Procedural layouts: a new one is drawn and built at every reset (random steering crashes every few dozen
    # steps, so resets weigh more here than in training).
    "sb3_adc/LidarObstacleCourse-v1": ("sb3_adc/LidarObstacleCourse-v1", {}, 50_000),
    "sb3_adc/LidarObstacleCourseNoisy-v1": ("sb3_adc/LidarObstacleCourseNoisy-v1", {}, 50_000),
    "sb3_adc/LidarObstacleCourse-v0" + FOUR_RAYS_SUFFIX: ("sb3_adc/LidarObstacleCourse-v0", FOUR_RAYS, 200_000),
    "sb3_adc/LidarObstacleCourse-v1" + FOUR_RAYS_SUFFIX: ("sb3_adc/LidarObstacleCourse-v1", FOUR_RAYS, 50_000),
    # The robot with dynamics: 10 physics steps per environment step.
    "sb3_adc/LidarObstacleCourse-v0" + WHEELED_SUFFIX: ("sb3_adc/LidarObstacleCourse-v0", WHEELED, 20_000),
    "sb3_adc/LidarObstacleCourse-v1" + WHEELED_SUFFIX: ("sb3_adc/LidarObstacleCourse-v1", WHEELED, 20_000),
    "sb3_adc/HighwayObstacle-v0": ("sb3_adc/HighwayObstacle-v0", {}, 5_000),
}
LEVELS = ("core", "gym.make")
#: Targets behind gym.make's wrappers: name -> (measurement, column, target), a least steps/s or a most reset ms.
TARGETS: dict[str, tuple[str, str, float]] = {
    "lidar": ("sb3_adc/LidarObstacleCourse-v0", "steps_per_s", 20_000),
    "wheeled": ("sb3_adc/LidarObstacleCourse-v0" + WHEELED_SUFFIX, "steps_per_s", 2_000),
    "v1": ("sb3_adc/LidarObstacleCourse-v1", "steps_per_s", 10_000),
    "v1_reset": ("sb3_adc/LidarObstacleCourse-v1", "reset_ms", 3.0),
}
#: Resets timed one by one for the median reset time (a full run; 20 in a quick one).
RESETS = 200


def make_env(env_id: str, level: str, kwargs: dict[str, Any] | None = None) -> gym.Env[Any, Any]:
    """``env_id`` at ``level``: ``"core"`` (what the entry point returns) or ``"gym.make"``, with make ``kwargs``."""
    kwargs = kwargs or {}
    if level == "gym.make":
        return gym.make(env_id, **kwargs)
    spec = gym.spec(env_id)
    entry_point = spec.entry_point
    if entry_point is None:
        raise ValueError(f"{env_id} has no entry point")
    creator = load_env_creator(entry_point) if isinstance(entry_point, str) else entry_point
    return cast(gym.Env[Any, Any], creator(**{**spec.kwargs, **kwargs}))


def time_steps(env: gym.Env[Any, Any], n_steps: int, seed: int) -> tuple[float, int]:
    """Step ``n_steps`` times under uniformly random actions; returns the seconds taken and the resets in the loop."""
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(n_steps)]
    env.reset(seed=seed)
    step = env.step
    resets = 0
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            env.reset()
            resets += 1
    return time.perf_counter() - start, resets


def median_reset_ms(env: gym.Env[Any, Any], n_resets: int) -> float:
    """The median time of ``reset(seed=k)`` for ``k = 0, ..., n_resets - 1`` [ms]."""
    times = []
    for seed in range(n_resets):
        start = time.perf_counter()
        env.reset(seed=seed)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) * 1e3


def pin_to_one_core() -> str:
    """Pin this process to one CPU core (where the OS allows it); returns a description."""
    if hasattr(os, "sched_setaffinity"):
        core = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {core})
        return f"pinned to core {core}"
    return "not pinned (no sched_setaffinity on this OS)"


def run(scale: float, repeats: int, names: list[str] | None = None) -> list[dict[str, Any]]:
    """
    Measure every environment (or those of ``names``, with ``Pendulum-v1``) at every level; returns one row per
    (environment, level).

    The repeats go round all the measurements in turn (rather than repeating one measurement back to back), so
    that a burst of load on a shared machine hits every environment alike; each keeps its best repeat.
    """
    chosen = [name for name in ENVIRONMENTS if names is None or name in names or name == "Pendulum-v1"]
    cases = [(name, level, max(100, int(ENVIRONMENTS[name][2] * scale))) for name in chosen for level in LEVELS]
    envs = {}
    for name, level, n_steps in cases:
        env_id, kwargs, _ = ENVIRONMENTS[name]
        envs[name, level] = make_env(env_id, level, kwargs)
        time_steps(envs[name, level], min(n_steps, 1_000), seed=1)  # warm-up: imports, caches
    best: dict[tuple[str, str], tuple[float, int]] = {}
    for repeat in range(repeats):
        for name, level, n_steps in cases:
            seconds, resets = time_steps(envs[name, level], n_steps, seed=repeat)
            if (name, level) not in best or seconds < best[name, level][0]:
                best[name, level] = (seconds, resets)
        print(f"  repeat {repeat + 1}/{repeats} done", flush=True)
    rows: list[dict[str, Any]] = []
    for name, level, n_steps in cases:
        reset_ms = median_reset_ms(envs[name, level], RESETS if scale == 1.0 else 20)
        envs[name, level].close()
        seconds, resets = best[name, level]
        rows.append(
            {
                "environment": name,
                "env_id": ENVIRONMENTS[name][0],
                "robot": ENVIRONMENTS[name][1].get("robot", ""),
                "level": level,
                "steps": n_steps,
                "resets": resets,
                "seconds": seconds,
                "steps_per_s": n_steps / seconds,
                "us_per_step": seconds / n_steps * 1e6,
                "reset_ms": reset_ms,
            }
        )
    pendulum = {row["level"]: row["steps_per_s"] for row in rows if row["environment"] == "Pendulum-v1"}
    for row in rows:
        row["ratio_to_pendulum"] = row["steps_per_s"] / pendulum[row["level"]]
    return rows


def print_table(rows: list[dict[str, Any]]) -> None:
    """Print the results as a table."""
    header = f"{'env':<54} {'level':<8} {'steps/s':>10} {'us/step':>8} {'x Pendulum':>10} {'resets':>7} {'reset ms':>8}"
    print(header)
    print("-" * len(header))
    for row in rows:
        print(
            f"{row['environment']:<54} {row['level']:<8} {row['steps_per_s']:>10,.0f} {row['us_per_step']:>8.1f} "
            f"{row['ratio_to_pendulum']:>10.2f} {row['resets']:>7} {row['reset_ms']:>8.2f}"
        )


def write_table(rows: list[dict[str, Any]], path: Path) -> None:
    """The rounded table the documentation shows."""
    with path.open("w") as table:
        table.write("environment,level,steps/s,us/step,x Pendulum-v1,reset ms (median)\n")
        for row in rows:
            table.write(
                f"{row['environment']},{row['level']},{row['steps_per_s']:.0f},{row['us_per_step']:.1f},"
                f"{row['ratio_to_pendulum']:.2f},{row['reset_ms']:.2f}\n"
            )


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """Bar chart of steps per second (log scale), core and gym.make side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env_ids = list(ENVIRONMENTS)
    width = 0.38
    fig, ax = plt.subplots(figsize=(12, 4.2))
    for offset, level in zip((-width / 2, width / 2), LEVELS, strict=True):
        values = [next(r["steps_per_s"] for r in rows if r["environment"] == e and r["level"] == level) for e in env_ids]
        bars = ax.bar(np.arange(len(env_ids)) + offset, values, width, label=level)
        ax.bar_label(bars, labels=[f"{v:,.0f}" for v in values], fontsize=7)
    ax.axhline(TARGETS["lidar"][2], color="tab:red", linestyle="--", linewidth=1, label="lidar course target")
    ax.axhline(TARGETS["wheeled"][2], color="tab:purple", linestyle=":", linewidth=1, label="wheeled robot target")
    ax.set_yscale("log")
    ax.set_ylabel("steps / s (one core)")
    labels = [
        e.replace("sb3_adc/", "")
        .replace("LidarObstacleCourse", "Lidar")
        .replace(WHEELED_SUFFIX, "\nrobot=wheeled")
        .replace(FOUR_RAYS_SUFFIX, "\n4 rays/reading")
        for e in env_ids
    ]
    ax.set_xticks(np.arange(len(env_ids)), labels, fontsize=8)
    ax.set_title("Environment throughput under random actions")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="1%% of the steps and one repeat; writes no results")
    parser.add_argument("--repeats", type=int, default=3, help="repeats per measurement, the best is kept (default 3)")
    parser.add_argument(
        "--only",
        nargs="+",
        metavar="NAME",
        choices=list(ENVIRONMENTS),
        help="measure only these (and Pendulum-v1, the reference), into the files of --suffix",
    )
    parser.add_argument(
        "--suffix",
        default="",
        help="with --only: write env_throughput<SUFFIX>.json and env_throughput_table<SUFFIX>.csv (say, of older code)",
    )
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error(f"--repeats must be >= 1, got {args.repeats}")

    pinning = pin_to_one_core()
    print(f"sb3-adc {sb3_adc.__version__}, Python {platform.python_version()}, {cpu_model()}, {pinning}")
    if args.only and not args.suffix and not args.quick:
        parser.error("--only needs --suffix: a partial run does not replace the full results")
    rows = run(scale=0.01 if args.quick else 1.0, repeats=1 if args.quick else args.repeats, names=args.only)
    print()
    print_table(rows)
    met = {}
    for key, (name, column, target) in TARGETS.items():
        value = next((r[column] for r in rows if r["environment"] == name and r["level"] == "gym.make"), None)
        if value is None:
            continue  # not measured (--only)
        met[key] = value <= target if column == "reset_ms" else value >= target
        print(f"{name}, gym.make: {value:,.2f} {column} (target {target:,}): {'met' if met[key] else 'NOT met'}")
    if args.quick:
        return 0

    import highway_env
    import pybullet  # noqa: F401 (imported by the environments already; only its version is read)
    import stable_baselines3

    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    metadata = {
        "script": "benchmarks/env_throughput.py",
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu": cpu_model(),
        "pinning": pinning,
        "repeats": args.repeats,
        "gymnasium": gym.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "highway_env": getattr(highway_env, "__version__", "unknown"),
        "numpy": np.__version__,
        "resets_timed": RESETS,
        "targets": TARGETS,
        "targets_met": met,
        "make_kwargs": {name: kwargs for name, (_, kwargs, _) in ENVIRONMENTS.items() if kwargs},
        "only": args.only,
    }
    if args.only:
        # A partial run (say, of the code before a change): its own files, beside the full results.
        (RESULTS_DIR / f"env_throughput{args.suffix}.json").write_text(
            json.dumps({"metadata": metadata, "results": rows}, indent=2) + "\n"
        )
        write_table(rows, RESULTS_DIR / f"env_throughput_table{args.suffix}.csv")
        print(f"Wrote env_throughput{args.suffix}.json and env_throughput_table{args.suffix}.csv in {RESULTS_DIR}")
        return 0
    (RESULTS_DIR / "env_throughput.json").write_text(json.dumps({"metadata": metadata, "results": rows}, indent=2) + "\n")
    with (RESULTS_DIR / "env_throughput.csv").open("w") as csv:
        columns = list(rows[0])
        csv.write(",".join(columns) + "\n")
        for row in rows:
            csv.write(",".join(f"{row[c]:.6g}" if isinstance(row[c], float) else str(row[c]) for c in columns) + "\n")
    write_table(rows, RESULTS_DIR / "env_throughput_table.csv")
    plot(rows, FIGURE_PATH)
    print(f"Wrote env_throughput.json, env_throughput.csv and env_throughput_table.csv in {RESULTS_DIR}, and {FIGURE_PATH}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
