"""A lidar observation of highway-env that turns with the vehicle and also sees the road's edges."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces

from sb3_adc.extras import requires_extra

with requires_extra("envs", "the highway obstacle task"):
    from highway_env.envs.common.observation import LidarObservation


class RoadEdgeLidarObservation(LidarObservation):
    """
    Distances along ``cells`` rays spread evenly around the observer vehicle, in its own frame (ray 0
    points along its heading), to the nearest obstacle **or road edge**, divided by ``maximum_range``.

    highway-env's :class:`~highway_env.envs.common.observation.LidarObservation` casts its rays in the world
    frame and sees vehicles and road objects only. This subclass rotates the rays with the vehicle (so the
    readings tell the vehicle's heading relative to the road, as the lidar course's rays do) and cuts every
    ray at the road's edges, the two lines ``y = road_edges[0]`` and ``y = road_edges[1]`` of a straight road
    along the x axis: leaving the road is then "hitting a wall" the lidar can see coming. The relative
    speed channel of the parent class is dropped.

    :param env: The highway-env environment
    :param road_edges: ``(y_right, y_left)`` of the straight road's edges [m], ``y_right < y_left``
    :param cells: Number of rays
    :param maximum_range: Length of the rays [m]
    :param kwargs: Passed to :class:`~highway_env.envs.common.observation.LidarObservation`
    """

    def __init__(
        self,
        env: Any,
        road_edges: tuple[float, float],
        cells: int = 16,
        maximum_range: float = 50.0,
        **kwargs: Any,
    ):
        super().__init__(env, cells=cells, maximum_range=maximum_range, normalize=True, **kwargs)
        self.road_edges = (float(road_edges[0]), float(road_edges[1]))
        self._ray_offsets = np.arange(cells) * self.angle

    def space(self) -> spaces.Box:
        return spaces.Box(low=0.0, high=1.0, shape=(self.cells,), dtype=np.float32)

    def observe(self) -> np.ndarray:
        vehicle = self.observer_vehicle
        distances = self.trace(vehicle.position, vehicle.velocity)[:, self.DISTANCE]
        distances = np.minimum(distances, self.edge_distances(vehicle.position, vehicle.heading))
        return np.clip(distances / self.maximum_range, 0.0, 1.0).astype(np.float32)

    def edge_distances(self, position: np.ndarray, heading: float) -> np.ndarray:
        """
        Distance along each ray from ``position`` to the road's edges (``maximum_range`` where a ray meets none).

        :param position: ``(x, y)`` of the ray's origin [m]
        :param heading: Heading of the vehicle [rad]
        """
        sines = np.sin(heading + self._ray_offsets)
        y_right, y_left = self.road_edges
        with np.errstate(divide="ignore", invalid="ignore"):
            to_edge = np.where(sines > 0.0, (y_left - position[1]) / sines, (y_right - position[1]) / sines)
        to_edge = np.where(np.abs(sines) > 1e-9, np.maximum(to_edge, 0.0), np.inf)
        return np.minimum(to_edge, self.maximum_range)

    # The parent traces rays in the world frame; these two conversions make its rays turn with the vehicle.
    def position_to_angle(self, position: np.ndarray, origin: np.ndarray) -> float:
        world_angle = math.atan2(position[1] - origin[1], position[0] - origin[0])
        return math.remainder(world_angle - self.observer_vehicle.heading, 2.0 * math.pi) + self.angle / 2.0

    def index_to_direction(self, index: int) -> np.ndarray:
        angle = index * self.angle + self.observer_vehicle.heading
        return np.array([math.cos(angle), math.sin(angle)])
