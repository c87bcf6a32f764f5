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
    obstacles:                      # optional: bodies in the free space
      - {shape: box, position: [6.0, 0.3], size: [0.4, 0.6], yaw_deg: 30}
      - {shape: cylinder, position: [8.0, 3.0], radius: 0.15}
      - {shape: wall, position: [4.0, 6.4], length: 0.8, yaw_deg: 90}   # a wall stub, wall_thickness thick
    start: {x: 4.0, y: 0.0, heading_deg: 0.0}

A course needs ``start`` and at least one of ``corridor`` and ``walls``. The robot must not be able to
leave it: the corridor is a closed loop and the start pose must lie inside it, and a course made of
``walls`` only needs a closed polyline around the start pose. An obstacle's centre lies in the free space,
at least :data:`OBSTACLE_START_CLEARANCE` from the start pose; a robot must still be able to drive round a
corridor (checked with the robot's radius by :meth:`Course.check_robot_fits`). Every error names the file
and the field. YAML files are read as YAML 1.2 reads numbers (``-1e300`` is a number, not a string), without
aliases, and at most :data:`MAX_COURSE_FILE_BYTES` long (:mod:`~sb3_adc_envs.lidar_course.course_yaml`).

A small file can describe a huge course, so the sizes that set the cost of loading one are bounded, each
checked before the memory it sets is allocated: the course's extent (:data:`MAX_COURSE_SIDE`), the points of
the centre line and of the walls (:data:`MAX_CENTERLINE_POINTS`, :data:`MAX_WALL_POINTS`), the wall segments
(:data:`MAX_WALL_SEGMENTS`), the obstacles (:data:`MAX_OBSTACLES`) and the distances of the overlap check
(:data:`MAX_OVERLAP_CHECK_DISTANCES`); the passability grid has its own bound
(:data:`~sb3_adc_envs.lidar_course.passability.MAX_GRID_CELLS`). Each error names the limit and the value.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sb3_adc_envs.lidar_course import geometry
from sb3_adc_envs.lidar_course.course_yaml import CourseYamlError, load_course_yaml
from sb3_adc_envs.lidar_course.passability import blocked_corridor_point

#: Folder of the courses shipped with the package.
COURSES_DIR = Path(__file__).resolve().parent.parent / "courses"
#: File extensions a course file may have.
COURSE_SUFFIXES = (".yml", ".yaml", ".json")
#: Wall thickness when a course file does not give one [m].
DEFAULT_WALL_THICKNESS = 0.1

#: Largest course file accepted [bytes]: the shipped ones have about 1 kB, a course at every count limit below
#: about 200 kB, and PyYAML reads about 100 kB/s (the hyperparameter files have the same bound).
MAX_COURSE_FILE_BYTES = 256 * 1024
#: Largest absolute coordinate or size accepted [m].
MAX_COORDINATE = 10_000.0
#: Largest side of a course's bounding box, its walls' thickness included [m]: the shipped courses span at most
#: 19.6 m and the default procedural layouts 17.2 m. The bound keeps the passability grid
#: (:data:`~sb3_adc_envs.lidar_course.passability.MAX_GRID_CELLS`) and the simulation small.
MAX_COURSE_SIDE = 200.0
#: Most points of ``corridor.centerline`` (the shipped courses have at most 14, before rounding the corners).
MAX_CENTERLINE_POINTS = 2_000
#: Most points of all ``walls`` polylines together (the shipped courses have at most 16).
MAX_WALL_POINTS = 2_000
#: Most wall segments of a course, the corridor's two walls (after rounding its corners) included: the shipped
#: courses have at most 324, the default procedural layouts 196.
MAX_WALL_SEGMENTS = 5_000
#: Most obstacles (the shipped courses have at most 8, the default procedural layouts 8).
MAX_OBSTACLES = 500
#: Most point-to-wall distances of the check that a corridor does not overlap itself: centre-line samples
#: (:data:`_OVERLAP_CHECK_SPACING` apart) times wall segments. The shipped courses need at most 412,000 and the
#: default procedural layouts 171,000; the bound keeps the check under a few seconds.
MAX_OVERLAP_CHECK_DISTANCES = 50_000_000
#: Obstacles must leave at least this distance free around the start position [m].
OBSTACLE_START_CLEARANCE = 1.0
#: Shapes of obstacles, and the keys of each.
OBSTACLE_KEYS: dict[str, tuple[str, ...]] = {
    "box": ("shape", "position", "size", "yaw_deg"),
    "cylinder": ("shape", "position", "radius"),
    "wall": ("shape", "position", "length", "thickness", "yaw_deg"),
}

_TOP_LEVEL_KEYS = ("name", "description", "wall_thickness", "corridor", "walls", "obstacles", "start")
_CORRIDOR_KEYS = ("width", "centerline", "corner_radius")
_START_KEYS = ("x", "y", "heading_deg")
# Spacing of the centre-line samples used to check that a corridor does not overlap itself [m].
_OVERLAP_CHECK_SPACING = 0.05
# Relative tolerance of that check (mitred joints put walls slightly further away, never closer).
_OVERLAP_TOLERANCE = 1e-3
# Distances computed at once by that check: a block of samples times the walls (8 MB per temporary array).
_OVERLAP_CHECK_BLOCK = 1_000_000


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
class Obstacle:
    """
    A static body in the free space of a course, as high as the walls.

    :param shape: ``"box"``, ``"cylinder"`` or ``"wall"`` (a wall stub: a box ``thickness`` thick)
    :param x: Position of the centre [m]
    :param y: Position of the centre [m]
    :param length: Extent along the obstacle's own x axis [m] (a cylinder's diameter)
    :param width: Extent along its y axis [m] (a cylinder's diameter, a wall stub's thickness)
    :param yaw: Orientation [rad], counter-clockwise from the course's x axis (0 for a cylinder)
    """

    shape: str
    x: float
    y: float
    length: float
    width: float
    yaw: float = 0.0

    @property
    def bounding_radius(self) -> float:
        """Radius of the smallest circle around the centre that holds the obstacle [m]."""
        if self.shape == "cylinder":
            return self.length / 2.0
        return math.hypot(self.length, self.width) / 2.0

    def distance(self, x: float, y: float) -> float:
        """Distance from a point to the obstacle's surface [m] (0 inside it)."""
        dx, dy = x - self.x, y - self.y
        if self.shape == "cylinder":
            return max(math.hypot(dx, dy) - self.length / 2.0, 0.0)
        cos_yaw, sin_yaw = math.cos(self.yaw), math.sin(self.yaw)
        local_x = abs(cos_yaw * dx + sin_yaw * dy) - self.length / 2.0
        local_y = abs(-sin_yaw * dx + cos_yaw * dy) - self.width / 2.0
        return math.hypot(max(local_x, 0.0), max(local_y, 0.0))

    def footprint(self, n_arc: int = 24) -> np.ndarray:
        """``(n, 2)`` vertices of the outline seen from above (a cylinder's as a ``n_arc``-gon) [m]."""
        if self.shape == "cylinder":
            angles = np.linspace(0.0, 2.0 * math.pi, n_arc, endpoint=False)
            return np.column_stack([self.x + self.length / 2.0 * np.cos(angles), self.y + self.length / 2.0 * np.sin(angles)])
        half = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) * [self.length / 2.0, self.width / 2.0]
        cos_yaw, sin_yaw = math.cos(self.yaw), math.sin(self.yaw)
        return half @ np.array([[cos_yaw, sin_yaw], [-sin_yaw, cos_yaw]]) + [self.x, self.y]


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
    :param obstacles: Static bodies in the free space (see :class:`Obstacle`)
    """

    name: str
    source: str
    walls: np.ndarray
    wall_thickness: float
    start: StartPose
    corridor: Corridor | None = None
    description: str = ""
    obstacles: tuple[Obstacle, ...] = field(default=())

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` of the walls, their thickness included [m]."""
        xs = self.walls[:, [0, 2]]
        ys = self.walls[:, [1, 3]]
        half = self.wall_thickness / 2.0
        return float(xs.min()) - half, float(ys.min()) - half, float(xs.max()) + half, float(ys.max()) + half

    def clearance(self, x: float, y: float) -> float:
        """Distance from a point to the nearest wall face or obstacle [m] (negative inside a wall, 0 in an obstacle)."""
        _, distance = geometry.closest_segment(np.array([x, y]), self.walls)
        clearance = distance - self.wall_thickness / 2.0
        for obstacle in self.obstacles:
            clearance = min(clearance, obstacle.distance(x, y))
        return clearance

    def check_robot_fits(self, robot_radius: float) -> None:
        """
        Check that a round robot of the given radius fits the corridor, does not start on a wall or an obstacle,
        and can drive round a corridor past its obstacles
        (:func:`~sb3_adc_envs.lidar_course.passability.blocked_corridor_point`).

        :param robot_radius: Radius of the robot [m]
        :raises CourseError: naming ``corridor.width``, ``start`` or ``obstacles``
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
                f"{robot_radius:g} m there would be {clearance:.3g} m from the nearest wall face or obstacle (needs more than "
                f"{robot_radius:g} m).",
            )
        if self.corridor is not None and self.obstacles:
            blocked = blocked_corridor_point(self, robot_radius)
            if blocked is not None:
                raise CourseError(
                    self.source,
                    "obstacles",
                    f"the obstacles leave no way round the corridor for a robot of radius {robot_radius:g} m: it is "
                    f"blocked near ({blocked[0]:.3g}, {blocked[1]:.3g}). Leave a gap wider than {2.0 * robot_radius:g} m "
                    "(the robot's diameter) beside every obstacle.",
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
    if len(walls) > MAX_WALL_SEGMENTS:
        raise CourseError(
            source,
            "walls",
            f"the course has {len(walls):,} wall segments (the corridor's two walls and the `walls` polylines "
            f"together); a course may have at most MAX_WALL_SEGMENTS = {MAX_WALL_SEGMENTS:,}.",
        )
    half = wall_thickness / 2.0
    _check_extent(source, "<extent>", walls[:, [0, 2]].ravel(), walls[:, [1, 3]].ravel(), half, "the course's walls")

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
    obstacles = _parse_obstacles(source, data.get("obstacles", []), wall_thickness)
    for i, obstacle in enumerate(obstacles):
        _check_obstacle_placement(
            source, f"obstacles[{i}]", obstacle, walls, wall_thickness, corridor, closed_polylines, start
        )
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
    for i, obstacle in enumerate(parsed):
        _check_obstacle_placement(
            course.source, f"obstacles[{i}]", obstacle, course.walls, course.wall_thickness, course.corridor, [], course.start
        )
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


def _check_extent(source: str, field: str, xs: np.ndarray, ys: np.ndarray, margin: float, what: str) -> None:
    """Refuse points whose bounding box, widened by ``margin`` on every side, has a side over MAX_COURSE_SIDE."""
    width = float(xs.max() - xs.min()) + 2.0 * margin
    height = float(ys.max() - ys.min()) + 2.0 * margin
    if max(width, height) > MAX_COURSE_SIDE:
        raise CourseError(
            source,
            field,
            f"{what} span {width:,.6g} m x {height:,.6g} m; a course must fit in a square of "
            f"MAX_COURSE_SIDE = {MAX_COURSE_SIDE:g} m (its walls' thickness included).",
        )


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


def _parse_corridor(source: str, value: Any, wall_thickness: float) -> Corridor:
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
    _check_extent(source, "corridor", centerline[:, 0], centerline[:, 1], width / 2.0 + wall_thickness, "the corridor's walls")
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
    # Count the samples before drawing them: the distances are samples x walls.
    segments = geometry.polyline_segments(corridor.centerline, closed=True)
    lengths = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
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
    block = max(1, _OVERLAP_CHECK_BLOCK // len(walls))
    clearances = np.concatenate(
        [geometry.point_segment_distances(samples[i : i + block], walls).min(axis=1) for i in range(0, len(samples), block)]
    )
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


def _check_obstacle_placement(
    source: str,
    field: str,
    obstacle: Obstacle,
    walls: np.ndarray,
    wall_thickness: float,
    corridor: Corridor | None,
    closed_polylines: list[np.ndarray],
    start: StartPose,
) -> None:
    centre = np.array([obstacle.x, obstacle.y])
    start_point = np.array([start.x, start.y])
    if corridor is not None:
        _, distance = geometry.closest_segment(centre, geometry.polyline_segments(corridor.centerline, closed=True))
        inside = distance <= corridor.width / 2.0
    else:
        # Inside the same region as the start: enclosed by the same closed polylines (an island is a hole).
        inside = all(
            geometry.point_in_polygon(centre, polyline) == geometry.point_in_polygon(start_point, polyline)
            for polyline in closed_polylines
        )
    _, wall_distance = geometry.closest_segment(centre, walls)
    if not inside or wall_distance <= wall_thickness / 2.0:
        where = "outside the corridor" if corridor is not None and not inside else "outside the free space"
        raise CourseError(
            source,
            f"{field}.position",
            f"the {obstacle.shape}'s centre ({obstacle.x:g}, {obstacle.y:g}) is {where}; an obstacle's centre must lie "
            "in the free space the robot drives in (not in a wall).",
        )
    gap = obstacle.distance(start.x, start.y)
    if gap < OBSTACLE_START_CLEARANCE:
        raise CourseError(
            source,
            field,
            f"the {obstacle.shape} at ({obstacle.x:g}, {obstacle.y:g}) is {gap:.3g} m from the start position "
            f"({start.x:g}, {start.y:g}); obstacles must leave {OBSTACLE_START_CLEARANCE:g} m free around the start.",
        )
