"""``sb3_adc/LidarObstacleCourse-v0``: a lidar robot drives through a walled course (ADC paper, Section 5.1.2)."""

from __future__ import annotations

import math
import os
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sb3_adc_envs.lidar_course.course import Course, load_course
from sb3_adc_envs.lidar_course.rendering import TopDownRenderer
from sb3_adc_envs.lidar_course.simulation import CourseSimulation

# Initial capacity of the path buffer (positions); it doubles when full.
_PATH_CAPACITY = 512
_TWO_PI = 2.0 * math.pi


class LidarObstacleCourseEnv(gym.Env[np.ndarray, np.ndarray]):
    """
    A round robot drives forward at constant speed through a walled course and steers to avoid the walls.

    The navigation task of the Actor-Dueling-Critic paper (Section 5.1.2, Figure 6), simulated with
    pybullet (``p.DIRECT``, one physics client per environment; see
    :class:`~sb3_adc_envs.lidar_course.simulation.CourseSimulation`).

    - **Action**: ``Box(-1, 1, (1,))``, the change of heading during the step, scaled to
      ``[-max_steer_deg, +max_steer_deg]`` (the paper's ±6°). Positive turns left (counter-clockwise).
    - **Observation**: ``Box(0, 1, (n_rays,))``, the lidar's distances to the walls divided by
      ``max_range`` (1 where a ray sees no wall). The rays are spread evenly over ``fov_deg`` around the
      heading, the first one straight ahead when ``fov_deg`` is 360.
    - **Reward**: ``step_reward`` (+0.001) for a step without collision; ``collision_reward`` (-1) when the
      robot touches a wall, which terminates the episode.
    - **Episode**: starts at the course's start pose (optionally jittered); registered with a
      500-step time limit (``gym.make`` adds the ``TimeLimit`` wrapper; the class alone never truncates).
    - **Info**: ``{"collision": bool}``.

    ``reset(options={"start_pose": (x, y, heading_deg)})`` starts that episode elsewhere (no jitter).

    :param course: A shipped course name (``"training"``, ``"unseen_narrow"``, ... see
        :func:`~sb3_adc_envs.lidar_course.course.shipped_courses`), the path of a YAML/JSON course file,
        or a :class:`~sb3_adc_envs.lidar_course.course.Course`
    :param n_rays: Number of lidar rays (8 in the paper)
    :param fov_deg: Angle the rays are spread over [deg], in ``(0, 360]``
    :param max_range: Length of the rays [m]; observations are distances divided by it
    :param speed: Distance driven per step [m]
    :param max_steer_deg: Largest change of heading per step [deg] (6 in the paper)
    :param robot_radius: Radius of the robot [m]
    :param start_position_jitter: Start positions are drawn uniformly within this distance of the course's
        start along x and along y [m] (0: always the course's start)
    :param start_heading_jitter_deg: Start headings are drawn uniformly within this angle of the course's
        start heading [deg]
    :param step_reward: Reward of a step without collision
    :param collision_reward: Reward of the step that hits a wall
    :param render_mode: ``None`` or ``"rgb_array"`` (a top-down picture of walls, robot, rays and path)
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
    ):
        if isinstance(n_rays, bool) or not isinstance(n_rays, (int, np.integer)) or n_rays < 1:
            raise ValueError(f"`n_rays` must be an integer >= 1, got {n_rays!r}.")
        if not 0.0 < fov_deg <= 360.0:
            raise ValueError(f"`fov_deg` must be in (0, 360], got {fov_deg!r}.")
        for name, value in (("max_range", max_range), ("speed", speed), ("robot_radius", robot_radius)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"`{name}` must be a finite number > 0, got {value!r}.")
        if not 0.0 < max_steer_deg <= 180.0:
            raise ValueError(f"`max_steer_deg` must be in (0, 180], got {max_steer_deg!r}.")
        for name, value in (
            ("start_position_jitter", start_position_jitter),
            ("start_heading_jitter_deg", start_heading_jitter_deg),
        ):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"`{name}` must be a finite number >= 0, got {value!r}.")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"`render_mode` must be None or one of {self.metadata['render_modes']}, got {render_mode!r}.")

        self.course = course if isinstance(course, Course) else load_course(course)
        self.course.check_robot_fits(robot_radius)
        start = self.course.start
        jitter_reach = start_position_jitter * math.sqrt(2.0)
        if self.course.clearance(start.x, start.y) - jitter_reach <= robot_radius:
            raise ValueError(
                f"`start_position_jitter`={start_position_jitter!r} m can put the robot (radius {robot_radius} m) on a "
                f"wall of course {self.course.name!r}: the start is {self.course.clearance(start.x, start.y):.3g} m "
                "from the nearest wall face."
            )
        self.n_rays = int(n_rays)
        self.fov = math.radians(fov_deg)
        self.max_range = float(max_range)
        self.speed = float(speed)
        self.max_steer = math.radians(max_steer_deg)
        self.robot_radius = float(robot_radius)
        self.start_position_jitter = float(start_position_jitter)
        self.start_heading_jitter = math.radians(start_heading_jitter_deg)
        self.step_reward = float(step_reward)
        self.collision_reward = float(collision_reward)
        self.render_mode = render_mode

        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Box(0.0, 1.0, shape=(self.n_rays,), dtype=np.float32)
        #: Ray directions relative to the heading [rad].
        self.ray_angles = self._ray_angles(self.n_rays, self.fov)
        self._simulation = CourseSimulation(self.course, self.robot_radius, self.ray_angles, self.max_range)
        self._renderer: TopDownRenderer | None = None

        self._lidar = np.ones(self.n_rays, dtype=np.float32)
        self._x, self._y, self._heading = start.x, start.y, start.heading
        self._collided = False
        self._path = np.empty((_PATH_CAPACITY, 2))
        self._path_length = 0

    @staticmethod
    def _ray_angles(n_rays: int, fov: float) -> np.ndarray:
        if math.isclose(fov, 2.0 * math.pi):
            return np.arange(n_rays) * (2.0 * math.pi / n_rays)
        if n_rays == 1:
            return np.zeros(1)
        return np.linspace(-fov / 2.0, fov / 2.0, n_rays)

    @property
    def pose(self) -> tuple[float, float, float]:
        """``(x, y, heading)`` of the robot [m, m, rad]."""
        return self._x, self._y, self._heading

    @property
    def trajectory(self) -> np.ndarray:
        """``(n, 2)`` positions of the robot since the last reset (the start included) [m]."""
        return self._path[: self._path_length].copy()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """
        Put the robot back at the start pose (the course's, jittered if configured, or ``options["start_pose"]``).

        :param seed: Seeds the start-pose jitter
        :param options: ``{"start_pose": (x, y, heading_deg)}`` starts this episode there, without jitter
        :return: the first observation and ``{"collision": False}``
        :raises ValueError: if ``options["start_pose"]`` puts the robot on a wall
        """
        super().reset(seed=seed)
        start = self.course.start
        if options and "start_pose" in options:
            x, y, heading_deg = (float(value) for value in options["start_pose"])
            heading = math.radians(heading_deg)
        else:
            x, y, heading = start.x, start.y, start.heading
            if self.start_position_jitter > 0.0:
                x += self.np_random.uniform(-self.start_position_jitter, self.start_position_jitter)
                y += self.np_random.uniform(-self.start_position_jitter, self.start_position_jitter)
            if self.start_heading_jitter > 0.0:
                heading += self.np_random.uniform(-self.start_heading_jitter, self.start_heading_jitter)
        self._x, self._y, self._heading = x, y, heading
        self._collided = self._simulation.move_robot(x, y, heading, self._lidar)
        if self._collided:
            raise ValueError(
                f"`options['start_pose']`: the start pose ({x:g}, {y:g}, {math.degrees(heading):g} deg) puts the robot "
                f"on a wall of course {self.course.name!r}."
            )
        self._path_length = 0
        self._record_position()
        return self._lidar.copy(), {"collision": False}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """
        Turn by ``action[0] * max_steer_deg`` (clipped to ``[-1, 1]``), drive ``speed`` metres, read the lidar.

        :param action: ``(1,)`` array in ``[-1, 1]``
        :return: observation, reward (``step_reward``, or ``collision_reward`` on a collision), terminated (a
            collision), truncated (always ``False``: ``gym.make`` adds the 500-step limit) and
            ``{"collision": bool}``
        :raises ValueError: if the action is NaN
        """
        steer = float(action[0])
        if steer > 1.0:
            steer = 1.0
        elif steer < -1.0:
            steer = -1.0
        elif steer != steer:  # NaN
            raise ValueError(f"`action` must not be NaN, got {action!r}.")
        heading = math.remainder(self._heading + steer * self.max_steer, _TWO_PI)
        x = self._x + self.speed * math.cos(heading)
        y = self._y + self.speed * math.sin(heading)
        self._x, self._y, self._heading = x, y, heading
        collided = self._simulation.move_robot(x, y, heading, self._lidar)
        self._collided = collided
        self._record_position()
        reward = self.collision_reward if collided else self.step_reward
        return self._lidar.copy(), reward, collided, False, {"collision": collided}

    def _record_position(self) -> None:
        if self._path_length == len(self._path):
            self._path = np.concatenate([self._path, np.empty_like(self._path)])
        self._path[self._path_length, 0] = self._x
        self._path[self._path_length, 1] = self._y
        self._path_length += 1

    def render(self) -> np.ndarray | None:
        """A top-down ``(height, width, 3)`` ``uint8`` picture with ``render_mode="rgb_array"``, else ``None``."""
        if self.render_mode is None:
            gym.logger.warn("Calling `render()` without a render mode; make the environment with render_mode='rgb_array'.")
            return None
        if self._renderer is None:
            self._renderer = TopDownRenderer(self.course)
        cos_heading, sin_heading = math.cos(self._heading), math.sin(self._heading)
        rotation = np.array([[cos_heading, sin_heading], [-sin_heading, cos_heading]])
        ray_ends = np.array([self._x, self._y]) + self._lidar[:, None] * (self._simulation.ray_vectors @ rotation)
        return self._renderer.render(
            self.trajectory,
            self.pose,
            self.robot_radius,
            ray_ends,
            self._lidar < 1.0,
            self._collided,
        )

    def close(self) -> None:
        """Disconnect the pybullet client (safe to call more than once)."""
        self._simulation.close()
        super().close()
