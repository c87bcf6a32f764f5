"""Course files of the lidar obstacle course: loading, validation and the shipped courses.

A course is a small YAML (``.yml``/``.yaml``) or JSON (``.json``) mapping::

    name: my-course                 # optional, defaults to the file name
    description: A closed corridor  # optional
    wall_thickness: 0.1             # optional [m], default 0.1
    corridor:                       # a closed-loop corridor around a centre line ...
      width: 1.4                    #   free width between the wall faces [m]
      corner_radius: 1.5            #   optional: round every corner with an arc of this radius [m]
      centerline: [[0, 0], [8, 0], [8, 6], [0, 6]]   # the last point joins the first
    walls:                          # ... and/or wall polylines (wall centre lines) [m]
      - [[-1, -1], [9, -1], [9, 7], [-1, 7], [-1, -1]]   # closed: the last point repeats the first
    start: {x: 4.0, y: 0.0, heading_deg: 0.0}

A course needs ``start`` and at least one of ``corridor`` and ``walls``. The robot must not be able to
leave it: the corridor is a closed loop and the start pose must lie inside it, and a course made of
``walls`` only needs a closed polyline around the start pose. Every error names the file and the field.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sb3_adc_envs.lidar_course import geometry

#: Folder of the courses shipped with the package.
COURSES_DIR = Path(__file__).resolve().parent.parent / "courses"
#: File extensions a course file may have.
COURSE_SUFFIXES = (".yml", ".yaml", ".json")
#: Wall thickness when a course file does not give one [m].
DEFAULT_WALL_THICKNESS = 0.1

_TOP_LEVEL_KEYS = ("name", "description", "wall_thickness", "corridor", "walls", "start")
_CORRIDOR_KEYS = ("width", "centerline", "corner_radius")
_START_KEYS = ("x", "y", "heading_deg")
# Spacing of the centre-line samples used to check that a corridor does not overlap itself [m].
_OVERLAP_CHECK_SPACING = 0.05
# Relative tolerance of that check (mitred joints put walls slightly further away, never closer).
_OVERLAP_TOLERANCE = 1e-3


class CourseError(ValueError):
    """
    An invalid course file; the message names the file and the field.

    :param source: The course file (or ``"<course>"`` for a course built in memory)
    :param field: The offending field, as a path such as ``corridor.width`` or ``walls[2][1]``
    :param message: What is wrong, and what is accepted
    """

    def __init__(self, source: str, field: str, message: str):
        self.source = source
        self.field = field
        super().__init__(f"Course file {source!r}, field `{field}`: {message}")


@dataclass(frozen=True)
class StartPose:
    """
    Pose at which the robot starts an episode.

    :param x: Position [m]
    :param y: Position [m]
    :param heading: Heading [rad], counter-clockwise from the x axis
    """

    x: float
    y: float
    heading: float


@dataclass(frozen=True)
class Corridor:
    """
    A closed-loop corridor.

    :param centerline: ``(n, 2)`` vertices of the centre line (after rounding the corners), a closed loop
    :param width: Free width between the wall faces [m]
    """

    centerline: np.ndarray
    width: float


@dataclass(frozen=True)
class Course:
    """
    A validated course: wall segments and a start pose.

    :param name: Name of the course
    :param source: Where it was loaded from (a path, or ``"<course>"``)
    :param walls: ``(n, 4)`` wall centre-line segments ``(x0, y0, x1, y1)`` [m]
    :param wall_thickness: Thickness of every wall [m]
    :param start: Start pose of the robot
    :param corridor: The corridor the walls were built around, if the course has one
    :param description: Free text
    """

    name: str
    source: str
    walls: np.ndarray
    wall_thickness: float
    start: StartPose
    corridor: Corridor | None = None
    description: str = ""

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` of the walls, their thickness included [m]."""
        xs = self.walls[:, [0, 2]]
        ys = self.walls[:, [1, 3]]
        half = self.wall_thickness / 2.0
        return float(xs.min()) - half, float(ys.min()) - half, float(xs.max()) + half, float(ys.max()) + half

    def clearance(self, x: float, y: float) -> float:
        """Distance from a point to the nearest wall face [m] (negative inside a wall)."""
        _, distance = geometry.closest_segment(np.array([x, y]), self.walls)
        return distance - self.wall_thickness / 2.0

    def check_robot_fits(self, robot_radius: float) -> None:
        """
        Check that a round robot of the given radius fits the corridor and does not start on a wall.

        :param robot_radius: Radius of the robot [m]
        :raises CourseError: naming ``corridor.width`` or ``start``
        """
        if self.corridor is not None and self.corridor.width <= 2.0 * robot_radius:
            raise CourseError(
                self.source,
                "corridor.width",
                f"the corridor ({self.corridor.width:g} m) is too narrow for a robot of radius {robot_radius:g} m "
                f"(the width must be more than {2.0 * robot_radius:g} m).",
            )
        clearance = self.clearance(self.start.x, self.start.y)
        if clearance <= robot_radius:
            raise CourseError(
                self.source,
                "start",
                f"the start pose ({self.start.x:g}, {self.start.y:g}) overlaps a wall: a robot of radius "
                f"{robot_radius:g} m there would be {clearance:.3g} m from the nearest wall face (needs more than "
                f"{robot_radius:g} m).",
            )


