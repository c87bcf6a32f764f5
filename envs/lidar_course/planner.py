"""
A reference controller for the lidar course: a local planner that reads one lidar scan and nothing else.

The learned policies of the benchmarks are memoryless functions of the scan (an MLP on the observation). Whether
such a function *can* drive the procedural courses is a question about the observation, not about learning:
:func:`~sb3_adc_envs.lidar_course.passability.kinematic_reach` answers it for a driver that sees the whole map,
this planner for one that sees what a policy sees. It is the dynamic-window idea (Fox, Burgard and Thrun, 1997)
reduced to the kinematic robot: it turns the scan into obstacle points around the robot, rolls out a fixed set
of steering plans (steer ``a`` for ``k`` steps, then ``b``) with the robot's speed and turn limit, and takes the
first action of the plan that drives longest before coming within the robot's radius (plus ``contact_margin``)
of a point, ties broken by the clearance it keeps (up to ``margin``) less ``turn_cost`` per unit of its first
steering value. A ray at the sensor's range sees no point; obstacles between rays are missed, as they are by a
policy. With observation noise in
``[noise_low, noise_high]`` (the noisy variants) a reading stands for any distance in ``[reading - noise_high,
reading - noise_low]``: the planner puts the point at the nearest of them and takes a ray for a hit only when
even the farthest is inside the range.

It is a benchmark reference (``benchmarks/reference_planner.py``), not a learner: it knows the robot's motion
model, which the policies must learn.
"""

from __future__ import annotations

import contextlib
import math
from typing import Any

import gymnasium as gym
import numpy as np


