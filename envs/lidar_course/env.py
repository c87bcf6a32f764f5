"""``sb3_adc/LidarObstacleCourse-v0`` and ``-v1``: a lidar robot drives through a walled course (ADC paper, Section 5.1.2)."""

from __future__ import annotations

import functools
import math
import os
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sb3_adc_envs.lidar_course.course import MAX_COURSE_SIDE, Course
from sb3_adc_envs.lidar_course.course_parsing import load_course
from sb3_adc_envs.lidar_course.geometry import LoopProgress
from sb3_adc_envs.lidar_course.lidar import reading_directions
from sb3_adc_envs.lidar_course.procedural import CourseGenerator
from sb3_adc_envs.lidar_course.rendering import TopDownRenderer
from sb3_adc_envs.lidar_course.simulation import ROBOTS, CourseSimulation

#: ``course=PROCEDURAL``: a new procedural layout at every reset (see :mod:`~sb3_adc_envs.lidar_course.procedural`).
PROCEDURAL = "procedural"
#: Layout seeds ``[start, stop)`` of procedural training courses (``sb3_adc/LidarObstacleCourse-v1``'s default).
TRAIN_LAYOUT_SEEDS = (0, 1_000_000)
#: Held-out layout seeds ``[start, stop)`` for evaluation, disjoint from :data:`TRAIN_LAYOUT_SEEDS`.
TEST_LAYOUT_SEEDS = (1_000_000, 1_000_100)
#: Validation layout seeds ``[start, stop)``, disjoint from both: for choices made while tuning (budget, settings),
#: so that :data:`TEST_LAYOUT_SEEDS` stays unseen by every choice.
VALIDATION_LAYOUT_SEEDS = (2_000_000, 2_000_100)

#: The most lidar readings (``n_rays``): the observation's size, which sizes a replay buffer's memory.
MAX_N_RAYS = 4096
#: The most rays ``rays_per_reading`` casts for each reading (each costs about 5 microseconds a step).
MAX_RAYS_PER_READING = 16
# Initial capacity of the path buffer (positions); it doubles when full.
_PATH_CAPACITY = 512


@functools.lru_cache(maxsize=256)
def _procedural_course(generator: CourseGenerator, layout_seed: int, robot_radius: float) -> Course:
    # Courses are immutable: an evaluation that comes back to a layout seed reuses it.
    return generator.generate(layout_seed, robot_radius)


