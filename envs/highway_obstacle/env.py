"""``sb3_adc/HighwayObstacle-v0`` and ``-v1``: steer a car at constant speed around static obstacles on a multi-lane road."""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterator
from typing import Any

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("envs", "the highway obstacle task"):
    from highway_env import utils
    from highway_env.envs.common.abstract import AbstractEnv
    from highway_env.envs.common.action import action_factory
    from highway_env.envs.common.graphics import EnvViewer
    from highway_env.road.lane import StraightLane
    from highway_env.road.road import Road, RoadNetwork
    from highway_env.vehicle.objects import Obstacle

from sb3_adc_envs.highway_obstacle.observation import RoadEdgeLidarObservation

#: The most lanes of the road (``config["lanes_count"]``).
MAX_LANES = 16
#: The most rays of the observation (``config["observation"]["cells"]``): the observation's size, which sizes a
#: replay buffer's memory.
MAX_CELLS = 4096
#: Rays of ``-v0``'s lidar: it tells an obstacle in the next lane from one in the car's own lane (or from none) only
#: within about 15 m.
V0_CELLS = 16
#: Rays of ``-v1``'s lidar: the next lane's obstacles are told apart from the car's own lane's over the whole range.
V1_CELLS = 64
#: Steering range of the paper's navigation task: ±6 degrees.
PAPER_STEERING_RANGE = (-math.radians(6.0), math.radians(6.0))


@contextlib.contextmanager
def _runtime_dir() -> Iterator[None]:
    """
    A private, empty ``XDG_RUNTIME_DIR`` while the block runs, where none is set: SDL (under pygame) looks for a
    Wayland display there when it starts, and without the variable prints ``error: XDG_RUNTIME_DIR is invalid or not
    set`` to the terminal although off-screen drawing needs no display.
    """
    if os.environ.get("XDG_RUNTIME_DIR"):
        yield
        return
    with tempfile.TemporaryDirectory(prefix="sb3-adc-runtime-") as folder:
        os.environ["XDG_RUNTIME_DIR"] = folder
        try:
            yield
        finally:
            del os.environ["XDG_RUNTIME_DIR"]