class LidarLocalPlanner:
    """
    A memoryless local planner on the lidar scan of :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv`.

    :param ray_angles: Directions of the rays relative to the heading [rad] (the environment's ``ray_angles``)
    :param max_range: Range of the lidar [m]; the observation is the distance divided by it
    :param speed: Distance driven per step [m]
    :param max_steer: Largest change of heading per step [rad]
    :param robot_radius: Radius of the robot [m]
    :param horizon: Steps of every plan
    :param n_steers: Steering values of a plan's segments, evenly spaced in ``[-1, 1]`` (odd: includes 0)
    :param switch_steps: Steps after which a plan switches from its first to its second steering value
    :param margin: Clearance beyond the robot's radius above which plans are not told apart by clearance [m]
    :param turn_cost: Clearance [m] given up per unit of the first steering value (prefers driving straight)
    :param contact_margin: A plan's step is blocked within the robot's radius plus this of a point [m]
    :param noise_low: Lower bound of the observation noise (a number, or one per ray; 0 for clean observations)
    :param noise_high: Upper bound of the observation noise
    """

    def __init__(
        self,
        ray_angles: np.ndarray,
        max_range: float,
        speed: float,
        max_steer: float,
        robot_radius: float,
        horizon: int = 40,
        n_steers: int = 11,
        switch_steps: tuple[int, ...] = (5, 12),
        margin: float = 0.4,
        turn_cost: float = 0.02,
        contact_margin: float = 0.02,
        noise_low: float | np.ndarray = 0.0,
        noise_high: float | np.ndarray = 0.0,
    ):
        if isinstance(horizon, bool) or not isinstance(horizon, int) or horizon < 1:
            raise ValueError(f"`horizon` must be an integer >= 1, got {horizon!r}.")
        if isinstance(n_steers, bool) or not isinstance(n_steers, int) or n_steers < 2:
            raise ValueError(f"`n_steers` must be an integer >= 2, got {n_steers!r}.")
        if not switch_steps or any(
            isinstance(k, bool) or not isinstance(k, int) or not 0 < k <= horizon for k in switch_steps
        ):
            raise ValueError(f"`switch_steps` must be integers in [1, horizon={horizon}], got {switch_steps!r}.")
        robot = {"max_range": max_range, "speed": speed, "max_steer": max_steer, "robot_radius": robot_radius}
        for name, value in robot.items():
            if not math.isfinite(value) or value <= 0.0:
                raise ValueError(f"`{name}` must be a finite number > 0, got {value!r}.")
        for name, value in (("margin", margin), ("turn_cost", turn_cost), ("contact_margin", contact_margin)):
            if not math.isfinite(value) or value < 0.0:
                raise ValueError(f"`{name}` must be a finite number >= 0, got {value!r}.")
        self.ray_angles = np.asarray(ray_angles, dtype=float)
        shape = self.ray_angles.shape
        low, high = (np.broadcast_to(np.asarray(bound, dtype=float), shape) for bound in (noise_low, noise_high))
        if not (np.isfinite(low).all() and np.isfinite(high).all() and (low <= high).all()):
            raise ValueError(
                "`noise_low` and `noise_high` must be finite with noise_low <= noise_high, "
                f"got {noise_low!r} and {noise_high!r}."
            )
        self.noise_low, self.noise_high = low.copy(), high.copy()
        self.max_range = float(max_range)
        self.robot_radius = float(robot_radius)
        self.margin = float(margin)
        self.turn_cost = float(turn_cost)
        self.contact = float(robot_radius) + float(contact_margin)
        steers = np.linspace(-1.0, 1.0, n_steers)
        first, second, switch = (grid.ravel() for grid in np.meshgrid(steers, steers, switch_steps, indexing="ij"))
        #: Steering value of each plan's step, shape ``(plans, horizon)``.
        self.plan_steers = np.where(np.arange(horizon)[None, :] < switch[:, None], first[:, None], second[:, None])
        heading = np.cumsum(self.plan_steers * max_steer, axis=1)
        #: The robot's positions along each plan in its own frame (x ahead, y left), shape ``(plans, horizon, 2)``.
        self.plan_points = np.stack([np.cumsum(speed * np.cos(heading), 1), np.cumsum(speed * np.sin(heading), 1)], -1)
        self._squared_norms = (self.plan_points**2).sum(axis=-1)

    @classmethod
    def for_env(cls, env: gym.Env, **kwargs: Any) -> LidarLocalPlanner:
        """
        The planner for an environment's sensor and robot.

        :param env: A lidar course environment, wrapped or not (the noise bounds of a noisy variant are read from
            its wrapper unless ``kwargs`` gives them)
        :param kwargs: The planner's own parameters (``horizon``, ``margin``, ...)
        """
        course = env.unwrapped
        if "noise_low" not in kwargs and "noise_high" not in kwargs:
            with contextlib.suppress(AttributeError):  # the noisy variants' UniformObservationNoise wrapper
                kwargs |= {"noise_low": env.get_wrapper_attr("noise_low"), "noise_high": env.get_wrapper_attr("noise_high")}
        for name in ("ray_angles", "max_range", "speed", "max_steer", "robot_radius"):
            if not hasattr(course, name):
                raise TypeError(f"`env` must be a lidar course environment (it has no `{name}`), got {course!r}.")
        return cls(
            course.ray_angles,  # type: ignore[attr-defined]
            course.max_range,  # type: ignore[attr-defined]
            course.speed,  # type: ignore[attr-defined]
            course.max_steer,  # type: ignore[attr-defined]
            course.robot_radius,  # type: ignore[attr-defined]
            **kwargs,
        )

    def act(self, observation: np.ndarray) -> np.ndarray:
        """
        The action for one scan.

        :param observation: The lidar distances divided by the range, shape ``(n_rays,)``
        :return: The steering action, shape ``(1,)``, in ``[-1, 1]``
        """
        scan = np.asarray(observation, dtype=float).reshape(-1)
        if scan.shape != self.ray_angles.shape:
            raise ValueError(f"`observation` must hold {self.ray_angles.size} rays, got shape {np.shape(observation)}.")
        # The farthest distance a reading can stand for decides a hit, the nearest one the point.
        hit = scan - self.noise_low < 1.0 - 1e-6
        distance = np.clip(scan - self.noise_high, 0.0, 1.0) * self.max_range
        points = np.stack([distance[hit] * np.cos(self.ray_angles[hit]), distance[hit] * np.sin(self.ray_angles[hit])], -1)
        horizon = self.plan_points.shape[1]
        if len(points):
            # |p - q|^2 = |p|^2 + |q|^2 - 2 p.q, one matrix product instead of a (plans, horizon, points, 2) array.
            squared = self._squared_norms[:, :, None] + (points**2).sum(axis=1) - 2.0 * self.plan_points @ points.T
            gaps = np.sqrt(np.maximum(squared.min(axis=2), 0.0))
            blocked = gaps < self.contact
            steps = np.where(blocked.any(axis=1), blocked.argmax(axis=1), horizon)
            clearance = np.minimum(gaps.min(axis=1) - self.robot_radius, self.margin)
        else:
            steps = np.full(len(self.plan_points), horizon)
            clearance = np.full(len(self.plan_points), self.margin)
        first = self.plan_steers[:, 0]
        # Longest drive first, then clearance less the turn's cost: lexicographic through np.lexsort (last key first).
        best = np.lexsort((-(clearance - self.turn_cost * np.abs(first)), -steps))[0]
        return np.array([first[best]], dtype=np.float32)

    def predict(
        self,
        observation: np.ndarray,
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...] | None]:
        """:meth:`act` with Stable-Baselines3's ``predict`` signature, so evaluation code can run the planner."""
        return self.act(observation), None
