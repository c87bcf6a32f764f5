"""Procedural courses: closed corridors of random shape and width with random obstacles, drawn from a generator.

A layout is a function of one integer, its *layout seed*: :meth:`CourseGenerator.generate` draws everything from
``numpy.random.default_rng(layout_seed)``, so a layout seed names a layout on every machine. The environment
draws the layout seed of each episode from its own seeded generator (Procgen's and MetaDrive's protocol: a range
of layout seeds for training, a disjoint range held out for evaluation).

The corridor's centre line is a star-shaped polygon (``n_corners`` corners at jittered, evenly spread angles
and random distances from the loop's centre), driven clockwise or counter-clockwise, its corners rounded with
``corner_radius``; a draw whose corridor overlaps itself is redrawn. The robot starts in the middle of the
longest straight, heading along it. Obstacles (boxes, cylinders and wall stubs) stand at random places along
the loop, at least ``obstacle_spacing`` apart along the centre line and ``start_clearance`` ahead of the start
(2.5 m behind it). Each one leaves a gap of at least the robot's diameter plus ``gap_margin`` on one side,
by construction: across the corridor an obstacle covers at most ``width - gap`` from one wall, and since
obstacles are ``obstacle_spacing`` apart along the loop, no two of them close the corridor together.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sb3_adc_envs.lidar_course import geometry
from sb3_adc_envs.lidar_course.course import MAX_CENTERLINE_POINTS, MAX_COORDINATE, Corridor, Course, CourseError, StartPose
from sb3_adc_envs.lidar_course.course_checks import (
    check_corridor_does_not_overlap,
    check_extent,
    check_walls,
    corridor_walls,
)
from sb3_adc_envs.lidar_course.course_parsing import with_obstacles

#: Draws of a corridor before giving up (a draw is redrawn when the corridor overlaps itself).
_MAX_SHAPE_DRAWS = 200
#: Draws of an obstacle's place along the loop before leaving it out (places must be `obstacle_spacing` apart).
_MAX_PLACE_DRAWS = 30
#: Obstacles' centres stay this far inside the wall faces [m].
_INSIDE = 0.05
#: Obstacles' centres stay this far behind the start along the loop [m] (the loop comes back to the start).
_BEHIND_START = 2.5


def _check_range(name: str, value: tuple[float, float], low: float, integer: bool = False) -> None:
    if (
        not isinstance(value, (tuple, list))
        or len(value) != 2
        or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in value)
        or (integer and any(not float(v).is_integer() for v in value))
        or not low <= value[0] <= value[1]
    ):
        kind = "integers" if integer else "numbers"
        raise ValueError(f"`{name}` must be a pair (min, max) of {kind} with {low:g} <= min <= max, got {value!r}.")


@dataclass(frozen=True)
class CourseGenerator:
    """
    The distribution of procedural courses (every range is ``(min, max)``, drawn uniformly).

    :param n_corners: Corners of the centre line's polygon, before rounding
    :param loop_radius: Distance of the polygon's corners from the loop's centre [m]
    :param width: Free width of the corridor [m]
    :param corner_radius: Radius of the arcs that round the corners [m]; keep it above the robot's smallest
        turning radius (0.95 m by default) for a corridor that can be driven along its centre line
    :param n_obstacles: Obstacles per course (fewer where the loop is too short to space them)
    :param cylinder_radius: Radius of the cylinders [m]
    :param box_side: Length and width of the boxes [m]
    :param gap_margin: The gap beside every obstacle is at least the robot's diameter plus this [m]
    :param obstacle_spacing: Smallest distance between obstacles along the centre line [m]
    :param start_clearance: Obstacles stand at least this far ahead of the start along the centre line [m]
    :param wall_thickness: Thickness of the walls and of the wall stubs [m]
    """

    n_corners: tuple[int, int] = (5, 9)
    loop_radius: tuple[float, float] = (2.5, 8.0)
    width: tuple[float, float] = (1.2, 2.2)
    corner_radius: tuple[float, float] = (1.0, 1.6)
    n_obstacles: tuple[int, int] = (4, 8)
    cylinder_radius: tuple[float, float] = (0.05, 0.35)
    box_side: tuple[float, float] = (0.1, 0.7)
    gap_margin: float = 0.25
    obstacle_spacing: float = 3.0
    start_clearance: float = 3.0
    wall_thickness: float = 0.1

    def __post_init__(self) -> None:
        _check_range("n_corners", self.n_corners, 3, integer=True)
        _check_range("n_obstacles", self.n_obstacles, 0, integer=True)
        for name in ("loop_radius", "width", "corner_radius", "cylinder_radius", "box_side"):
            _check_range(name, getattr(self, name), 1e-6)
        for name in ("n_corners", "n_obstacles", "loop_radius", "width", "corner_radius", "cylinder_radius", "box_side"):
            # Tuples, also when given as lists (from a YAML file): a generator is hashable, a key of the layout cache.
            object.__setattr__(self, name, tuple(getattr(self, name)))
        for name in ("gap_margin", "obstacle_spacing", "start_clearance", "wall_thickness"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"`{name}` must be a finite number > 0, got {value!r}.")

    def min_gap(self, robot_radius: float) -> float:
        """The narrowest gap an obstacle may leave: the robot's diameter plus ``gap_margin`` [m]."""
        return 2.0 * robot_radius + self.gap_margin

    def check_robot_fits(self, robot_radius: float) -> None:
        """
        Check that every corridor of the distribution leaves a robot of this radius a gap beside an obstacle.

        :raises ValueError: naming ``width``, if the narrowest corridor is too narrow
        """
        if self.width[0] < self.min_gap(robot_radius) + 2.0 * _INSIDE:
            raise ValueError(
                f"`width`: the narrowest corridor ({self.width[0]:g} m) leaves no gap of {self.min_gap(robot_radius):g} m "
                f"(the diameter of a robot of radius {robot_radius:g} m plus gap_margin) beside an obstacle."
            )

    def generate(self, layout_seed: int, robot_radius: float = 0.15) -> Course:
        """
        The layout of one layout seed.

        :param layout_seed: Any integer >= 0; the same seed gives the same course
        :param robot_radius: Radius of the robot the gaps are sized for [m]
        :return: A validated course named ``procedural-<layout_seed>``
        """
        rng = np.random.default_rng(layout_seed)
        corridor = self._corridor(rng, layout_seed)
        assert corridor.corridor is not None
        obstacles = self._obstacles(rng, corridor.corridor.centerline, corridor.corridor.width, robot_radius)
        while True:
            try:
                return with_obstacles(corridor, obstacles)
            except CourseError as error:
                # An obstacle where the loop passes near the start: leave it out.
                if not error.field.startswith("obstacles["):
                    raise
                del obstacles[int(error.field[len("obstacles[") :].split("]")[0])]

    def _corridor(self, rng: np.random.Generator, layout_seed: int) -> Course:
        for _ in range(_MAX_SHAPE_DRAWS):
            n = int(rng.integers(self.n_corners[0], self.n_corners[1] + 1))
            step = 2.0 * math.pi / n
            angles = step * np.arange(n) + rng.uniform(-0.3, 0.3, n) * step
            radii = rng.uniform(*self.loop_radius, n)
            corners = radii[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])
            if rng.random() < 0.5:
                corners = corners[::-1]  # clockwise
            width = float(rng.uniform(*self.width))
            try:
                centerline = geometry.round_corners(corners, float(rng.uniform(*self.corner_radius)))
            except ValueError:
                continue  # an edge too short for its arcs
            # Start in the middle of the longest straight, so the loop begins with the centre line's order.
            segments = geometry.polyline_segments(centerline, closed=True)
            longest = int(np.argmax(geometry.segment_lengths(segments)))
            middle = (segments[longest, :2] + segments[longest, 2:]) / 2.0
            first = (longest + 1) % len(centerline)  # np.roll(centerline, -(longest + 1), axis=0), faster
            centerline = np.vstack([middle, centerline[first:], centerline[:first]])
            heading = math.degrees(
                math.atan2(segments[longest, 3] - segments[longest, 1], segments[longest, 2] - segments[longest, 0])
            )
            data: dict[str, Any] = {
                "name": f"procedural-{layout_seed}",
                "description": "Procedural course (sb3_adc_envs.lidar_course.procedural).",
                "wall_thickness": self.wall_thickness,
                "corridor": {"width": width, "centerline": centerline.tolist()},
                "start": {"x": float(middle[0]), "y": float(middle[1]), "heading_deg": heading},
            }
            try:
                return corridor_course(data, source=f"<procedural course {layout_seed}>")
            except CourseError:
                continue  # the corridor overlaps itself
        raise RuntimeError(f"no valid corridor in {_MAX_SHAPE_DRAWS} draws of layout seed {layout_seed}: widen `loop_radius`.")

    def _obstacles(
        self, rng: np.random.Generator, centerline: np.ndarray, width: float, robot_radius: float
    ) -> list[dict[str, Any]]:
        # Arc length along the centre line, from the start (its first vertex).
        closed = np.vstack([centerline, centerline[:1]])
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
        length = float(arc[-1])
        places: list[float] = []
        for _ in range(int(rng.integers(self.n_obstacles[0], self.n_obstacles[1] + 1))):
            for _ in range(_MAX_PLACE_DRAWS):
                s = float(rng.uniform(self.start_clearance, length - _BEHIND_START))
                if all(abs(s - other) >= self.obstacle_spacing for other in places):
                    places.append(s)
                    break
        obstacles = []
        min_gap = self.min_gap(robot_radius)
        # In Python floats: the arithmetic of NumPy's 2-vectors, element by element, without their overhead.
        vertices, arc_lengths = closed.tolist(), arc.tolist()
        for s in sorted(places):
            i = min(bisect.bisect_right(arc_lengths, s) - 1, len(centerline) - 1)
            (x0, y0), (x1, y1) = vertices[i], vertices[i + 1]
            tangent_x, tangent_y = x1 - x0, y1 - y0
            norm = math.hypot(tangent_x, tangent_y)
            tangent_x, tangent_y = tangent_x / norm, tangent_y / norm
            along = s - arc_lengths[i]
            point_x, point_y = x0 + tangent_x * along, y0 + tangent_y * along
            normal_x, normal_y = -tangent_y, tangent_x
            free_side = 1.0 if rng.random() < 0.5 else -1.0  # the side of the corridor left open
            shape = ("box", "cylinder", "wall")[int(rng.integers(3))]
            protrusion_max = width - min_gap  # how far an obstacle may reach across from the closed side
            if shape == "wall" and protrusion_max >= 2.0 * self.wall_thickness:
                # A stub from the closed side's wall, across the corridor, sunk one wall thickness into the wall.
                protrusion = float(rng.uniform(2.0 * self.wall_thickness, protrusion_max))
                offset = -free_side * (width / 2.0 - protrusion / 2.0 + self.wall_thickness / 2.0)
                centre = [point_x + normal_x * offset, point_y + normal_y * offset]
                yaw = math.degrees(math.atan2(normal_y, normal_x))
                obstacles.append(
                    {"shape": "wall", "position": centre, "length": protrusion + self.wall_thickness, "yaw_deg": yaw}
                )
                continue
            if shape == "box":
                size = rng.uniform(*self.box_side, 2)
                yaw = float(rng.uniform(0.0, 180.0))
                reach = float(np.hypot(*size)) / 2.0
            else:
                reach = float(rng.uniform(*self.cylinder_radius))
            # Shrink an obstacle too large for the corridor: its far edge must leave `min_gap` free.
            largest = width - min_gap - _INSIDE
            scale = min(1.0, largest / reach) if reach > 0.0 else 1.0
            reach *= scale
            # Centre across the corridor: from the closed side's wall face to where the gap is exactly `min_gap`.
            low = -width / 2.0 + _INSIDE
            lateral = float(rng.uniform(low, max(low, width / 2.0 - min_gap - reach)))  # max: rounding of `scale`
            across = free_side * lateral
            centre = [point_x + normal_x * across, point_y + normal_y * across]
            if shape == "box":
                obstacles.append({"shape": "box", "position": centre, "size": (size * scale).tolist(), "yaw_deg": yaw})
            else:
                obstacles.append({"shape": "cylinder", "position": centre, "radius": reach})
        return obstacles


