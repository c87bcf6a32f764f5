"""``sb3_adc/LidarObstacleCourseSpeed-v1``: the lidar robot with two actions, steering and speed (issue 63's 2-D task)."""

from __future__ import annotations

import math
from typing import Any, SupportsFloat

import numpy as np
from gymnasium import spaces

from sb3_adc_envs.lidar_course.env import LidarObstacleCourseEnv


class SpeedSteeringLidarCourse(LidarObstacleCourseEnv):
    """
    :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv` whose robot also chooses its speed: a
    two-dimensional action in which the value of a steering command depends on the speed it is driven at.

    - **Action**: ``Box(-1, 1, (2,))``: ``action[0]`` steers as in the one-dimensional task (the change of heading
      during the step, ``action[0] * max_steer_deg``); ``action[1]`` sets the distance driven during the step,
      linearly from ``min_speed_fraction * speed`` (at -1) to ``speed`` (at +1). The heading turns by the same angle
      at any speed, so a slower robot turns on a tighter circle: slowing down is how it gets round an obstacle that
      it would hit at full speed.
    - **Reward**: ``step_reward`` times the progress of the step along the course, in steps at the top speed: the
      change of ``info["distance"]`` (along the corridor's centre line, which every procedural layout has; the
      length of the path on a course without one) divided by ``speed``. A step straight along the corridor at full
      speed earns ``step_reward``, one at the lowest speed ``min_speed_fraction * step_reward``, and circling on
      the spot earns nothing, so driving on, and fast, pays; ``collision_reward`` on a collision, which ends the
      episode.
    - **Info**: that of the one-dimensional task, plus ``"speed"``, the distance driven during the step [m] (0 after
      a reset).

    Observations, courses, layouts, robots and every other keyword are those of the one-dimensional task.

    :param min_speed_fraction: The lowest speed, as a fraction of ``speed``, in ``(0, 1)``
    :param env_kwargs: Keyword arguments of :class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv`
        (``speed`` is the top speed)
    """

    def __init__(self, min_speed_fraction: float = 0.25, **env_kwargs: Any):
        if (
            isinstance(min_speed_fraction, bool)
            or not isinstance(min_speed_fraction, (int, float, np.integer, np.floating))
            or not 0.0 < min_speed_fraction < 1.0
        ):
            raise ValueError(f"`min_speed_fraction` must be a number in (0, 1), got {min_speed_fraction!r}.")
        super().__init__(**env_kwargs)
        self.min_speed_fraction = float(min_speed_fraction)
        #: The top speed [m per step]; :attr:`speed` is the speed of the current step.
        self.top_speed = self.speed
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)

    def speed_of(self, throttle: float) -> float:
        """
        The distance driven in a step [m] for ``action[1] = throttle``, clipped to ``[-1, 1]``.

        :raises ValueError: if ``throttle`` is NaN
        """
        if math.isnan(throttle):
            raise ValueError(f"`action[1]` must not be NaN, got {throttle!r}.")
        fraction = self.min_speed_fraction + (1.0 - self.min_speed_fraction) * (min(max(throttle, -1.0), 1.0) + 1.0) / 2.0
        return self.top_speed * fraction

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """The one-dimensional task's reset; ``info["speed"]`` is 0."""
        observation, info = super().reset(seed=seed, options=options)
        return observation, {**info, "speed": 0.0}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """
        Turn by ``action[0] * max_steer_deg`` and drive at the speed ``action[1]`` sets (both clipped to ``[-1, 1]``).

        :param action: ``(2,)`` array in ``[-1, 1]``: steering, speed
        :return: observation, reward (``step_reward`` times the progress in steps at the top speed, or
            ``collision_reward``),
            terminated (a collision), truncated (``False``), and the info with ``"speed"``
        :raises ValueError: if an action is NaN
        """
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape != (2,):
            raise ValueError(f"`action` must have shape (2,) (steering, speed), got {action.shape}.")
        self.speed = self.speed_of(float(action[1]))
        distance = self._distance
        try:
            observation, reward, terminated, truncated, info = super().step(action[:1])
        finally:
            speed, self.speed = self.speed, self.top_speed
        if not terminated:
            reward = self.step_reward * (info["distance"] - distance) / self.top_speed
        return observation, reward, terminated, truncated, {**info, "speed": speed}
