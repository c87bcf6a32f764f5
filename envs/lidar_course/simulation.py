"""The pybullet worlds of one lidar course: walls, obstacles and a round robot with a planar lidar (and its ground)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("envs", "the lidar obstacle course"):
    import pybullet

from sb3_adc_envs.lidar_course.course import Course
from sb3_adc_envs.lidar_course.lidar import Lidar
from sb3_adc_envs.lidar_course.wheeled import WheeledRobot

#: Height of the walls [m].
WALL_HEIGHT = 0.5
#: Height of the robot's cylinder [m].
ROBOT_HEIGHT = 0.2
#: Gap between the ground and the bottom of the robot [m]: the robot never touches the ground plane.
ROBOT_GROUND_CLEARANCE = 0.05
#: Height of the lidar's rays, the centre of the robot's cylinder [m].
SENSOR_HEIGHT = ROBOT_GROUND_CLEARANCE + ROBOT_HEIGHT / 2.0
#: The robots: ``"kinematic"``, a cylinder placed at each step; ``"wheeled"``, a differential-drive multibody
#: (:class:`~sb3_adc_envs.lidar_course.wheeled.WheeledRobot`) simulated with ``stepSimulation``.
ROBOTS = ("kinematic", "wheeled")

# Collision filter groups. pybullet lets a pair collide when either one's group is in the other's mask; a ray
# hits a body when the body's group is in the ray's mask and the ray's group, Bullet's default (1), is in the
# body's mask. Rays see walls and obstacles only, never the robot.
# - The course's world is never stepped: walls (and obstacles) are in group 1, the group pybullet gives the links of
#   a multibody (which spares a call per link at every reset), and the robot's mask is the walls' group.
# - The wheeled robot's world (ground and robot, no walls; :meth:`WheeledRobot.build_world`) is stepped: the robot's
#   body collides with nothing there, and its contact with a wall is the geometric test of `_touches_wall` in the
#   course's world, as for the kinematic robot (the episode ends there, so no wall ever needs to push it).
_WALL_GROUP = 1
_ROBOT_GROUP = 2
#: Walls and obstacles per multibody: the most links a ``createMultiBody`` call takes (pybullet 3.2 drops those
#: beyond 127: ``MAX_CREATE_MULTI_BODY_LINKS``, 128 with the base).
LINKS_PER_BODY = 127
#: Courses a client holds in turn before its world is emptied (``resetSimulation``), which frees the collision
#: shapes of the courses before: pybullet frees a shape no other way once a body has used it.
RESET_WORLD_EVERY = 16
_FAR = (1.0e4, 1.0e4, 0.0)
_ORIGIN = (0.0, 0.0, 0.0)
_IDENTITY = (0.0, 0.0, 0.0, 1.0)
_TWO_PI = 2.0 * math.pi


class CourseSimulation:
    """
    A pybullet physics client (``p.DIRECT``) holding one course (walls and obstacles) and one robot.

    With ``robot="kinematic"`` the robot is a cylinder without dynamics: :meth:`drive_robot` turns it and drives it
    straight (the pose changes exactly by the step), and :meth:`move_robot` places it with
    ``resetBasePositionAndOrientation``, asks pybullet whether it touches a wall (broad phase
    ``getOverlappingObjects`` on the robot's bounding box, then ``getClosestPoints`` against the walls and
    obstacles found there) and casts the lidar's rays (:class:`~sb3_adc_envs.lidar_course.lidar.Lidar`). Rays
    start at the robot's centre and are filtered to the walls' collision group (obstacles are in it too), so they
    never hit the robot. :meth:`load` replaces the course in the same client (see there how, and why it is fast).

    With ``robot="wheeled"`` the robot is a :class:`~sb3_adc_envs.lidar_course.wheeled.WheeledRobot` whose
    wheels roll on the ground under gravity, in a second client that holds only the ground and the robot
    (no wall ever touches the robot's wheels, so the stepped world needs none): :meth:`move_robot` puts it at
    rest at a pose, and :meth:`drive_robot` runs its motors for one control period (``stepSimulation``). The
    course's client then puts the robot's cylinder (the wheeled robot's body) at the body's pose, tilt
    included, reads the lidar and tests the body against the walls as above.

    Every call passes this instance's ``physicsClientId``: several simulations run side by side in one
    process. :meth:`close` disconnects the clients; it is safe to call twice and runs on garbage collection.

    :param course: The course to build
    :param robot_radius: Radius of the robot's cylinder [m]
    :param ray_angles: ``(n_rays,)`` directions of the lidar's readings relative to the robot's heading [rad]
    :param max_range: Length of the rays [m]
    :param robot: One of :data:`ROBOTS`
    :param rays_per_reading: Rays cast for each reading (1: one ray along the reading's direction)
    :param sector: Angle each reading's rays are spread over [rad] (used when ``rays_per_reading`` is above 1)
    :raises ValueError: if ``robot`` is not one of :data:`ROBOTS`, or the wheeled robot's radius is too small
    """

    def __init__(
        self,
        course: Course,
        robot_radius: float,
        ray_angles: np.ndarray,
        max_range: float,
        robot: str = "kinematic",
        rays_per_reading: int = 1,
        sector: float = 0.0,
    ):
        if robot not in ROBOTS:
            raise ValueError(f"`robot` must be one of {ROBOTS}, got {robot!r}.")
        self.robot_radius = robot_radius
        self.max_range = max_range
        #: The wheeled robot's model (``None`` for the kinematic robot).
        self.wheeled = WheeledRobot(robot_radius, ROBOT_HEIGHT, SENSOR_HEIGHT) if robot == "wheeled" else None
        self._client: int | None = pybullet.connect(pybullet.DIRECT)
        # The wheeled robot's stepped world, without walls: the step's cost does not grow with the course.
        self._physics_client: int | None = pybullet.connect(pybullet.DIRECT) if self.wheeled is not None else None

        #: The robot's lidar.
        self.lidar = Lidar(ray_angles, max_range, SENSOR_HEIGHT, _WALL_GROUP, rays_per_reading, sector)
        self._position = [0.0, 0.0, SENSOR_HEIGHT]
        self._orientation = [0.0, 0.0, 0.0, 1.0]
        self._aabb_min = [0.0, 0.0, ROBOT_GROUND_CLEARANCE]
        self._aabb_max = [0.0, 0.0, ROBOT_GROUND_CLEARANCE + ROBOT_HEIGHT]
        self._part_offsets: dict[int, int] = {}
        self.robot_id = -1
        self._courses_since_reset = 0
        #: ``(x, y, heading)`` of the robot [m, m, rad], where the last :meth:`load`, :meth:`move_robot` or
        #: :meth:`drive_robot` left it.
        self.pose = (course.start.x, course.start.y, course.start.heading)
        self.load(course)

    def load(self, course: Course) -> None:
        """
        Build a course in this client, replacing the one there, and put the robot at rest at its start.

        The walls and obstacles are the links of a few fixed multibodies, :data:`LINKS_PER_BODY` each, one
        ``createMultiBody`` call per multibody (a call costs about 90 microseconds: a body per wall made a
        procedural reset take 20 ms). The robot's cylinder stays; the multibodies of the course before are removed
        (``removeBody``, a few microseconds a link) rather than the world emptied with ``resetSimulation`` (about
        0.7 ms, even for an empty world). pybullet frees a collision shape that a body used only on
        ``resetSimulation``, and the walls of every layout have sizes of their own, so every
        :data:`RESET_WORLD_EVERY` courses the world is emptied and the robot built again, which bounds the memory
        the shapes of past courses hold. A course's bodies are built the same way whatever came before (ids of
        bodies and shapes aside, which :attr:`wall_ids` and :attr:`obstacle_ids` hide): the same course gives the
        same readings, contacts and ids. The wheeled robot's world (ground and robot) is emptied and rebuilt at
        every course: each course starts from the same physics state.

        :param course: The course
        """
        client = self._client
        if client is None:
            raise RuntimeError("the simulation is closed")
        self.course = course
        if self._courses_since_reset >= RESET_WORLD_EVERY or self.robot_id < 0:
            self._reset_world()
        else:
            for body in self._part_offsets:
                pybullet.removeBody(body, physicsClientId=client)
            # The robot back where _reset_world built it, by way of a far point (a jump, not a move: pybullet
            # widens the box of a body it moves by less than the body's size), so that the broadphase's tree of
            # the new course grows as in a new world: rays whose nearest hits tie (two walls sharing a face)
            # report the same one.
            for far in (_FAR, _ORIGIN):
                pybullet.resetBasePositionAndOrientation(self.robot_id, far, _IDENTITY, physicsClientId=client)
        self._courses_since_reset += 1
        shapes, positions, orientations = self._parts(course)
        self._part_offsets = {}
        for first in range(0, len(shapes), LINKS_PER_BODY):
            parts = slice(first, first + LINKS_PER_BODY)
            n_links = len(shapes[parts])
            body = pybullet.createMultiBody(
                baseMass=0.0,
                linkMasses=[0.0] * n_links,
                linkCollisionShapeIndices=shapes[parts],
                linkVisualShapeIndices=[-1] * n_links,
                linkPositions=positions[parts],
                linkOrientations=orientations[parts],
                linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n_links,
                linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n_links,
                linkParentIndices=[0] * n_links,
                linkJointTypes=[pybullet.JOINT_FIXED] * n_links,
                linkJointAxis=[[0.0, 0.0, 1.0]] * n_links,
                physicsClientId=client,
            )
            if pybullet.getNumJoints(body, physicsClientId=client) != n_links:
                raise RuntimeError(f"pybullet built {n_links} links short; lower LINKS_PER_BODY ({LINKS_PER_BODY})")
            # The links keep the collision group pybullet gives them, _WALL_GROUP: no call per link.
            self._part_offsets[body] = first
        #: Ids of the wall segments, then of the obstacles: their indices in the course's walls, then obstacles.
        self.wall_ids = list(range(len(course.walls)))
        self.obstacle_ids = list(range(len(course.walls), len(shapes)))
        start = course.start
        self.pose = (start.x, start.y, start.heading)
        if self.wheeled is not None:
            assert self._physics_client is not None
            self.wheeled.build_world(self._physics_client)
            self.wheeled.place(start.x, start.y, start.heading)
            self._follow_wheeled()
        else:
            pybullet.resetBasePositionAndOrientation(
                self.robot_id, [start.x, start.y, SENSOR_HEIGHT], [0.0, 0.0, 0.0, 1.0], physicsClientId=client
            )

    def _reset_world(self) -> None:
        # An empty world (freeing every collision shape) with the robot's cylinder in it.
        client = self._client
        pybullet.resetSimulation(physicsClientId=client)
        self.robot_id = pybullet.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=pybullet.createCollisionShape(
                pybullet.GEOM_CYLINDER, radius=self.robot_radius, height=ROBOT_HEIGHT, physicsClientId=client
            ),
            physicsClientId=client,
        )
        pybullet.setCollisionFilterGroupMask(self.robot_id, -1, _ROBOT_GROUP, _WALL_GROUP, physicsClientId=client)
        self._part_offsets = {}
        self._courses_since_reset = 0

    def _parts(self, course: Course) -> tuple[list[int], list[list[float]], list[list[float]]]:
        # The collision shapes of the walls, then of the obstacles, and their positions and orientations.
        client = self._client
        thickness = course.wall_thickness
        half_height = WALL_HEIGHT / 2.0
        create = pybullet.createCollisionShape
        box = pybullet.GEOM_BOX
        walls = course.walls
        # The walls' centres at once (the same numbers as one by one); their lengths and yaws with math's functions.
        positions = np.column_stack(
            [(walls[:, 0] + walls[:, 2]) / 2.0, (walls[:, 1] + walls[:, 3]) / 2.0, np.full(len(walls), half_height)]
        ).tolist()
        deltas = (walls[:, 2:] - walls[:, :2]).tolist()
        half_thickness = thickness / 2.0
        hypot, atan2, sin, cos = math.hypot, math.atan2, math.sin, math.cos
        # Half a thickness longer at both ends, so that the walls of a polyline overlap at their joints.
        extents = [[hypot(dx, dy) / 2.0 + half_thickness, half_thickness, half_height] for dx, dy in deltas]
        shapes = [create(box, halfExtents=half_extents, physicsClientId=client) for half_extents in extents]
        yaws = [atan2(dy, dx) / 2.0 for dx, dy in deltas]
        orientations = [[0.0, 0.0, sin(half_yaw), cos(half_yaw)] for half_yaw in yaws]
        for obstacle in course.obstacles:
            if obstacle.shape == "cylinder":
                shape = create(
                    pybullet.GEOM_CYLINDER, radius=obstacle.length / 2.0, height=WALL_HEIGHT, physicsClientId=client
                )
            else:
                shape = create(
                    box, halfExtents=[obstacle.length / 2.0, obstacle.width / 2.0, half_height], physicsClientId=client
                )
            shapes.append(shape)
            positions.append([obstacle.x, obstacle.y, half_height])
            orientations.append([0.0, 0.0, math.sin(obstacle.yaw / 2.0), math.cos(obstacle.yaw / 2.0)])
        return shapes, positions, orientations

    def _follow_wheeled(self) -> None:
        # The robot's cylinder in the course's world takes the wheeled robot's body's pose, tilt included.
        assert self.wheeled is not None
        position, orientation = self.wheeled.base_pose
        pybullet.resetBasePositionAndOrientation(self.robot_id, position, orientation, physicsClientId=self._client)

    @property
    def client_id(self) -> int | None:
        """The pybullet physics client id of the course (walls, obstacles, the robot's cylinder), ``None`` once closed."""
        return self._client

    def move_robot(self, x: float, y: float, heading: float, lidar_out: np.ndarray) -> bool:
        """
        Place the robot (the wheeled robot at rest), read the lidar and tell whether the robot touches a wall.

        :param x: Position [m]
        :param y: Position [m]
        :param heading: Heading [rad]
        :param lidar_out: ``(n_rays,)`` array that receives the ray lengths divided by ``max_range``
            (1 where a ray hits nothing)
        :return: whether the robot overlaps a wall
        """
        self.pose = (x, y, heading)
        if self.wheeled is not None:
            self.wheeled.place(x, y, heading)
            self._follow_wheeled()
            return self._sense(x, y, heading, lidar_out)
        position = self._position
        position[0] = x
        position[1] = y
        orientation = self._orientation
        orientation[2] = math.sin(heading / 2.0)
        orientation[3] = math.cos(heading / 2.0)
        pybullet.resetBasePositionAndOrientation(self.robot_id, position, orientation, physicsClientId=self._client)
        return self._sense(x, y, heading, lidar_out)

    def drive_robot(self, advance: float, turn: float, lidar_out: np.ndarray) -> tuple[float, float, float, bool]:
        """
        Drive the robot for one step, read the lidar and tell whether the robot touches a wall: the kinematic robot
        turns by ``turn``, then drives ``advance`` straight; the wheeled robot sets its wheels to make that turn and
        that distance in one control period and simulates it.

        :param advance: Forward distance of the step [m]
        :param turn: Change of heading of the step [rad], positive to the left
        :param lidar_out: ``(n_rays,)`` array that receives the ray lengths divided by ``max_range``
        :return: ``(x, y, heading, collided)``: the pose afterwards [m, m, rad], and whether the robot overlaps a wall
        """
        if self.wheeled is None:
            x, y, heading = self.pose
            heading = math.remainder(heading + turn, _TWO_PI)
            x, y = x + advance * math.cos(heading), y + advance * math.sin(heading)
            return x, y, heading, self.move_robot(x, y, heading, lidar_out)
        x, y, heading = self.wheeled.drive(advance, turn)
        self.pose = (x, y, heading)
        self._follow_wheeled()
        return x, y, heading, self._sense(x, y, heading, lidar_out)

    def _sense(self, x: float, y: float, heading: float, lidar_out: np.ndarray) -> bool:
        # The lidar's rays from the robot's pose, and the contact test.
        self.lidar.read(self._client, x, y, heading, lidar_out)
        return self._touches_wall(x, y)

    @property
    def ray_bodies(self) -> list[int]:
        """
        Id each reading of the last :meth:`move_robot` or :meth:`drive_robot` met (a wall's or an obstacle's, of
        :attr:`wall_ids` and :attr:`obstacle_ids`, or -1 for none): with several rays per reading, that of its
        nearest hit.
        """
        # The rays see the course's links only (body -1 where a ray hits nothing).
        return [self._part_offsets[hit[0]] + hit[1] if hit[0] >= 0 else -1 for hit in self.lidar.reading_hits()]

    def _touches_wall(self, x: float, y: float) -> bool:
        return next(self._touched_bodies(x, y), None) is not None

    def _touched_bodies(self, x: float, y: float) -> Iterator[int]:
        # The walls and obstacles the robot at (x, y) touches, lazily: the step's test stops at the first.
        radius = self.robot_radius
        aabb_min = self._aabb_min
        aabb_max = self._aabb_max
        aabb_min[0] = x - radius
        aabb_min[1] = y - radius
        aabb_max[0] = x + radius
        aabb_max[1] = y + radius
        client = self._client
        candidates = pybullet.getOverlappingObjects(aabb_min, aabb_max, physicsClientId=client)
        if candidates:
            offsets = self._part_offsets
            for body, link in candidates:
                # -1: the robot's body (the wheeled robot's wheels and casters lie inside its footprint).
                if body in offsets and pybullet.getClosestPoints(
                    self.robot_id, body, 0.0, linkIndexA=-1, linkIndexB=link, physicsClientId=client
                ):
                    yield offsets[body] + link

    def touched_bodies(self, x: float, y: float) -> list[int]:
        """
        The ids of the walls and obstacles that the robot, where the last :meth:`move_robot` or
        :meth:`drive_robot` left it at ``(x, y)``, touches (ids of :attr:`wall_ids` and :attr:`obstacle_ids`, the
        ids :attr:`ray_bodies` reports). Empty without a collision. For diagnostics, as :meth:`touching`.

        :param x: The robot's position [m]
        :param y: The robot's position [m]
        """
        return list(self._touched_bodies(x, y))

    def touching(self, x: float, y: float) -> list[str]:
        """
        What the robot, where the last :meth:`move_robot` or :meth:`drive_robot` left it at ``(x, y)``, touches:
        one name per wall or obstacle, ``"wall"`` for a segment of the course's walls, else the obstacle's shape (``"box"``,
        ``"cylinder"``, or ``"stub"`` for a wall stub). Empty without a collision. For diagnostics (which obstacles
        a policy hits); the step itself only asks whether there is any.

        :param x: The robot's position [m]
        :param y: The robot's position [m]
        """
        return self.body_kinds(self.touched_bodies(x, y))

    def body_kinds(self, bodies: list[int]) -> list[str]:
        """
        What each id is, in :meth:`touching`'s names: ``"wall"`` for a segment of the course's walls, else the
        obstacle's shape (``"box"``, ``"cylinder"``, or ``"stub"`` for a wall stub).

        :param bodies: Ids of :attr:`wall_ids` and :attr:`obstacle_ids` (as :meth:`touched_bodies` gives them)
        """
        first_obstacle = self.obstacle_ids[0] if self.obstacle_ids else None
        names = []
        for body in bodies:
            if first_obstacle is None or body < first_obstacle:
                names.append("wall")
            else:
                shape = self.course.obstacles[body - first_obstacle].shape
                names.append("stub" if shape == "wall" else shape)
        return names

    def close(self) -> None:
        """Disconnect the physics clients (safe to call more than once)."""
        clients = (self._client, self._physics_client)
        self._client = self._physics_client = None
        for client in clients:
            if client is not None and pybullet is not None and pybullet.isConnected(client):
                pybullet.disconnect(physicsClientId=client)

    def __del__(self) -> None:
        # At interpreter shutdown module globals may already be gone: never raise from here.
        with contextlib.suppress(Exception):
            self.close()