class HighwayObstacleEnv(AbstractEnv):
    """
    A car drives at constant speed along a straight multi-lane road blocked here and there by static
    obstacles; it steers (one continuous action) to weave between them without leaving the road.

    The highway-env counterpart of the lidar obstacle course (Actor-Dueling-Critic paper, Section 5.1.2):

    - **Action**: ``Box(-1, 1, (1,))``, highway-env's ``ContinuousAction`` with lateral control only: the
      front-wheel steering angle, scaled to ``config["action"]["steering_range"]`` (±6° as in the paper).
      The speed stays at ``config["ego_speed"]``.
    - **Observation**: ``Box(0, 1, (cells,))``, a :class:`RoadEdgeLidarObservation`: ``cells`` rays in the
      car's frame measure the distance to the nearest obstacle **or road edge**, divided by ``maximum_range``.
    - **Obstacles**: rows of static obstacles (2 m x 2 m, each blocking a lane) every
      ``obstacle_gap`` metres (drawn uniformly in that range); a row blocks 1 to ``max_blocked_lanes``
      lanes chosen at random and always leaves at least one lane free.
    - **Reward**: ``step_reward`` (+0.001) per step; ``collision_reward`` (-1) on hitting an obstacle or
      leaving the road (a corner of the car beyond a road edge), which both terminate the episode.
    - **Episode**: truncated after ``duration`` seconds (``duration * policy_frequency`` steps, 200 by default,
      the registered ``max_episode_steps``; with another duration or frequency pass ``max_episode_steps`` to
      ``gym.make`` too).
    - **Frame rate**: ``metadata["render_fps"]`` is ``policy_frequency`` (5), one frame per step, before and
      after ``reset``.
    - **Rendering**: ``rgb_array`` is drawn off-screen by pygame: no display is needed, and it also works with
      ``SDL_VIDEODRIVER=dummy`` (with which highway-env alone draws blank frames).
    - **Info**: ``{"collision": bool, "off_road": bool, "is_success": bool, "speed": float, "crashed": bool,
      "action": ...}``: ``is_success`` is ``not (collision or off_road)``, so at the episode's last step it tells
      whether the car drove until truncation (what SB3's ``EvalCallback`` and ``--best-model-metric success``
      read).

    Configure it as any highway-env environment, with ``config=`` at ``gym.make`` or ``env.unwrapped.configure``
    followed by ``reset``; the keys and defaults are in :meth:`default_config`.

    :param config: Overrides of :meth:`default_config`
    :param render_mode: ``None`` or ``"rgb_array"`` (highway-env's top view, drawn off-screen)
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}  # noqa: RUF012 (Gymnasium's class attribute)
    #: Rays of the default observation (``config["observation"]["cells"]``).
    lidar_cells: int = V0_CELLS

    @classmethod
    def default_config(cls) -> dict[str, Any]:
        config: dict[str, Any] = super().default_config()
        config.update(
            {
                "observation": {"type": "RoadEdgeLidarObservation", "cells": cls.lidar_cells, "maximum_range": 50.0},
                "action": {
                    "type": "ContinuousAction",
                    "longitudinal": False,
                    "lateral": True,
                    "steering_range": list(PAPER_STEERING_RANGE),
                },
                "lanes_count": 3,
                "ego_speed": 20.0,  # [m/s]
                "first_obstacle_distance": 60.0,  # [m] ahead of the car's start
                "obstacle_gap": [45.0, 75.0],  # [m] between rows of obstacles
                "max_blocked_lanes": 2,
                "duration": 40.0,  # [s]
                "simulation_frequency": 15,  # [Hz]
                "policy_frequency": 5,  # [Hz]
                "step_reward": 0.001,
                "collision_reward": -1.0,
                "offscreen_rendering": True,
                "screen_width": 600,
                "screen_height": 150,
                "centering_position": [0.3, 0.5],
            }
        )
        return config

    @property
    def road_edges(self) -> tuple[float, float]:
        """``(y_right, y_left)`` of the road's edges [m] (lane 0 is centred on ``y = 0``)."""
        half_lane = StraightLane.DEFAULT_WIDTH / 2.0
        return -half_lane, (self.config["lanes_count"] - 1) * StraightLane.DEFAULT_WIDTH + half_lane

    def define_spaces(self) -> None:
        self._check_config()
        observation = self.config["observation"]
        if observation.get("type") != "RoadEdgeLidarObservation":
            raise ValueError(
                f"config['observation']['type'] must be 'RoadEdgeLidarObservation', got {observation.get('type')!r}."
            )
        options = {"cells": self.lidar_cells, **{key: value for key, value in observation.items() if key != "type"}}
        self.observation_type = RoadEdgeLidarObservation(self, road_edges=self.road_edges, **options)
        action = self.config["action"]
        if action.get("type") != "ContinuousAction" or action.get("longitudinal", True) or not action.get("lateral", True):
            raise ValueError(
                "config['action'] must be a ContinuousAction with lateral control only "
                f"(type='ContinuousAction', longitudinal=False, lateral=True), got {action!r}."
            )
        self.action_type = action_factory(self, action)
        self.observation_space = self.observation_type.space()
        self.action_space = self.action_type.space()

    def _check_config(self) -> None:
        config = self.config
        lanes = config["lanes_count"]
        if isinstance(lanes, bool) or not isinstance(lanes, int) or not 2 <= lanes <= MAX_LANES:
            raise ValueError(f"config['lanes_count'] must be an integer in [2, {MAX_LANES}], got {lanes!r}.")
        cells = config["observation"].get("cells", self.lidar_cells) if isinstance(config["observation"], dict) else None
        if isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= MAX_CELLS:
            raise ValueError(f"config['observation']['cells'] must be an integer in [1, {MAX_CELLS}], got {cells!r}.")
        numbers = ["ego_speed", "duration", "first_obstacle_distance", "step_reward", "collision_reward"]
        for key in numbers:
            value = config[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"config['{key}'] must be a finite number, got {value!r} ({type(value).__name__}).")
        blocked = config["max_blocked_lanes"]
        if isinstance(blocked, bool) or not isinstance(blocked, int) or not 1 <= blocked < lanes:
            raise ValueError(
                f"config['max_blocked_lanes'] must be an integer in [1, lanes_count - 1={lanes - 1}], got {blocked!r}."
            )
        gap = config["obstacle_gap"]
        if (
            not isinstance(gap, (list, tuple))
            or len(gap) != 2
            or any(isinstance(value, bool) or not isinstance(value, (int, float)) for value in gap)
            or not 0.0 < gap[0] <= gap[1] < math.inf
        ):
            raise ValueError(f"config['obstacle_gap'] must be [min, max] with 0 < min <= max [m], got {gap!r}.")
        for key in ("ego_speed", "duration", "first_obstacle_distance"):
            if not config[key] > 0.0:
                raise ValueError(f"config['{key}'] must be > 0, got {config[key]!r}.")

    def _reset(self) -> None:
        config = self.config
        lanes = config["lanes_count"]
        travel = config["ego_speed"] * config["duration"]
        # The road and its obstacles reach past the furthest point the car can get to, and past its lidar.
        road_length = travel + 2.0 * config["observation"].get("maximum_range", 50.0) + config["obstacle_gap"][1]
        self.road = Road(
            network=RoadNetwork.straight_road_network(lanes, length=road_length, speed_limit=config["ego_speed"]),
            np_random=self.np_random,
            record_history=config["show_trajectories"],
        )
        lane_width = StraightLane.DEFAULT_WIDTH
        start_lane = int(self.np_random.integers(lanes))
        ego = self.action_type.vehicle_class(self.road, [0.0, start_lane * lane_width], 0.0, config["ego_speed"])
        self.controlled_vehicles = [ego]
        self.road.vehicles.append(ego)

        x = float(config["first_obstacle_distance"])
        low, high = config["obstacle_gap"]
        while x < road_length:
            n_blocked = int(self.np_random.integers(1, config["max_blocked_lanes"] + 1))
            for lane in self.np_random.choice(lanes, size=n_blocked, replace=False):
                self.road.objects.append(Obstacle(self.road, [x, float(lane) * lane_width]))
            x += float(self.np_random.uniform(low, high))

    def update_metadata(self, video_real_time_ratio: int = 2) -> None:
        """
        Set ``metadata["render_fps"]`` to the rate frames come at, in real time: one per step at
        ``policy_frequency`` (5 Hz by default, the class's value), or ``simulation_frequency`` while highway-env
        records its intermediate frames. highway-env's own version doubles the rate and writes it into the dict
        shared by every instance; this one gives the instance its own dict.

        :param video_real_time_ratio: Ignored (highway-env's speed-up of videos)
        """
        recording = getattr(self, "_record_video_wrapper", None) is not None
        fps = self.config["simulation_frequency"] if recording else self.config["policy_frequency"]
        self.metadata = {**type(self).metadata, "render_fps": fps}

    def render(self) -> np.ndarray | None:
        """highway-env's top view as a ``(height, width, 3)`` ``uint8`` array with ``render_mode="rgb_array"``."""
        if self.render_mode == "rgb_array" and getattr(self, "viewer", None) is None:
            with _runtime_dir():  # quiet: SDL's probe for a display, which off-screen drawing does not need
                viewer = EnvViewer(self)
            # highway-env draws nothing when SDL_VIDEODRIVER=dummy, a common headless setting; drawing off-screen
            # needs no display, so draw anyway.
            viewer.enabled = True
            self.viewer = viewer
        frame: np.ndarray | None = super().render()
        return frame

    def _off_road(self) -> bool:
        vehicle = self.vehicle
        corners = utils.rect_corners(vehicle.position, vehicle.LENGTH, vehicle.WIDTH, vehicle.heading)
        y_right, y_left = self.road_edges
        return any(corner[1] < y_right or corner[1] > y_left for corner in corners)

    def _is_terminated(self) -> bool:
        return bool(self.vehicle.crashed or self._off_road())

    def _is_truncated(self) -> bool:
        return bool(self.time >= self.config["duration"])

    def _reward(self, action: np.ndarray) -> float:
        if self._is_terminated():
            return float(self.config["collision_reward"])
        return float(self.config["step_reward"])

    def _info(self, obs: np.ndarray, action: np.ndarray | None = None) -> dict[str, Any]:
        # A copy of the action: infos of consecutive steps must not share objects.
        info: dict[str, Any] = super()._info(obs, None if action is None else np.array(action, copy=True))
        info["collision"] = bool(self.vehicle.crashed)
        info["off_road"] = self._off_road()
        info["is_success"] = not (info["collision"] or info["off_road"])
        return info


class HighwayObstacleV1Env(HighwayObstacleEnv):
    """
    ``sb3_adc/HighwayObstacle-v1``: :class:`HighwayObstacleEnv` seen through :data:`V1_CELLS` (64) rays instead of
    :data:`V0_CELLS` (16), everything else the same.

    With 16 rays (22.5° each) an obstacle in the next lane gives the same readings as one in the car's own lane
    while it is more than about 20 m ahead, and then none until about 15 m (the road edge's readings hide it);
    a lane change takes about 28 m at 20 m/s, so ``-v0`` tells a policy which lane to leave too late. With 64 rays
    (5.6° each) the two differ over the lidar's whole range (50 m). ``docs/envs/highway_obstacle.rst`` has the
    measurements, ``tests/envs/test_highway_obstacle.py`` checks them.

    :param config: Overrides of :meth:`default_config`
    :param render_mode: ``None`` or ``"rgb_array"``
    """

    lidar_cells = V1_CELLS
