"""The robot's planar lidar: the directions of its readings, and its rays cast in a pybullet world."""

from __future__ import annotations

import math

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("envs", "the lidar obstacle course"):
    import pybullet


def reading_directions(n_rays: int, fov: float) -> tuple[np.ndarray, float]:
    """
    The directions of a lidar's readings, spread evenly over its field of view.

    :param n_rays: Number of readings
    :param fov: Field of view [rad]: a full turn starts straight ahead, a smaller one is centred on the heading
    :return: ``(n_rays,)`` directions relative to the heading [rad], and the angle between neighbouring readings
        (the sector each reading's rays cover; the whole field of view for one reading)
    """
    if math.isclose(fov, 2.0 * math.pi):
        sector = 2.0 * math.pi / n_rays
        return np.arange(n_rays) * sector, sector
    if n_rays == 1:
        return np.zeros(1), fov
    return np.linspace(-fov / 2.0, fov / 2.0, n_rays), fov / (n_rays - 1)


class Lidar:
    """
    A planar lidar: rays from the robot's centre at a fixed height, all cast in one ``rayTestBatch``.

    With ``rays_per_reading`` above 1, each reading is the nearest hit of that many rays spread evenly over its
    sector (``sector`` wide, centred on the reading's direction).

    :param ray_angles: ``(n_rays,)`` directions of the readings relative to the robot's heading [rad]
    :param max_range: Length of the rays [m]
    :param height: Height of the rays [m]
    :param collision_mask: The collision groups the rays see (pybullet's ``collisionFilterMask``)
    :param rays_per_reading: Rays cast for each reading (1: one ray along the reading's direction)
    :param sector: Angle each reading's rays are spread over [rad] (used when ``rays_per_reading`` is above 1)
    """

    def __init__(
        self,
        ray_angles: np.ndarray,
        max_range: float,
        height: float,
        collision_mask: int,
        rays_per_reading: int = 1,
        sector: float = 0.0,
    ):
        self.max_range = max_range
        self.collision_mask = collision_mask
        #: ``(n_rays, 2)`` vectors of the readings in the robot's frame (unit direction times ``max_range``).
        self.ray_vectors = max_range * np.column_stack([np.cos(ray_angles), np.sin(ray_angles)])
        self.rays_per_reading = int(rays_per_reading)
        # The rays cast, reading after reading: each reading's rays at the middles of equal parts of its sector.
        offsets = (np.arange(self.rays_per_reading) + 0.5) / self.rays_per_reading * sector - sector / 2.0
        cast_angles = (np.asarray(ray_angles)[:, None] + offsets).ravel()  # one ray: offset 0, the reading's direction
        self._cast_vectors = max_range * np.column_stack([np.cos(cast_angles), np.sin(cast_angles)])
        n_rays = len(cast_angles)
        self._ray_from = np.full((n_rays, 3), height)
        self._ray_to = np.full((n_rays, 3), height)
        self._rotation = np.empty((2, 2))
        #: pybullet's ``rayTestBatch`` hits of the last :meth:`read`, one per ray cast.
        self.hits: tuple[tuple[int, ...], ...] = ()

    def _rotate(self, heading: float) -> np.ndarray:
        # The matrix that turns row vectors of the robot's frame into the course's frame.
        cos_heading = math.cos(heading)
        sin_heading = math.sin(heading)
        rotation = self._rotation
        rotation[0, 0] = cos_heading
        rotation[0, 1] = sin_heading
        rotation[1, 0] = -sin_heading
        rotation[1, 1] = cos_heading
        return rotation

    def read(self, client: int | None, x: float, y: float, heading: float, out: np.ndarray) -> None:
        """
        Cast the rays from a pose and write the readings.

        :param client: The pybullet physics client id of the world to cast in
        :param x: Position [m]
        :param y: Position [m]
        :param heading: Heading [rad]
        :param out: ``(n_rays,)`` array that receives the ray lengths divided by ``max_range`` (1 where a ray hits
            nothing)
        """
        ray_to = self._ray_to
        np.matmul(self._cast_vectors, self._rotate(heading), out=ray_to[:, :2])
        ray_to[:, 0] += x
        ray_to[:, 1] += y
        ray_from = self._ray_from
        ray_from[:, 0] = x
        ray_from[:, 1] = y
        hits = pybullet.rayTestBatch(ray_from, ray_to, collisionFilterMask=self.collision_mask, physicsClientId=client)
        per_reading = self.rays_per_reading
        if per_reading == 1:
            out[:] = [hit[2] for hit in hits]
        else:
            # Each reading: the nearest of its rays' hits (a ray that hits nothing has fraction 1).
            for i in range(len(out)):
                out[i] = min(hit[2] for hit in hits[i * per_reading : (i + 1) * per_reading])
        self.hits = hits

    def reading_hits(self) -> tuple[tuple[int, ...], ...]:
        """The hit of each reading of the last :meth:`read` (with several rays per reading, its nearest one)."""
        per_reading, hits = self.rays_per_reading, self.hits
        if per_reading > 1:
            hits = tuple(min(hits[i : i + per_reading], key=lambda hit: hit[2]) for i in range(0, len(hits), per_reading))
        return hits

    def ray_ends(self, x: float, y: float, heading: float, readings: np.ndarray) -> np.ndarray:
        """
        Where each reading's ray ends, seen from a pose: where it hit, or at its full length.

        :param x: Position [m]
        :param y: Position [m]
        :param heading: Heading [rad]
        :param readings: ``(n_rays,)`` readings (distances divided by ``max_range``)
        :return: ``(n_rays, 2)`` points [m]
        """
        return np.array([x, y]) + readings[:, None] * (self.ray_vectors @ self._rotate(heading))