def corridor_course(data: dict[str, Any], source: str) -> Course:
    """
    The course :func:`~sb3_adc_envs.lidar_course.course_parsing.course_from_dict` builds from a generator's draw, faster.

    ``data`` holds what :meth:`CourseGenerator._corridor` draws: ``name``, ``description``, ``wall_thickness``,
    ``corridor`` (``width`` and ``centerline``, no ``corner_radius``) and ``start``, from NumPy's floats. The
    same checks, on the same numbers: a draw is refused exactly when ``course_from_dict`` refuses it, and an
    accepted one gives the same course, bit for bit (``tests/envs/test_lidar_procedural_fast.py`` compares the two
    over many draws). What makes it fast: the numbers are checked as arrays rather than one by one, and the check
    that the corridor does not overlap itself measures only the distances that can fail it
    (:func:`~sb3_adc_envs.lidar_course.geometry.nearest_segment_distances`), about a tenth of the
    samples-times-walls distances of ``course_from_dict``, the most of its time.

    :param data: A draw, as above
    :param source: Name of the course in error messages
    :raises CourseError: where ``course_from_dict`` raises one (the message may differ)
    """
    wall_thickness = float(data["wall_thickness"])
    corridor_data, start_data = data["corridor"], data["start"]
    width = float(corridor_data["width"])
    centerline = np.array(corridor_data["centerline"], dtype=float)
    numbers = np.concatenate(
        [centerline.ravel(), [wall_thickness, width, start_data["x"], start_data["y"], start_data["heading_deg"]]]
    )
    if not (np.all(np.isfinite(numbers)) and np.all(np.abs(numbers) <= MAX_COORDINATE)):
        raise CourseError(source, "<numbers>", "a number is not finite or out of range")
    if wall_thickness <= 0.0 or width <= 0.0:
        raise CourseError(source, "corridor.width", "sizes must be > 0")
    start = StartPose(
        x=float(start_data["x"]), y=float(start_data["y"]), heading=math.radians(float(start_data["heading_deg"]))
    )
    # As course_from_dict's corridor: the centre line's points, extent and closure, then the overlap check.
    if len(centerline) > MAX_CENTERLINE_POINTS or len(centerline) < 3:
        raise CourseError(source, "corridor.centerline", "too many or too few points")
    if np.any(np.hypot(*np.diff(centerline, axis=0).T) <= 1e-9):
        raise CourseError(source, "corridor.centerline", "a point repeats the point before it")
    check_extent(source, "corridor", centerline[:, 0], centerline[:, 1], width / 2.0 + wall_thickness, "the corridor's walls")
    (first_x, first_y), (last_x, last_y) = centerline[0].tolist(), centerline[-1].tolist()
    # np.allclose(centerline[0], centerline[-1]) (finite numbers), in Python floats.
    if abs(first_x - last_x) <= 1e-8 + 1e-5 * abs(last_x) and abs(first_y - last_y) <= 1e-8 + 1e-5 * abs(last_y):
        centerline = centerline[:-1]
    if len(centerline) < 3:
        raise CourseError(source, "corridor.centerline", "a closed corridor needs at least 3 distinct points")
    corridor = Corridor(centerline=centerline, width=width)
    walls = np.vstack(corridor_walls(corridor, wall_thickness))
    check_corridor_does_not_overlap(source, corridor, walls, wall_thickness, nearest_only=True)
    check_walls(source, walls, wall_thickness, corridor, [], start)
    return Course(
        name=str(data["name"]),
        source=source,
        walls=walls,
        wall_thickness=wall_thickness,
        start=start,
        corridor=corridor,
        description=str(data["description"]),
        obstacles=(),
    )