def shipped_courses() -> list[str]:
    """Names of the courses shipped with the package (accepted as ``course=<name>``)."""
    return sorted(path.stem for path in COURSES_DIR.glob("*.yml"))


def resolve_course_path(course: str | os.PathLike[str]) -> Path:
    """
    The file of a course given by shipped name or by path.

    :param course: A shipped course name (see :func:`shipped_courses`) or the path of a course file
    :raises FileNotFoundError: naming the parameter, the shipped names and the accepted suffixes
    """
    path = Path(course)
    if path.suffix == "" and len(path.parts) == 1:
        shipped = COURSES_DIR / f"{path.name}.yml"
        if shipped.is_file():
            return shipped
    if path.is_file():
        return path
    raise FileNotFoundError(
        f"`course`: {str(course)!r} is neither a shipped course ({', '.join(shipped_courses())}) nor an existing "
        f"course file ({', '.join(COURSE_SUFFIXES)})."
    )


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
    text = path.read_text(encoding="utf-8")
    try:
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as error:
        raise CourseError(source, "<file>", f"cannot be parsed: {error}") from error
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
        corridor = _parse_corridor(source, data["corridor"], wall_thickness)
        segments.extend(_corridor_walls(corridor, wall_thickness))
    closed_polylines: list[np.ndarray] = []
    if "walls" in data:
        polylines = _parse_walls(source, data["walls"])
        for polyline in polylines:
            segments.append(geometry.polyline_segments(polyline, closed=False))
            if len(polyline) >= 4 and np.allclose(polyline[0], polyline[-1]):
                closed_polylines.append(polyline)
    walls = np.vstack(segments)

    start_point = np.array([start.x, start.y])
    if corridor is not None:
        _, distance = geometry.closest_segment(start_point, geometry.polyline_segments(corridor.centerline, closed=True))
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
    return Course(
        name=name,
        source=source,
        walls=walls,
        wall_thickness=wall_thickness,
        start=start,
        corridor=corridor,
        description=description,
    )


def _check_keys(source: str, field: str, mapping: dict[Any, Any], accepted: tuple[str, ...]) -> None:
    unknown = [key for key in mapping if key not in accepted]
    if unknown:
        raise CourseError(source, field, f"unknown key(s) {', '.join(map(repr, unknown))}; accepted: {', '.join(accepted)}.")