class LidarObstacleCourseEnv(gym.Env[np.ndarray, np.ndarray]):
    """
    A round robot drives forward at constant speed through a walled course and steers to avoid the walls and
    obstacles.

    The navigation task of the Actor-Dueling-Critic paper (Section 5.1.2, Figure 6), simulated with
    pybullet (``p.DIRECT``, one physics client per environment, two with the wheeled robot; see
    :class:`~sb3_adc_envs.lidar_course.simulation.CourseSimulation`).

    - **Action**: ``Box(-1, 1, (1,))``, the change of heading during the step, scaled to
      ``[-max_steer_deg, +max_steer_deg]`` (the paper's ±6°). Positive turns left (counter-clockwise).
    - **Observation**: ``Box(0, 1, (n_rays,))``, the lidar's distances to the walls and obstacles divided by
      ``max_range`` (1 where a ray sees nothing). The rays are spread evenly over ``fov_deg`` around the
      heading, the first one straight ahead when ``fov_deg`` is 360.
    - **Reward**: ``step_reward`` (+0.001) for a step without collision; ``collision_reward`` (-1) when the
      robot touches a wall or an obstacle, which terminates the episode.
    - **Episode**: starts at the course's start pose (optionally jittered); registered with a
      500-step time limit (``gym.make`` adds the ``TimeLimit`` wrapper; the class alone never truncates).
    - **Info**: ``{"collision": bool, "is_success": bool, "distance": float, "clearance": float, "course": str}``:
      ``is_success`` is ``not collision``, so at the episode's last step it tells whether the robot drove until
      the time limit without a collision (what SB3's ``EvalCallback`` and the RL Zoo log as the success rate);
      ``distance`` is the distance driven along the course since the reset [m]: along the corridor's centre line
      (backwards counts negative) when the course has one, else the length of the path; ``clearance`` is the
      shortest lidar reading less the robot's radius [m]: the free space the rays see around the robot, without
      observation noise (a thin obstacle between two rays is not seen), which
      :class:`~sb3_adc_envs.wrappers.ClearanceShaping` shapes the reward with.

    With ``robot="wheeled"`` the robot has dynamics: a differential-drive
    :class:`~sb3_adc_envs.lidar_course.wheeled.WheeledRobot` (two motor-driven wheels and two casters under a
    body of radius ``robot_radius``) that pybullet simulates with ``stepSimulation``. The action becomes a
    target turn rate (``action[0] * max_steer_deg`` per step) and the forward speed ``speed`` per step; a step
    sets the wheel motors (``VELOCITY_CONTROL``) and simulates one control period of 0.1 s (10 Hz control, physics
    at 100 Hz), and the lidar and the contact test start from the body's pose read back from pybullet.
    Observations, rewards, termination and ``info`` are those of the kinematic robot; ``distance`` without a
    centre line is the length of the path the body drove. Same seed and same actions give the same trajectory.

    With ``course="procedural"`` every reset draws a new layout
    (:class:`~sb3_adc_envs.lidar_course.procedural.CourseGenerator`): its layout seed is drawn uniformly from
    ``layout_seeds`` with the environment's generator, so ``reset(seed=k)`` gives the same layout for the same
    ``k``; ``reset(options={"layout_seed": n})`` picks one. ``reset(options={"start_pose": (x, y, heading_deg)})``
    starts that episode elsewhere (no jitter).

    :param course: A shipped course name (``"training"``, ``"unseen_narrow"``, ... see
        :func:`~sb3_adc_envs.lidar_course.course.shipped_courses`), the path of a YAML/JSON course file,
        a :class:`~sb3_adc_envs.lidar_course.course.Course`, or ``"procedural"``
    :param n_rays: Number of lidar rays (8 in the paper): the lidar's readings, one observation each, at most
        :data:`MAX_N_RAYS`
    :param fov_deg: Angle the rays are spread over [deg], in ``(0, 360]``
    :param rays_per_reading: Rays cast for each reading, 1 (the default, the paper's lidar) to
        :data:`MAX_RAYS_PER_READING`: above 1, each reading is the nearest hit of that many rays spread evenly over
        its sector (the angle between neighbouring readings, centred on the reading's direction), so that an
        obstacle thinner than the gap between two readings' directions is not missed; the observation keeps one
        value per reading
    :param max_range: Length of the rays [m], at most :data:`~sb3_adc_envs.lidar_course.course.MAX_COURSE_SIDE`;
        observations are distances divided by it
    :param speed: Distance driven per step [m], at most :data:`~sb3_adc_envs.lidar_course.course.MAX_COURSE_SIDE`
    :param max_steer_deg: Largest change of heading per step [deg] (6 in the paper); with the wheeled robot,
        the largest target turn rate, per step
    :param robot_radius: Radius of the robot [m] (at least 0.08 for the wheeled robot)
    :param start_position_jitter: Start positions are drawn uniformly within this distance of the course's
        start along x and along y [m] (0: always the course's start)
    :param start_heading_jitter_deg: Start headings are drawn uniformly within this angle of the course's
        start heading [deg]
    :param step_reward: Reward of a step without collision
    :param collision_reward: Reward of the step that hits a wall
    :param render_mode: ``None`` or ``"rgb_array"`` (a top-down picture of walls, robot, rays and path);
        ``gym.make(..., render_mode="human")`` shows these pictures in a window (Gymnasium's ``HumanRendering``)
    :param layout_seeds: ``(start, stop)``: the layout seeds procedural courses are drawn from (default
        :data:`TRAIN_LAYOUT_SEEDS`; :data:`TEST_LAYOUT_SEEDS` holds out 100 others for evaluation)
    :param generator: The distribution of procedural courses (default
        :class:`~sb3_adc_envs.lidar_course.procedural.CourseGenerator`)
    :param robot: ``"kinematic"`` (the default, the paper's robot: the pose changes exactly by the action) or
        ``"wheeled"`` (a robot with dynamics, see above)
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}  # noqa: RUF012 (Gymnasium's class attribute)

    def __init__(
        self,
        course: str | os.PathLike[str] | Course = "training",
        n_rays: int = 8,
        fov_deg: float = 360.0,
        max_range: float = 3.0,
        speed: float = 0.1,
        max_steer_deg: float = 6.0,
        robot_radius: float = 0.15,
        start_position_jitter: float = 0.0,
        start_heading_jitter_deg: float = 0.0,
        step_reward: float = 0.001,
        collision_reward: float = -1.0,
        render_mode: str | None = None,
        layout_seeds: tuple[int, int] = TRAIN_LAYOUT_SEEDS,
        generator: CourseGenerator | None = None,
        robot: str = "kinematic",
        rays_per_reading: int = 1,
    ):
        if not isinstance(course, (str, os.PathLike, Course)):
            raise TypeError(
                "`course` must be a shipped course name (str), the path of a course file (str or os.PathLike), a Course, "
                f"or {PROCEDURAL!r}; got {course!r} of type {type(course).__name__}."
            )
        if isinstance(n_rays, bool) or not isinstance(n_rays, (int, np.integer)) or not 1 <= n_rays <= MAX_N_RAYS:
            raise ValueError(f"`n_rays` must be an integer in [1, {MAX_N_RAYS}], got {n_rays!r}.")
        numbers = {
            "fov_deg": fov_deg,
            "max_range": max_range,
            "speed": speed,
            "max_steer_deg": max_steer_deg,
            "robot_radius": robot_radius,
            "start_position_jitter": start_position_jitter,
            "start_heading_jitter_deg": start_heading_jitter_deg,
            "step_reward": step_reward,
            "collision_reward": collision_reward,
        }
        for name, value in numbers.items():
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise TypeError(f"`{name}` must be a number, got {value!r} ({type(value).__name__}).")
            if not math.isfinite(value):
                raise ValueError(f"`{name}` must be a finite number, got {value!r}.")
        if not 0.0 < fov_deg <= 360.0:
            raise ValueError(f"`fov_deg` must be in (0, 360], got {fov_deg!r}.")
        if (
            isinstance(rays_per_reading, bool)
            or not isinstance(rays_per_reading, (int, np.integer))
            or not 1 <= rays_per_reading <= MAX_RAYS_PER_READING
        ):
            raise ValueError(
                f"`rays_per_reading` must be an integer in [1, {MAX_RAYS_PER_READING}], got {rays_per_reading!r}."
            )
        for name, value in (("max_range", max_range), ("speed", speed), ("robot_radius", robot_radius)):
            if not value > 0.0:
                raise ValueError(f"`{name}` must be a finite number > 0, got {value!r}.")
        for name, value in (("max_range", max_range), ("speed", speed)):
            if value > MAX_COURSE_SIDE:
                raise ValueError(
                    f"`{name}` must be in (0, {MAX_COURSE_SIDE:g}] m (MAX_COURSE_SIDE, the largest course: a step or a "
                    f"ray longer than that leaves every course), got {value!r}."
                )
        if not 0.0 < max_steer_deg <= 180.0:
            raise ValueError(f"`max_steer_deg` must be in (0, 180], got {max_steer_deg!r}.")
        for name, value in (
            ("start_position_jitter", start_position_jitter),
            ("start_heading_jitter_deg", start_heading_jitter_deg),
        ):
            if not value >= 0.0:
                raise ValueError(f"`{name}` must be a finite number >= 0, got {value!r}.")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"`render_mode` must be None or one of {self.metadata['render_modes']}, got {render_mode!r}.")
        if (
            not isinstance(layout_seeds, (tuple, list))
            or len(layout_seeds) != 2
            or any(isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) for seed in layout_seeds)
            or not 0 <= layout_seeds[0] < layout_seeds[1]
        ):
            raise ValueError(
                f"`layout_seeds` must be a pair (start, stop) of integers with 0 <= start < stop, got {layout_seeds!r}."
            )
        if generator is not None and not isinstance(generator, CourseGenerator):
            raise TypeError(f"`generator` must be a CourseGenerator or None, got {generator!r}.")
        if not isinstance(robot, str) or robot not in ROBOTS:
            raise ValueError(f"`robot` must be one of {ROBOTS}, got {robot!r}.")

        self.robot_radius = float(robot_radius)
        #: Whether every reset draws a procedural layout.
        self.procedural = isinstance(course, str) and course == PROCEDURAL
        self.layout_seeds = (int(layout_seeds[0]), int(layout_seeds[1]))
        self.generator = generator if generator is not None else CourseGenerator()
        if self.procedural:
            self.generator.check_robot_fits(self.robot_radius)
            #: Layout seed of the current procedural course (``None`` for a fixed course).
            self.layout_seed: int | None = self.layout_seeds[0]
            self.course = _procedural_course(self.generator, self.layout_seed, self.robot_radius)
            start_clearance = self.generator.width[0] / 2.0
        else:
            self.layout_seed = None
            self.course = course if isinstance(course, Course) else load_course(course)
            self.course.check_robot_fits(robot_radius)
            start_clearance = self.course.clearance(self.course.start.x, self.course.start.y)
        jitter_reach = start_position_jitter * math.sqrt(2.0)
        if start_clearance - jitter_reach <= robot_radius:
            raise ValueError(
                f"`start_position_jitter`={start_position_jitter!r} m can put the robot (radius {robot_radius} m) on a "
                f"wall of course {self.course.name!r}: the start is {start_clearance:.3g} m from the nearest wall face."
            )
        self.n_rays = int(n_rays)
        self.fov = math.radians(fov_deg)
        self.max_range = float(max_range)
        self.speed = float(speed)
        self.max_steer = math.radians(max_steer_deg)
        self.start_position_jitter = float(start_position_jitter)
        self.start_heading_jitter = math.radians(start_heading_jitter_deg)
        self.step_reward = float(step_reward)
        self.collision_reward = float(collision_reward)
        self.render_mode = render_mode
        #: ``"kinematic"`` or ``"wheeled"``.
        self.robot = robot

        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Box(0.0, 1.0, shape=(self.n_rays,), dtype=np.float32)
        #: Ray directions relative to the heading [rad].
        self.ray_angles, sector = reading_directions(self.n_rays, self.fov)
        #: Rays cast for each reading.
        self.rays_per_reading = int(rays_per_reading)
        self._simulation = CourseSimulation(
            self.course, self.robot_radius, self.ray_angles, self.max_range, robot, self.rays_per_reading, sector
        )
        self._renderer: TopDownRenderer | None = None
        self._progress = self._loop_progress(self.course)

        self._lidar = np.ones(self.n_rays, dtype=np.float32)
        self._collided = False
        self._distance = 0.0
        self._path = np.empty((_PATH_CAPACITY, 2))
        self._path_length = 0

    @staticmethod
    def _loop_progress(course: Course) -> LoopProgress | None:
        return LoopProgress(course.corridor.centerline) if course.corridor is not None else None

    @property
    def pose(self) -> tuple[float, float, float]:
        """``(x, y, heading)`` of the robot [m, m, rad]."""
        return self._simulation.pose

    @property
    def trajectory(self) -> np.ndarray:
        """``(n, 2)`` positions of the robot since the last reset (the start included) [m]."""
        return self._path[: self._path_length].copy()

    @property
    def simulation(self) -> CourseSimulation:
        """The pybullet world of the current course (its body ids, and what each ray hit at the last step)."""
        return self._simulation

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """
        Put the robot back at the start pose (the course's, jittered if configured, or ``options["start_pose"]``);
        with ``course="procedural"``, on a new layout first.

        :param seed: Seeds the layout seed's draw and the start-pose jitter
        :param options: ``{"start_pose": (x, y, heading_deg)}`` starts this episode there, without jitter;
            ``{"layout_seed": n}`` (procedural courses) picks the layout instead of drawing it
        :return: the first observation and the info of :meth:`step` (no collision, distance 0)
        :raises ValueError: if ``options["start_pose"]`` puts the robot on a wall, or ``options["layout_seed"]`` is
            given for a fixed course or is not an integer >= 0
        """
        super().reset(seed=seed)
        options = options or {}
        if self.procedural:
            if "layout_seed" in options:
                layout_seed = options["layout_seed"]
                if isinstance(layout_seed, bool) or not isinstance(layout_seed, (int, np.integer)) or layout_seed < 0:
                    raise ValueError(f"`options['layout_seed']` must be an integer >= 0, got {layout_seed!r}.")
            else:
                layout_seed = self.np_random.integers(*self.layout_seeds)
            self._load_layout(int(layout_seed))
        elif "layout_seed" in options:
            raise ValueError(
                f"`options['layout_seed']` applies to procedural courses (course={PROCEDURAL!r}); this environment "
                f"drives course {self.course.name!r}."
            )
        start = self.course.start
        if "start_pose" in options:
            x, y, heading_deg = (float(value) for value in options["start_pose"])
            heading = math.radians(heading_deg)
        else:
            x, y, heading = start.x, start.y, start.heading
            if self.start_position_jitter > 0.0:
                x += self.np_random.uniform(-self.start_position_jitter, self.start_position_jitter)
                y += self.np_random.uniform(-self.start_position_jitter, self.start_position_jitter)
            if self.start_heading_jitter > 0.0:
                heading += self.np_random.uniform(-self.start_heading_jitter, self.start_heading_jitter)
        self._collided = self._simulation.move_robot(x, y, heading, self._lidar)
        if self._collided:
            raise ValueError(
                f"`options['start_pose']`: the start pose ({x:g}, {y:g}, {math.degrees(heading):g} deg) puts the robot "
                f"on a wall of course {self.course.name!r}."
            )
        if self._progress is not None:
            self._progress.reset(x, y)
        self._distance = 0.0
        self._path_length = 0
        self._record_position()
        return self._lidar.copy(), self._info(False)

    def _load_layout(self, layout_seed: int) -> None:
        if layout_seed == self.layout_seed:
            return  # the same layout: its world is built already
        self.layout_seed = layout_seed
        self.course = _procedural_course(self.generator, layout_seed, self.robot_radius)
        self._simulation.load(self.course)
        self._progress = self._loop_progress(self.course)
        self._renderer = None

    def _info(self, collided: bool) -> dict[str, Any]:
        return {
            "collision": collided,
            "is_success": not collided,
            "distance": self._distance,
            "clearance": float(self._lidar.min()) * self.max_range - self.robot_radius,
            "course": self.course.name,
        }

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """
        Turn by ``action[0] * max_steer_deg`` (clipped to ``[-1, 1]``), drive ``speed`` metres, read the lidar.

        The wheeled robot sets its wheels to that turn and that distance over the control period and simulates
        it; its pose is what the physics gives.

        :param action: ``(1,)`` array in ``[-1, 1]``
        :return: observation, reward (``step_reward``, or ``collision_reward`` on a collision), terminated (a
            collision), truncated (always ``False``: ``gym.make`` adds the 500-step limit) and
            ``{"collision": bool, "is_success": bool, "distance": float, "clearance": float, "course": str}``
        :raises ValueError: if the action is NaN
        """
        steer = float(action[0])
        if steer != steer:  # NaN
            raise ValueError(f"`action` must not be NaN, got {action!r}.")
        steer = 1.0 if steer > 1.0 else -1.0 if steer < -1.0 else steer
        x_before, y_before, _ = self._simulation.pose
        x, y, _, collided = self._simulation.drive_robot(self.speed, steer * self.max_steer, self._lidar)
        self._collided = collided
        if self._progress is not None:
            self._distance += self._progress.advance(x, y)
        else:  # the length of the path: the kinematic robot drives `speed` exactly
            self._distance += self.speed if self.robot == "kinematic" else math.hypot(x - x_before, y - y_before)
        self._record_position()
        reward = self.collision_reward if collided else self.step_reward
        return self._lidar.copy(), reward, collided, False, self._info(collided)

    def _record_position(self) -> None:
        if self._path_length == len(self._path):
            self._path = np.concatenate([self._path, np.empty_like(self._path)])
        self._path[self._path_length] = self._simulation.pose[:2]
        self._path_length += 1

    def render(self) -> np.ndarray | None:
        """A top-down ``(height, width, 3)`` ``uint8`` picture with ``render_mode="rgb_array"``, else ``None``."""
        if self.render_mode is None:
            gym.logger.warn("Calling `render()` without a render mode; make the environment with render_mode='rgb_array'.")
            return None
        if self._renderer is None:
            self._renderer = TopDownRenderer(self.course)
        pose = self.pose
        ray_ends = self._simulation.lidar.ray_ends(*pose, self._lidar)
        return self._renderer.render(self.trajectory, pose, self.robot_radius, ray_ends, self._lidar < 1.0, self._collided)

    def close(self) -> None:
        """Disconnect the pybullet client (safe to call more than once)."""
        self._simulation.close()
        super().close()
