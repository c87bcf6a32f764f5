"""Courses of the lidar obstacle course: the file format, its limits, the validated course and the shipped courses.

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
and the field. :func:`~sb3_adc_envs.lidar_course.course_parsing.load_course` and
:func:`~sb3_adc_envs.lidar_course.course_parsing.course_from_dict` build a :class:`Course`. YAML files are read as
YAML 1.2 reads numbers (``-1e300`` is a number, not a string), without aliases, and at most
:data:`MAX_COURSE_FILE_BYTES` long (:mod:`~sb3_adc_envs.lidar_course.course_yaml`).

A small file can describe a huge course, so the sizes that set the cost of loading one are bounded, each
checked before the memory it sets is allocated: the course's extent (:data:`MAX_COURSE_SIDE`), the points of
the centre line and of the walls (:data:`MAX_CENTERLINE_POINTS`, :data:`MAX_WALL_POINTS`), the wall segments
(:data:`MAX_WALL_SEGMENTS`), the obstacles (:data:`MAX_OBSTACLES`) and the distances of the overlap check
(:data:`MAX_OVERLAP_CHECK_DISTANCES`); the passability grid has its own bound
(:data:`~sb3_adc_envs.lidar_course.passability.MAX_GRID_CELLS`). Each error names the limit and the value.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sb3_adc_envs.lidar_course import geometry
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
#: (5 cm apart, :mod:`~sb3_adc_envs.lidar_course.course_checks`) times wall segments. The shipped courses need at
#: most 412,000 and the default procedural layouts 171,000; the bound keeps the check under a few seconds.
MAX_OVERLAP_CHECK_DISTANCES = 50_000_000
#: Obstacles must leave at least this distance free around the start position [m].
OBSTACLE_START_CLEARANCE = 1.0
#: Shapes of obstacles, and the keys of each.
OBSTACLE_KEYS: dict[str, tuple[str, ...]] = {
    "box": ("shape", "position", "size", "yaw_deg"),
    "cylinder": ("shape", "position", "radius"),
    "wall": ("shape", "position", "length", "thickness", "yaw_deg"),
}


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

    def centre_distance(self, point: np.ndarray) -> float:
        """Distance from a ``(2,)`` point to the centre line [m] (at most half the width inside the corridor)."""
        return geometry.closest_segment(point, geometry.polyline_segments(self.centerline, closed=True))[1]


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
