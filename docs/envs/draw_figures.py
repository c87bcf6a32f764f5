"""Draw the environment pictures of the documentation into ``docs/_static/envs/``.

- ``courses.png``: every shipped course of the lidar obstacle course, with its obstacles and start pose;
- ``procedural_courses.png``: eight procedural layouts of ``sb3_adc/LidarObstacleCourse-v1``;
- ``lidar_course_frame.png``: ``render_mode="rgb_array"`` of the lidar course after 120 steps;
- ``highway_obstacle_frame.png``: ``render_mode="rgb_array"`` of the highway task after 8 steps.

Usage::

    python docs/envs/draw_figures.py
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import cast

import gymnasium as gym
import matplotlib
import numpy as np
from PIL import Image

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import Course, load_course, shipped_courses
from sb3_adc_envs.lidar_course.procedural import CourseGenerator

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes

OUT = Path(__file__).resolve().parent.parent / "_static" / "envs"


def draw_course(ax: Axes, course: Course, title: str = "") -> None:
    """
    A lidar course seen from above: its walls, its obstacles (filled) and its start pose (an orange arrow).

    :param ax: Where to draw
    :param course: The course (a shipped file's, or a procedural layout's: ``env.unwrapped.course``)
    :param title: The panel's title
    """
    for x0, y0, x1, y1 in course.walls:
        ax.plot([x0, x1], [y0, y1], color="0.2", linewidth=1.4)
    for obstacle in course.obstacles:
        outline = obstacle.footprint()
        ax.fill(outline[:, 0], outline[:, 1], color="tab:red", linewidth=0)
    start = course.start
    ax.annotate(
        "",
        xy=(start.x + 1.2 * math.cos(start.heading), start.y + 1.2 * math.sin(start.heading)),
        xytext=(start.x, start.y),
        arrowprops={"arrowstyle": "->", "color": "tab:orange", "linewidth": 1.5},
    )
    ax.plot(start.x, start.y, marker="o", color="tab:orange")
    ax.set_title(title, fontsize=9)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def draw_courses(path: Path) -> None:
    """All shipped courses, four a row, with their start pose, corridor width and obstacles."""
    names = shipped_courses()
    columns = 4
    rows = math.ceil(len(names) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.4 * columns, 3.2 * rows))
    for ax in axes.flat[len(names) :]:
        ax.axis("off")
    for ax, name in zip(axes.flat, names, strict=False):
        course = load_course(name)
        width = f"width {course.corridor.width:g} m" if course.corridor is not None else "wall polylines"
        obstacles = f", {len(course.obstacles)} obstacles" if course.obstacles else ""
        draw_course(ax, course, f"{name}\n({width}{obstacles})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def draw_procedural_courses(path: Path) -> None:
    """Eight procedural layouts (layout seeds 0 to 7, from the training range)."""
    generator = CourseGenerator()
    fig, axes = plt.subplots(2, 4, figsize=(13.6, 6.4))
    for layout_seed, ax in enumerate(axes.flat):
        course = generator.generate(layout_seed)
        assert course.corridor is not None
        title = f"layout seed {layout_seed}\n(width {course.corridor.width:.2f} m, {len(course.obstacles)} obstacles)"
        draw_course(ax, course, title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def draw_lidar_frame(path: Path) -> None:
    """A rendered frame of the lidar course: a gentle left-turning controller for 120 steps."""
    env = gym.make("sb3_adc/LidarObstacleCourse-v0", render_mode="rgb_array")
    obs, _ = env.reset(seed=0)
    for _ in range(120):
        # Steer away from the nearer side (rays 2 and 6 look left and right).
        action = np.clip([4.0 * (obs[2] - obs[6]) + 2.0 * (obs[1] - obs[7])], -1.0, 1.0).astype(np.float32)
        obs, _, terminated, _, _ = env.step(action)
        if terminated:
            break
    Image.fromarray(cast(np.ndarray, env.render())).save(path)
    env.close()


def draw_highway_frame(path: Path) -> None:
    """A rendered frame of the highway obstacle task."""
    env = gym.make("sb3_adc/HighwayObstacle-v0", render_mode="rgb_array")
    env.reset(seed=2)
    for _ in range(8):
        env.step(np.zeros(1, dtype=np.float32))
    Image.fromarray(cast(np.ndarray, env.render())).save(path)
    env.close()


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    draw_courses(OUT / "courses.png")
    draw_procedural_courses(OUT / "procedural_courses.png")
    draw_lidar_frame(OUT / "lidar_course_frame.png")
    draw_highway_frame(OUT / "highway_obstacle_frame.png")
    print(f"Wrote the pictures in {OUT}")


if __name__ == "__main__":
    main()
