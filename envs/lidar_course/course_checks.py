"""Geometric checks of a course: its extent, a corridor that must not overlap itself, obstacles in the free space."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sb3_adc_envs.lidar_course import geometry
from sb3_adc_envs.lidar_course.course import (
    MAX_COURSE_SIDE,
    MAX_OVERLAP_CHECK_DISTANCES,
    MAX_WALL_SEGMENTS,
    OBSTACLE_START_CLEARANCE,
    Corridor,
    CourseError,
    Obstacle,
    StartPose,
)

# Spacing of the centre-line samples used to check that a corridor does not overlap itself [m].
_OVERLAP_CHECK_SPACING = 0.05
# Relative tolerance of that check (mitred joints put walls slightly further away, never closer).
_OVERLAP_TOLERANCE = 1e-3
# Distances computed at once by that check: a block of samples times the walls (8 MB per temporary array).
_OVERLAP_CHECK_BLOCK = 1_000_000


def check_extent(source: str, field: str, xs: np.ndarray, ys: np.ndarray, margin: float, what: str) -> None:
    """
    Refuse points whose bounding box, widened by ``margin`` on every side, has a side over
    :data:`~sb3_adc_envs.lidar_course.course.MAX_COURSE_SIDE`.

    :param source: The course file, for the error message
    :param field: The field the points come from
    :param xs: The points' x coordinates [m]
    :param ys: The points' y coordinates [m]
    :param margin: Widening of the bounding box on every side [m]
    :param what: What the points are, in the error message
    :raises CourseError: naming ``field``
    """
    width = float(xs.max() - xs.min()) + 2.0 * margin
    height = float(ys.max() - ys.min()) + 2.0 * margin
    if max(width, height) > MAX_COURSE_SIDE:
        raise CourseError(
            source,
            field,
            f"{what} span {width:,.6g} m x {height:,.6g} m; a course must fit in a square of "
            f"MAX_COURSE_SIDE = {MAX_COURSE_SIDE:g} m (its walls' thickness included).",
        )


def corridor_walls(corridor: Corridor, wall_thickness: float) -> list[np.ndarray]:
    """
    The two walls of a corridor, as ``(n, 4)`` segments of their centre lines, left wall first.

    :param corridor: The corridor
    :param wall_thickness: Thickness of the walls [m]: their centre lines lie half of it beyond the free width
    """
    offset = corridor.width / 2.0 + wall_thickness / 2.0
    return [
        geometry.polyline_segments(geometry.offset_closed_polyline(corridor.centerline, side * offset), closed=True)
        for side in (1.0, -1.0)
    ]


def check_corridor_does_not_overlap(
    source: str, corridor: Corridor, walls: np.ndarray, wall_thickness: float, nearest_only: bool = False
) -> None:
    """
    Check that every point of the centre line is at least half the free width from every wall face: a loop that
    comes back near itself, or a corner too sharp for the width, puts a wall closer than that.

    :param source: The course file, for the error message
    :param corridor: The corridor
    :param walls: ``(n, 4)`` segments of its walls (:func:`corridor_walls`)
    :param wall_thickness: Thickness of the walls [m]
    :param nearest_only: Measure only the distances that can fail the check
        (:func:`~sb3_adc_envs.lidar_course.geometry.nearest_segment_distances`): the same outcome, faster
    :raises CourseError: naming ``corridor.centerline``
    """
    required = corridor.width / 2.0 * (1.0 - _OVERLAP_TOLERANCE)
    # Count the samples before drawing them: the distances are samples x walls.
    lengths = geometry.segment_lengths(geometry.polyline_segments(corridor.centerline, closed=True))
    n_samples = int(np.maximum(np.ceil(lengths / _OVERLAP_CHECK_SPACING), 1).sum())
    if n_samples * len(walls) > MAX_OVERLAP_CHECK_DISTANCES:
        raise CourseError(
            source,
            "corridor.centerline",
            f"checking that the corridor does not overlap itself needs {n_samples:,} centre-line samples x "
            f"{len(walls):,} wall segments = {n_samples * len(walls):,} distances; at most MAX_OVERLAP_CHECK_DISTANCES = "
            f"{MAX_OVERLAP_CHECK_DISTANCES:,} are computed. Shorten the centre line or give it fewer corners.",
        )
    samples = geometry.sample_polyline(corridor.centerline, _OVERLAP_CHECK_SPACING, closed=True)
    if nearest_only:
        # A sample fails when its nearest wall face is closer than `required`: walls further than that (plus the
        # wall's half thickness, and a margin for the rounding of the subtraction) cannot change the outcome.
        reach = (required + wall_thickness / 2.0) * (1.0 + 1e-6) + 1e-9
        # Most corridors pass: the smallest distance decides it (the smallest clearance is the smallest distance
        # less the half thickness, the same rounding), and the per-sample distances only name the worst sample.
        if geometry.nearest_segment_distance(samples, walls, reach) - wall_thickness / 2.0 >= required:
            return
        clearances = geometry.nearest_segment_distances(samples, walls, reach)
    else:
        block = max(1, _OVERLAP_CHECK_BLOCK // len(walls))
        parts = (samples[i : i + block] for i in range(0, len(samples), block))
        clearances = np.concatenate([geometry.point_segment_distances(part, walls).min(axis=1) for part in parts])
    clearances -= wall_thickness / 2.0
    worst = int(np.argmin(clearances))
    if clearances[worst] < required:
        point = samples[worst]
        raise CourseError(
            source,
            "corridor.centerline",
            f"the corridor overlaps itself or turns too sharply for its width near ({point[0]:.3g}, {point[1]:.3g}): "
            f"a wall comes within {max(float(clearances[worst]), 0.0):.3g} m of the centre line, which needs "
            f"{corridor.width / 2.0:g} m (half the width) on both sides. Move the loop's parts apart, "
            "round the corners (`corridor.corner_radius`) or narrow the corridor.",
        )


def check_walls(
    source: str,
    walls: np.ndarray,
    wall_thickness: float,
    corridor: Corridor | None,
    closed_polylines: list[np.ndarray],
    start: StartPose,
) -> None:
    """
    Check a course's walls: their number and extent, and that they hold the start pose in (in the corridor, or
    enclosed by a closed wall polyline).

    :param source: The course file, for the error message
    :param walls: ``(n, 4)`` segments of all the course's walls
    :param wall_thickness: Thickness of the walls [m]
    :param corridor: The course's corridor, if it has one
    :param closed_polylines: The closed wall polylines (used without a corridor)
    :param start: The start pose
    :raises CourseError: naming ``walls``, ``<extent>`` or ``start``
    """
    if len(walls) > MAX_WALL_SEGMENTS:
        raise CourseError(
            source,
            "walls",
            f"the course has {len(walls):,} wall segments (the corridor's two walls and the `walls` polylines "
            f"together); a course may have at most MAX_WALL_SEGMENTS = {MAX_WALL_SEGMENTS:,}.",
        )
    half = wall_thickness / 2.0
    check_extent(source, "<extent>", walls[:, [0, 2]].ravel(), walls[:, [1, 3]].ravel(), half, "the course's walls")
    start_point = np.array([start.x, start.y])
    if corridor is not None:
        distance = corridor.centre_distance(start_point)
        if distance > corridor.width / 2.0:
            raise CourseError(
                source,
                "start",
                f"the start position ({start.x:g}, {start.y:g}) is {distance:.3g} m from the corridor's centre line, "
                f"outside the corridor (at most {corridor.width / 2.0:g} m, half its width).",
            )
    elif not any(geometry.point_in_polygon(start_point, polyline) for polyline in closed_polylines):
        raise CourseError(
            source,
            "walls",
            "open geometry: no closed wall polyline encloses the start pose, so the robot could leave the course. "
            "Close a polyline around the start by repeating its first point at its end.",
        )


def check_obstacle_placements(
    source: str,
    obstacles: Sequence[Obstacle],
    walls: np.ndarray,
    wall_thickness: float,
    corridor: Corridor | None,
    closed_polylines: list[np.ndarray],
    start: StartPose,
) -> None:
    """
    Check that each obstacle's centre lies in the free space (in the corridor, or in the region of the start) and
    that it leaves :data:`~sb3_adc_envs.lidar_course.course.OBSTACLE_START_CLEARANCE` free around the start. Every
    centre's distances to the walls and to the centre line are measured at once (the same numbers as one by one).

    :param source: The course file, for the error message
    :param obstacles: The obstacles, ``obstacles[i]`` in the course file
    :param walls: ``(n, 4)`` segments of the course's walls
    :param wall_thickness: Thickness of the walls [m]
    :param corridor: The course's corridor, if it has one
    :param closed_polylines: The closed wall polylines (used without a corridor)
    :param start: The start pose
    :raises CourseError: naming the first misplaced ``obstacles[i]`` or its ``position``
    """
    if not obstacles:
        return
    centres = np.array([[obstacle.x, obstacle.y] for obstacle in obstacles])
    wall_distances = geometry.point_segment_distances(centres, walls).min(axis=1).tolist()
    if corridor is not None:
        centre_line = geometry.polyline_segments(corridor.centerline, closed=True)
        insides = (geometry.point_segment_distances(centres, centre_line).min(axis=1) <= corridor.width / 2.0).tolist()
    else:
        # Inside the same region as the start: enclosed by the same closed polylines (an island is a hole).
        start_point = np.array([start.x, start.y])
        start_sides = [geometry.point_in_polygon(start_point, polyline) for polyline in closed_polylines]
        sides = list(zip(closed_polylines, start_sides, strict=True))
        insides = [all(geometry.point_in_polygon(centre, polyline) == side for polyline, side in sides) for centre in centres]
    for i, (obstacle, inside, wall_distance) in enumerate(zip(obstacles, insides, wall_distances, strict=True)):
        if not inside or wall_distance <= wall_thickness / 2.0:
            where = "outside the corridor" if corridor is not None and not inside else "outside the free space"
            raise CourseError(
                source,
                f"obstacles[{i}].position",
                f"the {obstacle.shape}'s centre ({obstacle.x:g}, {obstacle.y:g}) is {where}; an obstacle's centre must "
                "lie in the free space the robot drives in (not in a wall).",
            )
        gap = obstacle.distance(start.x, start.y)
        if gap < OBSTACLE_START_CLEARANCE:
            raise CourseError(
                source,
                f"obstacles[{i}]",
                f"the {obstacle.shape} at ({obstacle.x:g}, {obstacle.y:g}) is {gap:.3g} m from the start position "
                f"({start.x:g}, {start.y:g}); obstacles must leave {OBSTACLE_START_CLEARANCE:g} m free around the start.",
            )
