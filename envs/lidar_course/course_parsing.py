"""Building a :class:`~sb3_adc_envs.lidar_course.course.Course` from a course file or its mapping, field by field.

The format and the limits are those of :mod:`~sb3_adc_envs.lidar_course.course`; every error is a
:class:`~sb3_adc_envs.lidar_course.course.CourseError` that names the file and the field.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from typing import Any

import numpy as np
import yaml

from sb3_adc_envs.lidar_course import geometry
from sb3_adc_envs.lidar_course.course import (
    COURSE_SUFFIXES,
    DEFAULT_WALL_THICKNESS,
    MAX_CENTERLINE_POINTS,
    MAX_COORDINATE,
    MAX_COURSE_FILE_BYTES,
    MAX_OBSTACLES,
    MAX_WALL_POINTS,
    MAX_WALL_SEGMENTS,
    OBSTACLE_KEYS,
    Corridor,
    Course,
    CourseError,
    Obstacle,
    StartPose,
    resolve_course_path,
)
from sb3_adc_envs.lidar_course.course_checks import (
    check_corridor_does_not_overlap,
    check_extent,
    check_obstacle_placements,
    check_walls,
    corridor_walls,
)
from sb3_adc_envs.lidar_course.course_yaml import CourseYamlError, load_course_yaml

_TOP_LEVEL_KEYS = ("name", "description", "wall_thickness", "corridor", "walls", "obstacles", "start")
_CORRIDOR_KEYS = ("width", "centerline", "corner_radius")
_START_KEYS = ("x", "y", "heading_deg")


def load_course(course: str | os.PathLike[str]) -> Course:
    """
    Load and validate a course.

    :param course: A shipped course name such as ``"training"`` or the path of a YAML/JSON course file
    :raises FileNotFoundError: if no such course exists
    :raises CourseError: if the file is not a valid course (the message names the file and the field)
    """
    path = resolve_course_path(course)
    source = str(path)
    if path.suffix not in COURSE_SUFFIXES:
        raise CourseError(source, "<file>", f"unknown file type {path.suffix!r}; accepted: {', '.join(COURSE_SUFFIXES)}.")
    size = path.stat().st_size
    if size > MAX_COURSE_FILE_BYTES:
        raise CourseError(
            source,
            "<file>",
            f"is {size:,} bytes long; a course file may have at most MAX_COURSE_FILE_BYTES = {MAX_COURSE_FILE_BYTES:,}.",
        )
    with path.open("rb") as stream:
        raw = stream.read(MAX_COURSE_FILE_BYTES + 1)  # the file may have grown since stat()
    if len(raw) > MAX_COURSE_FILE_BYTES:
        raise CourseError(source, "<file>", f"is longer than MAX_COURSE_FILE_BYTES = {MAX_COURSE_FILE_BYTES:,} bytes.")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise CourseError(
            source, "<file>", f"is not a UTF-8 text file ({error.reason} at byte {error.start}); save it as UTF-8."
        ) from None
    try:
        data = json.loads(text) if path.suffix == ".json" else load_course_yaml(text)
    except CourseYamlError as error:
        raise CourseError(source, "<file>", f"is over a limit of sb3_adc_envs.lidar_course.course_yaml: {error}") from None
    except (json.JSONDecodeError, yaml.YAMLError, RecursionError) as error:
        raise CourseError(source, "<file>", f"cannot be parsed: {str(error)[:500]}") from None
    return course_from_dict(data, source=source, default_name=path.stem)


def course_from_dict(data: Any, source: str = "<course>", default_name: str = "course") -> Course:
    """
    Build and validate a course from its mapping (the parsed content of a course file).

    :param data: The mapping (see the module documentation for its fields)
    :param source: Name of the file it came from, used in error messages
    :param default_name: Name of the course when the mapping has no ``name``
    :raises CourseError: if the mapping is not a valid course
    """
    if not isinstance(data, dict):
        raise CourseError(source, "<root>", f"a course must be a mapping with keys {', '.join(_TOP_LEVEL_KEYS)}.")
    _check_keys(source, "<root>", data, _TOP_LEVEL_KEYS)
    name = str(data.get("name", default_name))
    description = str(data.get("description", ""))
    wall_thickness = _positive(source, "wall_thickness", data.get("wall_thickness", DEFAULT_WALL_THICKNESS))
    if "start" not in data:
        raise CourseError(source, "start", "missing; give the start pose as {x: ..., y: ..., heading_deg: ...}.")
    start = _parse_start(source, data["start"])
    if "corridor" not in data and "walls" not in data:
        raise CourseError(source, "corridor", "a course needs a `corridor`, `walls`, or both; neither is given.")

    segments: list[np.ndarray] = []
    corridor = None
    if "corridor" in data:
        corridor, corridor_segments = _parse_corridor(source, data["corridor"], wall_thickness)
        segments.append(corridor_segments)
    closed_polylines: list[np.ndarray] = []
    if "walls" in data:
        polylines = _parse_walls(source, data["walls"])
        for polyline in polylines:
            segments.append(geometry.polyline_segments(polyline, closed=False))
            if len(polyline) >= 4 and np.allclose(polyline[0], polyline[-1]):
                closed_polylines.append(polyline)
    walls = np.vstack(segments)
    check_walls(source, walls, wall_thickness, corridor, closed_polylines, start)
    obstacles = _parse_obstacles(source, data.get("obstacles", []), wall_thickness)
    check_obstacle_placements(source, obstacles, walls, wall_thickness, corridor, closed_polylines, start)
    return Course(
        name=name,
        source=source,
        walls=walls,
        wall_thickness=wall_thickness,
        start=start,
        corridor=corridor,
        description=description,
        obstacles=tuple(obstacles),
    )


def with_obstacles(course: Course, obstacles: Any) -> Course:
    """
    A copy of a validated corridor course with obstacles added, parsed and checked as a course file's ``obstacles``
    (without validating the corridor again).

    :param course: A course with a ``corridor`` and no obstacles
    :param obstacles: A list of obstacle mappings, in the format of a course file
    :raises CourseError: as :func:`course_from_dict`, naming ``obstacles[i]`` and its fields
    :raises ValueError: if the course has no corridor or already has obstacles
    """
    if course.corridor is None or course.obstacles:
        raise ValueError(f"`course`: {course.name!r} must have a corridor and no obstacles yet.")
    parsed = _parse_obstacles(course.source, obstacles, course.wall_thickness)
    check_obstacle_placements(course.source, parsed, course.walls, course.wall_thickness, course.corridor, [], course.start)
    return dataclasses.replace(course, obstacles=tuple(parsed))


def _check_keys(source: str, field: str, mapping: dict[Any, Any], accepted: tuple[str, ...]) -> None:
    unknown = [key for key in mapping if key not in accepted]
    if unknown:
        raise CourseError(source, field, f"unknown key(s) {', '.join(map(repr, unknown))}; accepted: {', '.join(accepted)}.")


def _number(source: str, field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CourseError(source, field, f"must be a number, got {_short_repr(value)}.")
    if not math.isfinite(value):
        raise CourseError(source, field, f"must be finite, got {value!r}.")
    if abs(value) > MAX_COORDINATE:
        raise CourseError(source, field, f"out of range: {value!r}; coordinates and sizes lie within ±{MAX_COORDINATE:g} m.")
    return float(value)


def _short_repr(value: Any, limit: int = 200) -> str:
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _positive(source: str, field: str, value: Any) -> float:
    number = _number(source, field, value)
    if number <= 0.0:
        raise CourseError(source, field, f"must be > 0, got {value!r}.")
    return number


def _points(source: str, field: str, value: Any, min_points: int) -> np.ndarray:
    if not isinstance(value, list) or len(value) < min_points:
        raise CourseError(source, field, f"must be a list of at least {min_points} [x, y] points, got {_short_repr(value)}.")
    points = np.empty((len(value), 2))
    for i, point in enumerate(value):
        if not isinstance(point, list) or len(point) != 2:
            raise CourseError(source, f"{field}[{i}]", f"must be a point [x, y], got {_short_repr(point)}.")
        points[i] = [_number(source, f"{field}[{i}][{j}]", coordinate) for j, coordinate in enumerate(point)]
    steps = np.hypot(*np.diff(points, axis=0).T)
    if np.any(steps <= 1e-9):
        i = int(np.argmax(steps <= 1e-9)) + 1
        raise CourseError(source, f"{field}[{i}]", "repeats the point before it; consecutive points must differ.")
    return points


def _parse_start(source: str, value: Any) -> StartPose:
    if not isinstance(value, dict):
        raise CourseError(
            source, "start", f"must be a mapping {{x: ..., y: ..., heading_deg: ...}}, got {_short_repr(value)}."
        )
    _check_keys(source, "start", value, _START_KEYS)
    for key in _START_KEYS:
        if key not in value:
            raise CourseError(source, f"start.{key}", "missing; the start pose needs x, y and heading_deg.")
    return StartPose(
        x=_number(source, "start.x", value["x"]),
        y=_number(source, "start.y", value["y"]),
        heading=math.radians(_number(source, "start.heading_deg", value["heading_deg"])),
    )


def _parse_corridor(source: str, value: Any, wall_thickness: float) -> tuple[Corridor, np.ndarray]:
    # The corridor and the segments of its two walls.
    if not isinstance(value, dict):
        raise CourseError(
            source, "corridor", f"must be a mapping with keys {', '.join(_CORRIDOR_KEYS)}, got {_short_repr(value)}."
        )
    _check_keys(source, "corridor", value, _CORRIDOR_KEYS)
    for key in ("width", "centerline"):
        if key not in value:
            raise CourseError(source, f"corridor.{key}", "missing; a corridor needs a width and a centerline.")
    width = _positive(source, "corridor.width", value["width"])
    points = value["centerline"]
    if isinstance(points, list) and len(points) > MAX_CENTERLINE_POINTS:
        raise CourseError(
            source,
            "corridor.centerline",
            f"has {len(points):,} points; a centre line may have at most MAX_CENTERLINE_POINTS = {MAX_CENTERLINE_POINTS:,}.",
        )
    centerline = _points(source, "corridor.centerline", points, min_points=3)
    # The walls lie half the width and a wall thickness beyond the centre line (further at sharp corners, which
    # the overlap check refuses); the whole course is checked again once its walls are built.
    check_extent(source, "corridor", centerline[:, 0], centerline[:, 1], width / 2.0 + wall_thickness, "the corridor's walls")
    if np.allclose(centerline[0], centerline[-1]):
        centerline = centerline[:-1]  # the loop is closed implicitly; a repeated first point is allowed
    if len(centerline) < 3:
        raise CourseError(source, "corridor.centerline", "a closed corridor needs at least 3 distinct points.")
    if "corner_radius" in value:
        radius = _positive(source, "corridor.corner_radius", value["corner_radius"])
        try:
            centerline = geometry.round_corners(centerline, radius)
        except ValueError as error:
            raise CourseError(source, "corridor.corner_radius", f"too large: {error}.") from error
        if 2 * len(centerline) > MAX_WALL_SEGMENTS:
            raise CourseError(
                source,
                "corridor.corner_radius",
                f"rounding the corners gives the corridor {2 * len(centerline):,} wall segments; a course may have "
                f"at most MAX_WALL_SEGMENTS = {MAX_WALL_SEGMENTS:,}. Give the centre line fewer corners.",
            )
    corridor = Corridor(centerline=centerline, width=width)
    walls = np.vstack(corridor_walls(corridor, wall_thickness))
    check_corridor_does_not_overlap(source, corridor, walls, wall_thickness)
    return corridor, walls


def _parse_walls(source: str, value: Any) -> list[np.ndarray]:
    if not isinstance(value, list) or not value:
        raise CourseError(
            source, "walls", f"must be a non-empty list of polylines [[x, y], [x, y], ...], got {_short_repr(value)}."
        )
    n_points = sum(len(polyline) if isinstance(polyline, list) else 1 for polyline in value)
    if n_points > MAX_WALL_POINTS:
        raise CourseError(
            source,
            "walls",
            f"has {n_points:,} points in all; the wall polylines may have at most MAX_WALL_POINTS = {MAX_WALL_POINTS:,}.",
        )
    return [_points(source, f"walls[{i}]", polyline, min_points=2) for i, polyline in enumerate(value)]


def _parse_obstacles(source: str, value: Any, wall_thickness: float) -> list[Obstacle]:
    if not isinstance(value, list):
        raise CourseError(
            source,
            "obstacles",
            f"must be a list of obstacles {{shape: ..., position: [x, y], ...}}, got {_short_repr(value)}.",
        )
    if len(value) > MAX_OBSTACLES:
        raise CourseError(
            source, "obstacles", f"has {len(value):,} obstacles; a course may have at most MAX_OBSTACLES = {MAX_OBSTACLES:,}."
        )
    return [_parse_obstacle(source, f"obstacles[{i}]", item, wall_thickness) for i, item in enumerate(value)]


def _parse_obstacle(source: str, field: str, value: Any, wall_thickness: float) -> Obstacle:
    shapes = ", ".join(OBSTACLE_KEYS)
    if not isinstance(value, dict):
        raise CourseError(
            source, field, f"must be a mapping {{shape: {shapes}, position: [x, y], ...}}, got {_short_repr(value)}."
        )
    shape = value.get("shape")
    if not isinstance(shape, str) or shape not in OBSTACLE_KEYS:
        raise CourseError(source, f"{field}.shape", f"must be one of {shapes}, got {_short_repr(shape)}.")
    _check_keys(source, field, value, OBSTACLE_KEYS[shape])
    required = {"box": ("position", "size"), "cylinder": ("position", "radius"), "wall": ("position", "length")}[shape]
    for key in required:
        if key not in value:
            raise CourseError(source, f"{field}.{key}", f"missing; a {shape} needs {' and '.join(required)}.")
    position = value["position"]
    if not isinstance(position, list) or len(position) != 2:
        raise CourseError(source, f"{field}.position", f"must be a point [x, y], got {_short_repr(position)}.")
    x, y = (_number(source, f"{field}.position[{j}]", coordinate) for j, coordinate in enumerate(position))
    yaw = math.radians(_number(source, f"{field}.yaw_deg", value.get("yaw_deg", 0.0)))
    if shape == "cylinder":
        diameter = 2.0 * _positive(source, f"{field}.radius", value["radius"])
        return Obstacle("cylinder", x, y, diameter, diameter)
    if shape == "wall":
        length = _positive(source, f"{field}.length", value["length"])
        thickness = _positive(source, f"{field}.thickness", value.get("thickness", wall_thickness))
        return Obstacle("wall", x, y, length, thickness, yaw)
    size = value["size"]
    if not isinstance(size, list) or len(size) != 2:
        raise CourseError(source, f"{field}.size", f"must be [length, width] [m], got {_short_repr(size)}.")
    length, width = (_positive(source, f"{field}.size[{j}]", extent) for j, extent in enumerate(size))
    return Obstacle("box", x, y, length, width, yaw)
