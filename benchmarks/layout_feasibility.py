"""
Whether the lidar course's test sets can be driven at all: for each of the 100 held-out procedural layouts
(``TEST_LAYOUT_SEEDS``) and each shipped course file, the longest collision-free drive from the start that the
kinematic robot can steer (:func:`sb3_adc_envs.lidar_course.passability.kinematic_reach`: a search over five
steering actions with the environment's speed, turn limit and robot radius), against the 500 steps of an episode.

The generator guarantees a gap wider than the robot (a flood fill); this checks the robot's turning radius too,
so that the success rates of ``benchmarks/experiments/lidar_course_v1.yml`` can be read against what is possible: a
layout that reaches 500 steps has a collision-free episode, so a policy that crashes there failed to learn it.

Writes ``benchmarks/results/lidar_course_v1_feasibility/feasibility.csv`` (one row per layout or course),
``feasibility.md`` and ``feasibility_metadata.json``.

Usage::

    python benchmarks/layout_feasibility.py            # about 3 s a layout on one core
    python benchmarks/layout_feasibility.py --quick    # 3 layouts and one course file
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import gymnasium as gym
import pandas as pd

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc_envs.lidar_course import Course, load_course, shipped_courses
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS
from sb3_adc_envs.lidar_course.passability import kinematic_reach

ROOT = Path(__file__).resolve().parent
OUTPUT = ROOT / "results" / "lidar_course_v1_feasibility"
ENV_ID = "sb3_adc/LidarObstacleCourse-v1"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--max-states", type=int, default=2000, help="search states kept per step")
    parser.add_argument("--quick", action="store_true", help="smoke run: 3 layouts, one course file, 50 steps")
    args = parser.parse_args()
    if args.max_states < 1:
        parser.error("--max-states must be >= 1")
    env = gym.make(ENV_ID, layout_seeds=TEST_LAYOUT_SEEDS)
    unwrapped = env.unwrapped
    n_steps = int(env.spec.max_episode_steps) if env.spec and env.spec.max_episode_steps else 500
    robot = {
        "robot_radius": unwrapped.robot_radius,  # type: ignore[attr-defined]
        "speed": unwrapped.speed,  # type: ignore[attr-defined]
        "max_steer": unwrapped.max_steer,  # type: ignore[attr-defined]
    }
    layouts = range(*TEST_LAYOUT_SEEDS)
    courses = shipped_courses()
    if args.quick:
        layouts, courses, n_steps = layouts[:3], courses[:1], 50
    tests: list[tuple[str, str, Course]] = []
    for layout_seed in layouts:
        env.reset(options={"layout_seed": layout_seed})
        tests.append(("held-out layouts", f"layout {layout_seed}", unwrapped.course))  # type: ignore[attr-defined]
    env.close()
    tests.extend(("course file", name, load_course(name)) for name in courses)
    start, rows = time.perf_counter(), []
    for index, (test_set, name, course) in enumerate(tests, start=1):
        reach = kinematic_reach(course, n_steps=n_steps, max_states=args.max_states, **robot)
        rows.append({"test_set": test_set, "course": name, "steps_reached": reach, "drivable": reach == n_steps})
        print(f"[{index}/{len(tests)}] {name}: {reach} of {n_steps} steps", flush=True)
    wall_s = round(time.perf_counter() - start, 1)
    table = pd.DataFrame(rows)
    suffix = "_quick" if args.quick else ""
    OUTPUT.mkdir(parents=True, exist_ok=True)
    table.to_csv(OUTPUT / f"feasibility{suffix}.csv", index=False)
    lines = ["| test set | courses | drivable for the whole episode | shortest reach (steps) |", "|---|---:|---:|---:|"]
    for test_set, group in table.groupby("test_set", sort=False):
        lines.append(f"| {test_set} | {len(group)} | {int(group['drivable'].sum())} | {int(group['steps_reached'].min())} |")
    (OUTPUT / f"feasibility{suffix}.md").write_text("\n".join(lines) + "\n")
    metadata = {
        "env": ENV_ID,
        "robot": {
            "radius_m": robot["robot_radius"],
            "speed_m_per_step": robot["speed"],
            "max_steer_deg": math.degrees(robot["max_steer"]),
        },
        "n_steps": n_steps,
        "n_actions": 5,
        "max_states": args.max_states,
        "wall_time_s": wall_s,
        **machine_metadata(),
    }
    (OUTPUT / f"feasibility{suffix}_metadata.json").write_text(json.dumps(metadata, indent=2) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
