"""The wheeled robot of the lidar course: a differential-drive multibody that pybullet simulates with ``stepSimulation``."""

from __future__ import annotations

import math
from collections.abc import Sequence

from sb3_adc.extras import requires_extra

with requires_extra("envs", "the lidar obstacle course"):
    import pybullet

#: Control period: one environment step [s] (10 Hz, the environment's ``render_fps``).
CONTROL_PERIOD = 0.1
#: Physics steps per control step: the physics runs at 100 Hz (a 10 ms time step).
PHYSICS_SUBSTEPS = 10
#: Constraint solver iterations per physics step (pybullet's default is 50; 10 keep the wheels' contacts stiff
#: at a fifth of the cost, see docs/envs/lidar_course.rst).
SOLVER_ITERATIONS = 10
#: Radius of the two driven wheels [m].
WHEEL_RADIUS = 0.05
#: Width of a wheel [m].
WHEEL_WIDTH = 0.02
#: Gap between a wheel's outer face and the rim of the body [m]: the wheels stay inside the body's footprint.
WHEEL_INSET = 0.02
#: Radius of the two frictionless ball casters, in front of and behind the wheels [m].
CASTER_RADIUS = 0.025
#: Largest wheel speed a motor is asked for [rad/s] (1.5 m/s at the rim).
MAX_WHEEL_SPEED = 30.0
#: Largest torque of a wheel motor (``VELOCITY_CONTROL``'s ``force``) [N m].
MOTOR_FORCE = 5.0
#: Masses of the body, of a wheel and of a caster [kg].
BODY_MASS, WHEEL_MASS, CASTER_MASS = 2.0, 0.2, 0.05
#: Friction coefficient between the wheels and the ground (the casters have none).
WHEEL_FRICTION = 1.0
#: Smallest body radius that leaves room for the wheels and the casters [m].
MIN_RADIUS = 0.08
#: Gravity along -z [m/s^2].
GRAVITY = 9.81

# Collision filter groups of the robot's stepped world (simulation.py explains pybullet's rule): the ground and the
# robot's wheels and casters collide with each other only, and the robot's body with nothing.
_BODY_GROUP = 2
_GROUND_GROUP = 4
_WHEEL_GROUP = 8
# Link indices: the wheels are the robot's joints 0 and 1, the casters (fixed joints) 2 and 3.
_WHEELS = (0, 1)
_N_LINKS = 4


