"""Whether a round robot can drive round a corridor past its obstacles: a flood fill on a grid of the free space.

The walls and obstacles are drawn on a grid (Pillow), and a Euclidean distance transform (SciPy) marks the cells
where the robot's centre fits, more than its radius (plus one cell) from everything. The corridor is then cut
across at the start position, and the robot can drive round if the cells just ahead of the cut and those just
behind it are still connected: the only way from one to the other goes round the loop.

:func:`kinematic_reach` asks more: whether the robot can *steer* past the obstacles with its turning radius, by a
search over steering actions on the same grid.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("envs", "the lidar obstacle course"):
    from PIL import Image, ImageDraw
    from scipy import ndimage
    from scipy.spatial import cKDTree

from sb3_adc_envs.lidar_course import geometry

if TYPE_CHECKING:
    from sb3_adc_envs.lidar_course.course import Course

#: Side of a grid cell [m].
GRID_RESOLUTION = 0.04
#: Most cells of a grid: a course of the largest side
#: (:data:`~sb3_adc_envs.lidar_course.course.MAX_COURSE_SIDE`, 200 m) needs about 25 million at
#: :data:`GRID_RESOLUTION` (the shipped courses at most 160,000). The grid and the distance transform take about
#: 20 bytes a cell, so the bound keeps them under about 600 MB.
MAX_GRID_CELLS = 30_000_000
# Distance of the seed points ahead of and behind the cut, and the radius around them searched for free cells [m].
_SEED_OFFSET = 0.4
_SEED_RADIUS = 0.3


class _Grid:
    """Conversion between course coordinates [m] and grid cells (row 0 at the top, y pointing up)."""

    def __init__(self, bounds: tuple[float, float, float, float], resolution: float, margin: float):
        x_min, y_min, x_max, y_max = bounds
        self.x_min = x_min - margin
        self.y_max = y_max + margin
        self.resolution = resolution
        self.shape = (
            math.ceil((y_max - y_min + 2.0 * margin) / resolution),
            math.ceil((x_max - x_min + 2.0 * margin) / resolution),
        )

    def to_pixels(self, points: np.ndarray) -> list[tuple[float, float]]:
        columns = (points[:, 0] - self.x_min) / self.resolution
        rows = (self.y_max - points[:, 1]) / self.resolution
        return list(zip(columns.tolist(), rows.tolist(), strict=True))

    def cell_centres(self, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
        return np.column_stack([self.x_min + (columns + 0.5) * self.resolution, self.y_max - (rows + 0.5) * self.resolution])

    def image(self) -> Image.Image:
        return Image.new("1", (self.shape[1], self.shape[0]), 0)


def _rectangle(x0: float, y0: float, x1: float, y1: float, thickness: float) -> np.ndarray:
    # A wall segment as the simulation builds it: a box `thickness` wide, half a thickness longer at both ends.
    direction = np.array([x1 - x0, y1 - y0]) / math.hypot(x1 - x0, y1 - y0)
    along = direction * thickness / 2.0
    across = np.array([-direction[1], direction[0]]) * thickness / 2.0
    start, end = np.array([x0, y0]) - along, np.array([x1, y1]) + along
    return np.array([start + across, end + across, end - across, start - across])


def robot_fits(course: Course, robot_radius: float, resolution: float = GRID_RESOLUTION) -> tuple[np.ndarray, _Grid]:
    """
    The cells of a grid over the course where a round robot's centre is clear of every wall and obstacle.

    :param course: The course
    :param robot_radius: Radius of the robot [m]
    :param resolution: Side of a cell [m]
    :return: a boolean ``(rows, columns)`` array (row 0 at the top) and the grid it lies on
    :raises CourseError: naming ``<extent>``, if the grid would have more than :data:`MAX_GRID_CELLS` cells
    """
    grid = _Grid(course.bounds, resolution, margin=robot_radius + 2.0 * resolution)
    cells = grid.shape[0] * grid.shape[1]
    if cells > MAX_GRID_CELLS:
        # Imported here: the course module imports this one.
        from sb3_adc_envs.lidar_course.course import CourseError

        raise CourseError(
            course.source,
            "<extent>",
            f"the passability grid over the course ({grid.shape[1]:,} x {grid.shape[0]:,} cells of {resolution:g} m, "
            f"robot radius {robot_radius:g} m) would have {cells:,} cells; it may have at most "
            f"MAX_GRID_CELLS = {MAX_GRID_CELLS:,}. Make the course smaller.",
        )
    image = grid.image()
    draw = ImageDraw.Draw(image)
    for x0, y0, x1, y1 in course.walls:
        draw.polygon(grid.to_pixels(_rectangle(x0, y0, x1, y1, course.wall_thickness)), fill=1, outline=1)
    for obstacle in course.obstacles:
        draw.polygon(grid.to_pixels(obstacle.footprint()), fill=1, outline=1)
    occupied = np.asarray(image, dtype=bool)
    # Distance from each cell to the nearest occupied cell; one cell of margin for the rasterised outlines.
    distance = ndimage.distance_transform_edt(~occupied) * resolution
    return distance > robot_radius + resolution, grid


def blocked_corridor_point(
    course: Course, robot_radius: float, resolution: float = GRID_RESOLUTION
) -> tuple[float, float] | None:
    """
    Where the obstacles block a corridor course for a round robot, if they do.

    :param course: A course with a ``corridor``
    :param robot_radius: Radius of the robot [m]
    :param resolution: Side of a grid cell [m]
    :return: ``None`` if the robot can drive a full lap from its start position, else a point of the centre line
        near the blockage ``(x, y)`` [m]
    :raises ValueError: if the course has no corridor
    """
    if course.corridor is None:
        raise ValueError(f"course {course.name!r} has no corridor: passability is checked round a corridor only.")
    fits, grid = robot_fits(course, robot_radius, resolution)
    centerline = course.corridor.centerline
    segments = geometry.polyline_segments(centerline, closed=True)
    start = np.array([course.start.x, course.start.y])
    index, _ = geometry.closest_segment(start, segments)
    x0, y0, x1, y1 = segments[index]
    tangent = np.array([x1 - x0, y1 - y0]) / math.hypot(x1 - x0, y1 - y0)
    normal = np.array([-tangent[1], tangent[0]])

    # Cut the corridor across at the start (two cells thick, so no diagonal step crosses it).
    reach = course.corridor.width / 2.0 + 2.0 * course.wall_thickness + 2.0 * resolution
    cut = grid.image()
    ImageDraw.Draw(cut).line(grid.to_pixels(np.array([start - normal * reach, start + normal * reach])), fill=1, width=2)
    fits = fits & ~np.asarray(cut, dtype=bool)
    labels, _ = ndimage.label(fits)

    rows, columns = np.nonzero(fits)
    centres = grid.cell_centres(rows, columns)
    ahead = _labels_near(labels, rows, columns, centres, start + tangent * _SEED_OFFSET)
    behind = _labels_near(labels, rows, columns, centres, start - tangent * _SEED_OFFSET)
    if not ahead or not behind:
        return float(start[0]), float(start[1])
    if ahead & behind:
        return None
    # Blocked: the furthest the robot gets along the centre line going forward from the cut.
    samples = geometry.sample_polyline(centerline, resolution, closed=True)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(samples, axis=0).T))])
    length = arc[-1] + float(np.hypot(*(samples[0] - samples[-1])))
    _, start_sample = cKDTree(samples).query(start)
    in_reach = np.isin(labels[rows, columns], list(ahead))
    _, nearest = cKDTree(samples).query(centres[in_reach])
    forward = (arc[nearest] - arc[start_sample]) % length
    furthest = samples[nearest[int(np.argmax(forward))]]
    return float(furthest[0]), float(furthest[1])


def _labels_near(
    labels: np.ndarray, rows: np.ndarray, columns: np.ndarray, centres: np.ndarray, point: np.ndarray
) -> set[int]:
    near = np.hypot(*(centres - point).T) <= _SEED_RADIUS
    return {int(label) for label in np.unique(labels[rows[near], columns[near]])}


def kinematic_reach(
    course: Course,
    robot_radius: float,
    speed: float,
    max_steer: float,
    n_steps: int,
    n_actions: int = 5,
    max_states: int = 4000,
    resolution: float = GRID_RESOLUTION,
) -> int:
    """
    How many steps the kinematic robot of the lidar course can drive from the course's start pose without a
    collision, at most ``n_steps``: a breadth-first search over ``n_actions`` evenly spaced steering actions
    (``-1`` to ``1``), the robot turning, then driving ``speed`` metres, as
    :meth:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv.step` does.

    :func:`robot_fits` asks whether a round robot fits through every gap; this asks whether it can *steer* through
    them, with its turning radius ``speed / max_steer``. A layout whose search stops short of ``n_steps`` has no
    collision-free episode for any policy of the searched actions (within the grid's resolution; the grid keeps
    one cell of margin, so a path that needs less may be missed). The states of each step are merged per grid cell
    and heading step and, above ``max_states``, thinned evenly in that order, so ``n_steps`` reached is proof of a
    path and a shorter reach is strong evidence that none exists.

    :param course: The course (a procedural layout: ``env.unwrapped.course``)
    :param robot_radius: Radius of the robot [m]
    :param speed: Distance driven per step [m]
    :param max_steer: Largest turn per step [rad]
    :param n_steps: Steps of an episode (the time limit)
    :param n_actions: Steering actions searched (odd, so that driving straight is one of them)
    :param max_states: States kept per step
    :param resolution: Side of a grid cell [m]
    :return: The number of steps of the longest collision-free drive found, ``n_steps`` when a whole episode is
        possible
    """
    if n_actions < 3 or n_actions % 2 == 0:
        raise ValueError(f"`n_actions` must be an odd integer >= 3, got {n_actions!r}.")
    free, grid = robot_fits(course, robot_radius, resolution)
    steers = np.linspace(-max_steer, max_steer, n_actions)
    heading_step = max_steer / ((n_actions - 1) // 2)
    x = np.array([course.start.x])
    y = np.array([course.start.y])
    heading = np.array([course.start.heading])
    for step in range(n_steps):
        new_heading = (heading[:, None] + steers[None, :]).ravel()
        new_x = np.repeat(x, n_actions) + speed * np.cos(new_heading)
        new_y = np.repeat(y, n_actions) + speed * np.sin(new_heading)
        rows = np.floor((grid.y_max - new_y) / grid.resolution).astype(np.int64)
        columns = np.floor((new_x - grid.x_min) / grid.resolution).astype(np.int64)
        inside = (rows >= 0) & (rows < free.shape[0]) & (columns >= 0) & (columns < free.shape[1])
        clear = np.zeros_like(inside)
        clear[inside] = free[rows[inside], columns[inside]]
        if not clear.any():
            return step
        turns = np.round(np.remainder(new_heading[clear], 2.0 * math.pi) / heading_step).astype(np.int64)
        keys = np.stack([rows[clear], columns[clear], turns], axis=1)
        _, first = np.unique(keys, axis=0, return_index=True)
        if len(first) > max_states:
            first = first[np.linspace(0, len(first) - 1, max_states).round().astype(np.int64)]
        x, y, heading = new_x[clear][first], new_y[clear][first], new_heading[clear][first]
    return n_steps