def _number(source: str, field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CourseError(source, field, f"must be a number, got {value!r}.")
    if not math.isfinite(value):
        raise CourseError(source, field, f"must be finite, got {value!r}.")
    return float(value)


def _positive(source: str, field: str, value: Any) -> float:
    number = _number(source, field, value)
    if number <= 0.0:
        raise CourseError(source, field, f"must be > 0, got {value!r}.")
    return number


def _points(source: str, field: str, value: Any, min_points: int) -> np.ndarray:
    if not isinstance(value, list) or len(value) < min_points:
        raise CourseError(source, field, f"must be a list of at least {min_points} [x, y] points, got {value!r}.")
    points = np.empty((len(value), 2))
    for i, point in enumerate(value):
        if not isinstance(point, list) or len(point) != 2:
            raise CourseError(source, f"{field}[{i}]", f"must be a point [x, y], got {point!r}.")
        points[i] = [_number(source, f"{field}[{i}][{j}]", coordinate) for j, coordinate in enumerate(point)]
    steps = np.hypot(*np.diff(points, axis=0).T)
    if np.any(steps <= 1e-9):
        i = int(np.argmax(steps <= 1e-9)) + 1
        raise CourseError(source, f"{field}[{i}]", "repeats the point before it; consecutive points must differ.")
    return points


def _parse_start(source: str, value: Any) -> StartPose:
    if not isinstance(value, dict):
        raise CourseError(source, "start", f"must be a mapping {{x: ..., y: ..., heading_deg: ...}}, got {value!r}.")
    _check_keys(source, "start", value, _START_KEYS)
    for key in _START_KEYS:
        if key not in value:
            raise CourseError(source, f"start.{key}", "missing; the start pose needs x, y and heading_deg.")
    return StartPose(
        x=_number(source, "start.x", value["x"]),
        y=_number(source, "start.y", value["y"]),
        heading=math.radians(_number(source, "start.heading_deg", value["heading_deg"])),
    )


def _parse_corridor(source: str, value: Any, wall_thickness: float) -> Corridor:
    if not isinstance(value, dict):
        raise CourseError(source, "corridor", f"must be a mapping with keys {', '.join(_CORRIDOR_KEYS)}, got {value!r}.")
    _check_keys(source, "corridor", value, _CORRIDOR_KEYS)
    for key in ("width", "centerline"):
        if key not in value:
            raise CourseError(source, f"corridor.{key}", "missing; a corridor needs a width and a centerline.")
    width = _positive(source, "corridor.width", value["width"])
    centerline = _points(source, "corridor.centerline", value["centerline"], min_points=3)
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
    corridor = Corridor(centerline=centerline, width=width)
    _check_corridor_does_not_overlap(source, corridor, wall_thickness)
    return corridor


def _corridor_walls(corridor: Corridor, wall_thickness: float) -> list[np.ndarray]:
    # Wall centre lines lie half a wall thickness beyond the free width, on both sides.
    offset = corridor.width / 2.0 + wall_thickness / 2.0
    return [
        geometry.polyline_segments(geometry.offset_closed_polyline(corridor.centerline, side * offset), closed=True)
        for side in (1.0, -1.0)
    ]


def _check_corridor_does_not_overlap(source: str, corridor: Corridor, wall_thickness: float) -> None:
    # Every point of the centre line must be at least half the free width from every wall face; a loop
    # that comes back near itself, or a corner too sharp for the width, puts a wall closer than that.
    walls = np.vstack(_corridor_walls(corridor, wall_thickness))
    required = corridor.width / 2.0 * (1.0 - _OVERLAP_TOLERANCE)
    samples = geometry.sample_polyline(corridor.centerline, _OVERLAP_CHECK_SPACING, closed=True)
    clearances = geometry.point_segment_distances(samples, walls).min(axis=1) - wall_thickness / 2.0
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


def _parse_walls(source: str, value: Any) -> list[np.ndarray]:
    if not isinstance(value, list) or not value:
        raise CourseError(source, "walls", f"must be a non-empty list of polylines [[x, y], [x, y], ...], got {value!r}.")
    return [_points(source, f"walls[{i}]", polyline, min_points=2) for i, polyline in enumerate(value)]