class WheeledRobot:
    """
    A differential-drive robot: a cylindrical body, two driven wheels on its middle axis and two ball casters.

    The body is a cylinder of radius ``radius`` and height ``body_height`` whose centre (the base's origin, where
    the lidar sits) is ``base_height`` above the ground. The wheels (radius :data:`WHEEL_RADIUS`, revolute joints
    about the body's y axis) sit :data:`WHEEL_INSET` inside the rim, so that the track width is
    ``2 * (radius - WHEEL_INSET - WHEEL_WIDTH / 2)`` (0.24 m for the default 0.15 m radius); the casters carry
    the body in front and behind without friction. Each wheel is driven by a ``VELOCITY_CONTROL`` motor of at
    most :data:`MOTOR_FORCE` N m towards a target of at most :data:`MAX_WHEEL_SPEED` rad/s.

    :meth:`drive` turns a step's forward distance and change of heading into the wheel speeds that give them
    over :data:`CONTROL_PERIOD` (unicycle model), sets the motors, then advances the physics one control
    period, :data:`PHYSICS_SUBSTEPS` physics steps (one ``stepSimulation`` call with ``numSubSteps``). A target
    beyond the wheels' limit is scaled down with both wheels' ratio kept, so the robot drives the same arc
    more slowly. The robot accelerates from rest in about 3 control steps.

    The robot is built by :meth:`build` in a client whose world :meth:`configure_world` has set up (gravity
    and the physics time step; call both again after ``resetSimulation``), or with its ground by :meth:`build_world`.

    :param radius: Radius of the body [m], at least :data:`MIN_RADIUS`
    :param body_height: Height of the body's cylinder [m]
    :param base_height: Height of the body's centre above the ground [m]
    """

    def __init__(self, radius: float, body_height: float, base_height: float):
        if not radius >= MIN_RADIUS:
            raise ValueError(f"`robot_radius` must be >= {MIN_RADIUS} m for the wheeled robot, got {radius!r}.")
        if base_height - body_height / 2.0 >= 2.0 * WHEEL_RADIUS:
            raise ValueError(f"the body ({body_height} m high at {base_height} m) must reach down to the wheels' axle")
        self.radius = float(radius)
        self.body_height = float(body_height)
        self.base_height = float(base_height)
        #: Distance between the wheels' centres [m].
        self.track_width = 2.0 * (self.radius - WHEEL_INSET - WHEEL_WIDTH / 2.0)
        self.body_id = -1
        self._client = -1
        self._half_track = self.track_width / 2.0
        self._position = [0.0, 0.0, self.base_height]
        self._orientation = [0.0, 0.0, 0.0, 1.0]
        self._zero = [0.0, 0.0, 0.0]
        self._targets = [0.0, 0.0]
        self._forces = [MOTOR_FORCE, MOTOR_FORCE]
        #: ``(position, orientation)`` of the body's base where the last :meth:`place` or :meth:`drive` left it:
        #: ``[x, y, z]`` [m] and the quaternion ``[x, y, z, w]``, as pybullet takes them.
        self.base_pose: tuple[Sequence[float], Sequence[float]] = (self._position, self._orientation)

    @staticmethod
    def configure_world(client: int) -> None:
        """
        Set gravity and the physics time step of a client (after every ``resetSimulation``).

        :param client: The physics client id
        """
        pybullet.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=client)
        pybullet.setPhysicsEngineParameter(
            fixedTimeStep=CONTROL_PERIOD,
            numSubSteps=PHYSICS_SUBSTEPS,
            numSolverIterations=SOLVER_ITERATIONS,
            deterministicOverlappingPairs=1,
            physicsClientId=client,
        )

    def build_world(self, client: int) -> None:
        """
        Empty a client's world (``resetSimulation``) and build the robot's stepped world there: the ground, the physics
        settings (:meth:`configure_world`) and the robot (:meth:`build`), whose wheels and casters collide with the
        ground only and whose body collides with nothing.

        :param client: The physics client id
        """
        pybullet.resetSimulation(physicsClientId=client)
        ground = pybullet.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client),
            physicsClientId=client,
        )
        pybullet.setCollisionFilterGroupMask(ground, -1, _GROUND_GROUP, _WHEEL_GROUP, physicsClientId=client)
        self.configure_world(client)
        robot = self.build(client)
        pybullet.setCollisionFilterGroupMask(robot, -1, _BODY_GROUP, 0, physicsClientId=client)
        for link in self.link_ids:
            pybullet.setCollisionFilterGroupMask(robot, link, _WHEEL_GROUP, _GROUND_GROUP, physicsClientId=client)

    def build(self, client: int) -> int:
        """
        Create the robot's multibody in a client, at rest at the origin.

        :param client: The physics client id
        :return: the body id
        """
        body = pybullet.createCollisionShape(
            pybullet.GEOM_CYLINDER, radius=self.radius, height=self.body_height, physicsClientId=client
        )
        # A cylinder's axis is its z axis: turned a quarter about x, it lies along the wheels' axle (y).
        wheel = pybullet.createCollisionShape(
            pybullet.GEOM_CYLINDER,
            radius=WHEEL_RADIUS,
            height=WHEEL_WIDTH,
            collisionFrameOrientation=[math.sin(math.pi / 4.0), 0.0, 0.0, math.cos(math.pi / 4.0)],
            physicsClientId=client,
        )
        caster = pybullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=CASTER_RADIUS, physicsClientId=client)
        axle = WHEEL_RADIUS - self.base_height
        caster_x = self.radius - 2.0 * CASTER_RADIUS
        caster_z = CASTER_RADIUS - self.base_height
        self.body_id = robot = pybullet.createMultiBody(
            baseMass=BODY_MASS,
            baseCollisionShapeIndex=body,
            basePosition=self._position,
            linkMasses=[WHEEL_MASS, WHEEL_MASS, CASTER_MASS, CASTER_MASS],
            linkCollisionShapeIndices=[wheel, wheel, caster, caster],
            linkVisualShapeIndices=[-1] * _N_LINKS,
            linkPositions=[
                [0.0, self._half_track, axle],
                [0.0, -self._half_track, axle],
                [caster_x, 0.0, caster_z],
                [-caster_x, 0.0, caster_z],
            ],
            linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * _N_LINKS,
            linkInertialFramePositions=[[0.0, 0.0, 0.0]] * _N_LINKS,
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * _N_LINKS,
            linkParentIndices=[0] * _N_LINKS,
            linkJointTypes=[pybullet.JOINT_REVOLUTE, pybullet.JOINT_REVOLUTE, pybullet.JOINT_FIXED, pybullet.JOINT_FIXED],
            linkJointAxis=[[0.0, 1.0, 0.0]] * _N_LINKS,
            physicsClientId=client,
        )
        for link in _WHEELS:
            pybullet.changeDynamics(robot, link, lateralFriction=WHEEL_FRICTION, physicsClientId=client)
        for link in (2, 3):
            pybullet.changeDynamics(
                robot, link, lateralFriction=0.0, rollingFriction=0.0, spinningFriction=0.0, physicsClientId=client
            )
        self._client = client
        self.place(0.0, 0.0, 0.0)
        return int(robot)

    @property
    def link_ids(self) -> tuple[int, ...]:
        """The links of the wheels and the casters (the body is the base, link -1)."""
        return tuple(range(_N_LINKS))

    def wheel_speeds(self, advance: float, turn: float) -> tuple[float, float]:
        """
        The left and right wheel speeds that drive ``advance`` metres and turn by ``turn`` in one control period.

        :param advance: Forward distance per control step [m]
        :param turn: Change of heading per control step [rad], positive to the left
        :return: ``(left, right)`` [rad/s], within ``±MAX_WHEEL_SPEED`` (both scaled by the same factor)
        """
        speed = advance / CONTROL_PERIOD
        differential = turn / CONTROL_PERIOD * self._half_track
        left = (speed - differential) / WHEEL_RADIUS
        right = (speed + differential) / WHEEL_RADIUS
        peak = max(abs(left), abs(right))
        if peak > MAX_WHEEL_SPEED:
            left *= MAX_WHEEL_SPEED / peak
            right *= MAX_WHEEL_SPEED / peak
        return left, right

    def place(self, x: float, y: float, heading: float) -> None:
        """
        Put the robot at rest at a pose: wheels on the ground, no base or wheel velocity, motors stopped.

        :param x: Position [m]
        :param y: Position [m]
        :param heading: Heading [rad]
        """
        client, robot = self._client, self.body_id
        position, orientation = self._position, self._orientation
        position[0] = x
        position[1] = y
        orientation[2] = math.sin(heading / 2.0)
        orientation[3] = math.cos(heading / 2.0)
        pybullet.resetBasePositionAndOrientation(robot, position, orientation, physicsClientId=client)
        self.base_pose = (position, orientation)
        pybullet.resetBaseVelocity(robot, self._zero, self._zero, physicsClientId=client)
        for joint in _WHEELS:
            pybullet.resetJointState(robot, joint, 0.0, 0.0, physicsClientId=client)
        self._targets[0] = self._targets[1] = 0.0
        pybullet.setJointMotorControlArray(
            robot,
            _WHEELS,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=self._targets,
            forces=self._forces,
            physicsClientId=client,
        )

    def drive(self, advance: float, turn: float) -> tuple[float, float, float]:
        """
        Set the wheel motors for a step (see :meth:`wheel_speeds`) and simulate one control period.

        :param advance: Forward distance per control step [m]
        :param turn: Change of heading per control step [rad], positive to the left
        :return: the body's pose afterwards, ``(x, y, heading)`` [m, m, rad] (``getBasePositionAndOrientation``)
        """
        client, robot = self._client, self.body_id
        targets = self._targets
        targets[0], targets[1] = self.wheel_speeds(advance, turn)
        pybullet.setJointMotorControlArray(
            robot,
            _WHEELS,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=targets,
            forces=self._forces,
            physicsClientId=client,
        )
        pybullet.stepSimulation(physicsClientId=client)
        self.base_pose = pose = pybullet.getBasePositionAndOrientation(robot, physicsClientId=client)
        (x, y, _), (qx, qy, qz, qw) = pose
        heading = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        return x, y, heading
